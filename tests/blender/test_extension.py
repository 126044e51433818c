"""The extension zip: built with Blender's own tool, installed into isolated user folders
by a fresh Blender process, rendering as ``bl_ext.user_default.photon_map``."""

import json
import os
import pathlib
import subprocess
import sys
import zipfile

import bpy
import pytest

from tests.conftest import ROOT

pytestmark = [pytest.mark.blender, pytest.mark.api]


def blender_ext_tool() -> pathlib.Path:
    """``blender_ext.py`` inside the bpy package (bpy/5.0/scripts/modules/bpy/__init__.py)."""
    scripts = pathlib.Path(bpy.__file__).resolve().parents[2]
    tool = scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    assert tool.is_file(), tool
    return tool


def run_tool(*args):
    return subprocess.run([sys.executable, str(blender_ext_tool()), *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    done = run_tool("build", "--source-dir", str(ROOT), "--output-dir", str(out))
    assert done.returncode == 0, done.stdout + done.stderr
    zips = list(out.glob("photon_map-*.zip"))
    assert len(zips) == 1, done.stdout
    return zips[0]


def test_manifest_and_zip_validate(extension_zip):
    for source in (str(ROOT), str(extension_zip)):
        done = run_tool("validate", source)
        assert done.returncode == 0 and "Success" in done.stdout, done.stdout + done.stderr


def test_zip_holds_the_runtime_and_nothing_else(extension_zip):
    names = set(zipfile.ZipFile(extension_zip).namelist())
    for needed in ("blender_manifest.toml", "__init__.py", "LICENSE",
                   "photon_engine/__init__.py", "photon_engine/engine.py",
                   "photon_engine/export.py", "core/__init__.py", "core/scene/contract.py",
                   "core/integrators/photon_mapping.py"):
        assert needed in names, needed
    for name in names:
        top = name.split("/", 1)[0]
        assert top not in {"tests", "examples", "benchmarks", "docs", "tools", "dist", ".ci",
                           ".venv", ".git", "__pycache__"}, name
        assert "__pycache__" not in name and not name.endswith((".pyc", ".blend1")), name


# Runs in a fresh interpreter: no photon_map on sys.path, user folders in a temp dir.
INSTALL_AND_RENDER = r'''
import importlib.util, json, math, sys
import bpy
import numpy as np

zip_path, scenes_path, out_path = sys.argv[1:4]

# The scene builders, loaded by path so the repository itself stays unimportable.
# The scene comes first: its factory reset would disable extensions enabled before it.
spec = importlib.util.spec_from_file_location("scenes", scenes_path)
scenes = importlib.util.module_from_spec(spec)
spec.loader.exec_module(scenes)
scene = scenes.plane_and_point_light(width=32, height=24)

done = bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo='user_default', enable_on_install=True)
assert done == {'FINISHED'}, done
scene.render.engine = 'PHOTON_MAP'
scene.photon_map.samples = 2
bpy.ops.render.render()
passes = scenes.saved_render_result(scene)
combined = passes["Combined"]
engine = next(c for c in bpy.types.RenderEngine.__subclasses__()
              if getattr(c, "bl_idname", "") == "PHOTON_MAP")
report = {
    "engine_module": engine.__module__,
    "loaded": sorted(k for k in sys.modules if "photon" in k),
    "shape": list(combined.shape),
    "finite": bool(np.isfinite(combined).all()),
    "min": float(combined[..., :3].min()),
    "max": float(combined[..., :3].max()),
}
with open(out_path, "w") as f:
    json.dump(report, f)
'''


def test_installed_zip_renders(extension_zip, tmp_path):
    script = tmp_path / "install_and_render.py"
    script.write_text(INSTALL_AND_RENDER)
    report_path = tmp_path / "report.json"
    env = dict(os.environ,
               BLENDER_USER_EXTENSIONS=str(tmp_path / "extensions"),
               BLENDER_USER_CONFIG=str(tmp_path / "config"),
               BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"),
               PYTHONPATH="")
    done = subprocess.run(
        [sys.executable, str(script), str(extension_zip),
         str(ROOT / "tests" / "blender" / "scenes.py"), str(report_path)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=400)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    report = json.loads(report_path.read_text())

    installed = tmp_path / "extensions" / "user_default" / "photon_map"
    assert (installed / "blender_manifest.toml").is_file()
    # Relative imports resolved inside the installed package, not the repository.
    assert report["engine_module"] == "bl_ext.user_default.photon_map.photon_engine.engine"
    assert all(name.startswith("bl_ext.user_default.photon_map") for name in report["loaded"])
    assert report["shape"] == [24, 32, 4]
    assert report["finite"] and report["min"] >= 0.0 and report["max"] > 0.0

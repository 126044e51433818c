"""The shippable extension: tools/build_extension.py's Linux zip, with bundled wheels for
CPython 3.11 and 3.13, validates, installs into a bpy whose Python lacks numba, llvmlite,
embreex and OpenEXR, and renders. The bpy is the one running the tests: CI runs this file
on bpy 5.2.3 (.venv, CPython 3.13) and on bpy 4.2 (.venv-4.2, CPython 3.11; it is marked
``api``), so the same zip is installed into both ends of the supported range.

The downloaded wheels are cached in dist/wheels (git-ignored), so only the first run
downloads (~80 MB for Linux).
"""

import importlib.metadata
import json
import os
import pathlib
import subprocess
import sys
import tomllib
import zipfile

import pytest

from tests.blender.test_extension import run_tool
from tests.conftest import ROOT

pytestmark = [pytest.mark.blender, pytest.mark.api]

BUNDLED = ("numba", "llvmlite", "embreex", "openexr")


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("package")
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "build_extension.py"), "--platform", "linux-x64",
         "--output-dir", str(out), "--wheel-cache", str(ROOT / "dist" / "wheels")],
        cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    path = out / "photon_map-0.1.0-linux_x64.zip"
    assert path.is_file(), done.stdout
    assert f"{path} (" in done.stdout and "validated" in done.stdout
    return path


def test_zip_validates_and_bundles_the_linux_wheels(linux_zip):
    done = run_tool("validate", str(linux_zip))
    assert done.returncode == 0 and "Success" in done.stdout, done.stdout + done.stderr
    names = zipfile.ZipFile(linux_zip).namelist()
    wheels = sorted(n for n in names if n.endswith(".whl"))
    # One wheel per bundled package and per CPython a supported Blender embeds: 3.11
    # (Blender 4.2 to 5.0) and 3.13 (5.1 and later); Blender installs the matching ones.
    found = sorted((w.split("/")[1].split("-")[0].lower(), w.split("-")[2]) for w in wheels)
    assert found == sorted((name, tag) for name in BUNDLED for tag in ("cp311", "cp313")), found
    assert all(w.startswith("wheels/") and "manylinux" in w for w in wheels)
    assert not any("numpy" in n.lower() for n in names)
    manifest = tomllib.loads(zipfile.ZipFile(linux_zip).read("blender_manifest.toml").decode())
    assert manifest["platforms"] == ["linux-x64"]
    assert sorted(w.removeprefix("./") for w in manifest["wheels"]) == wheels
    # The repository's own manifest stays wheel-free.
    source = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert "wheels" not in source and "platforms" not in source


# Runs as `python -S` with only bpy and numpy on sys.path (no site-packages).
INSTALL_AND_RENDER = r'''
import importlib.util, json, math, sys, time
import bpy
import numpy as np

zip_path, scenes_path, out_path = sys.argv[1:4]
report = {"before": {}}
for name in ("numba", "llvmlite", "embreex", "OpenEXR"):
    report["before"][name] = importlib.util.find_spec(name) is not None

spec = importlib.util.spec_from_file_location("scenes", scenes_path)
scenes = importlib.util.module_from_spec(spec)
spec.loader.exec_module(scenes)
scene = scenes.plane_and_point_light(width=32, height=24)

started = time.perf_counter()
done = bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo='user_default', enable_on_install=True)
assert done == {'FINISHED'}, done
installed = time.perf_counter()
scene.render.engine = 'PHOTON_MAP'
scene.photon_map.samples = 2
bpy.ops.render.render()
report["seconds"] = {"install": installed - started, "first_render": time.perf_counter() - installed}
passes = scenes.saved_render_result(scene)  # reads the EXR with the bundled OpenEXR
combined = passes["Combined"]
import numba, llvmlite, embreex, OpenEXR
report.update({
    "files": {m.__name__: m.__file__ for m in (numba, llvmlite, embreex, OpenEXR, np, bpy)},
    "shape": list(combined.shape),
    "finite": bool(np.isfinite(combined).all()),
    "min": float(combined[..., :3].min()),
    "max": float(combined[..., :3].max()),
})
with open(out_path, "w") as f:
    json.dump(report, f)
'''


def bpy_without_dependencies(folder: pathlib.Path) -> pathlib.Path:
    """A folder holding only bpy and numpy (symlinks), for ``python -S``."""
    folder.mkdir()
    for name in ("bpy", "numpy"):
        # The installed top-level package (once imported, ``bpy.__file__`` is Blender's
        # scripts/modules/bpy instead).
        package = pathlib.Path(importlib.metadata.distribution(name).locate_file(name))
        for path in [package, *package.parent.glob(name + ".libs")]:
            (folder / path.name).symlink_to(path)
    return folder


def test_isolated_install_renders(linux_zip, tmp_path):
    site = bpy_without_dependencies(tmp_path / "site")
    script = tmp_path / "install_and_render.py"
    script.write_text(INSTALL_AND_RENDER)
    report_path = tmp_path / "report.json"
    extensions = tmp_path / "extensions"
    env = dict(os.environ,
               PYTHONPATH=str(site),
               PYTHONNOUSERSITE="1",
               BLENDER_USER_EXTENSIONS=str(extensions),
               BLENDER_USER_CONFIG=str(tmp_path / "config"),
               BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"))
    done = subprocess.run(
        [sys.executable, "-S", str(script), str(linux_zip),
         str(ROOT / "tests" / "blender" / "scenes.py"), str(report_path)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    report = json.loads(report_path.read_text())
    print("isolated install:", report["seconds"])

    # Before the install none of the bundled modules could be imported...
    assert not any(report["before"].values()), report["before"]
    # ...afterwards they come from the wheels Blender unpacked into the user extensions.
    local = str(extensions / ".local")
    for name in ("numba", "llvmlite", "embreex", "OpenEXR"):
        assert report["files"][name].startswith(local), report["files"]
    assert report["files"]["numpy"].startswith(str(site))  # Blender's numpy, not a wheel
    assert report["shape"] == [24, 32, 4]
    assert report["finite"] and report["min"] >= 0.0 and report["max"] > 0.0

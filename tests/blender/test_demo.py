"""The README's first command, as a user runs it: ``python examples/cornell_box.py -o OUT``
in a fresh process (here with a small image), its Quality dial, and the demo scene it
renders (``build_demo``: Jensen's box with a glossy floor and a copper sphere)."""

import subprocess
import sys

import numpy as np
import pytest

from tests.blender import scenes
from tests.conftest import ROOT

pytestmark = pytest.mark.blender


def demo(*args, timeout=300):
    return subprocess.run([sys.executable, "examples/cornell_box.py", *map(str, args)],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)


def test_demo_writes_the_exr_and_png_with_the_preset_and_overrides(tmp_path):
    done = demo("-o", tmp_path / "demo", "--quality", "draft", "--resolution", "40x30",
                "--samples", "2")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    # Draft's photons, the hand-set samples: the dial reads Custom.
    assert "rendered demo 40x30 at 2 samples/pixel (quality custom)" in done.stdout
    assert "global map: 50,000 photons for final gathering" in done.stdout, done.stdout[-3000:]
    assert "32 rays per camera sample" in done.stdout  # Draft's 64 gather rays over 2 samples
    passes = scenes.read_multilayer_exr(tmp_path / "demo.exr")
    assert {"Combined", "Direct", "Specular", "Caustics", "Indirect"} <= set(passes)
    combined = passes["Combined"]
    assert combined.shape == (30, 40, 4) and np.isfinite(combined).all()
    assert combined.min() >= 0 and combined[..., :3].mean() > 0
    assert (tmp_path / "demo.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_refuses_an_unknown_quality(tmp_path):
    done = demo("-o", tmp_path / "demo", "--quality", "ultra")
    assert done.returncode == 2 and "invalid choice: 'ultra'" in done.stderr
    assert not (tmp_path / "demo.exr").exists()


def test_demo_scene_adds_a_glossy_floor_and_a_copper_sphere_clear_of_the_others():
    """build_demo: the floor a Principled BSDF of roughness 0.2, the copper sphere a
    Principled metal resting on the floor, inside the box, overlapping neither sphere."""
    import bpy
    from examples import cornell_box as cb
    scenes.reset()
    cb.build_demo(resolution=(40, 30))
    floor = bpy.data.objects["Floor"].data.materials[0].node_tree.nodes["Principled BSDF"]
    assert floor.inputs["Roughness"].default_value == pytest.approx(0.2)
    copper = bpy.data.objects["CopperSphere"]
    node = copper.data.materials[0].node_tree.nodes["Principled BSDF"]
    assert node.inputs["Metallic"].default_value == 1.0
    c = np.array(copper.location)
    r = max(copper.dimensions) / 2
    assert r == pytest.approx(cb.COPPER_RADIUS, rel=1e-3) and c[2] == pytest.approx(r)
    assert np.all(np.abs(c[:2]) + r < 1.0)  # inside the walls
    for name in ("MirrorSphere", "GlassSphere"):
        other = bpy.data.objects[name]
        gap = np.linalg.norm(c - np.array(other.location)) - r - max(other.dimensions) / 2
        assert gap > 0.05, (name, gap)

"""EXR round trip in Blender's multilayer layout, and the sRGB PNG preview."""

import numpy as np
import pytest

from core.io import exr
from core.scene import shapes
from core.api import render_to_exr
from core.scene.contract import LIGHT_POINT, Lights, Materials, Scene
from core.settings import RenderSettings


def test_round_trip_is_exact_float32(tmp_path, rng):
    passes = {k: rng.uniform(0, 50, (5, 7, 3)).astype(np.float32)
              for k in ("combined", "emission", "direct", "specular")}
    passes["direct"][0, 0] = [0.0, 1e-30, 3e38]
    path = exr.write_exr(str(tmp_path / "sub" / "out.exr"), passes)
    back = exr.read_exr(path)
    assert set(back) == {"Combined", "Emission", "Direct", "Specular"}
    for k, name in (("combined", "Combined"), ("emission", "Emission"), ("direct", "Direct"), ("specular", "Specular")):
        assert back[name].dtype == np.float32
        np.testing.assert_array_equal(back[name][..., :3], passes[k])
    # Blender's Combined is RGBA, opaque.
    assert back["Combined"].shape == (5, 7, 4) and np.all(back["Combined"][..., 3] == 1)
    assert back["Direct"].shape == (5, 7, 3)


def test_channels_are_named_like_blenders_multilayer(tmp_path):
    import OpenEXR
    passes = {"combined": np.zeros((2, 3, 3), np.float32), "environment": np.ones((2, 3, 3), np.float32)}
    path = exr.write_exr(str(tmp_path / "o.exr"), passes, view_layer="RenderLayer", metadata={"Frame": "007"})
    with OpenEXR.File(path, separate_channels=True) as f:
        names = [p.name() for p in f.parts]
        chans = {c for p in f.parts for c in p.channels}
        header = dict(f.parts[0].header)
    assert names == ["RenderLayer.Combined", "RenderLayer.Environment"]
    assert chans == {"RenderLayer.Combined.R", "RenderLayer.Combined.G", "RenderLayer.Combined.B",
                     "RenderLayer.Combined.A", "RenderLayer.Environment.R", "RenderLayer.Environment.G",
                     "RenderLayer.Environment.B"}
    assert header["BlenderMultiChannel"] == "Blender V2.55.1 and newer" and header["Frame"] == "007"
    full = exr.read_exr(path, strip_view_layer=False)
    assert set(full) == {"RenderLayer.Combined", "RenderLayer.Environment"}


def test_bad_shapes_are_refused(tmp_path):
    with pytest.raises(ValueError, match="'direct'"):
        exr.write_exr(str(tmp_path / "x.exr"), {"combined": np.zeros((2, 2, 3)), "direct": np.zeros((2, 3, 3))})
    with pytest.raises(ValueError, match="at least one"):
        exr.write_exr(str(tmp_path / "x.exr"), {})


def test_srgb_transfer_standard_view():
    lin = np.array([0.0, 0.0031308, 0.18, 0.5, 1.0, 4.0, -1.0])
    enc = exr.srgb_encode(lin)
    np.testing.assert_allclose(enc, [0.0, 0.04045, 0.46135, 0.735357, 1.0, 1.0, 0.0], atol=2e-5)


def test_save_png_writes_srgb_bytes(tmp_path):
    import matplotlib.pyplot as plt
    img = np.zeros((2, 2, 3), np.float32)
    img[0, 0] = [1.0, 0.5, 0.0]
    img[1, 1] = [0.18, 0.18, 0.18]
    path = exr.save_png(str(tmp_path / "p.png"), img)
    back = plt.imread(path)
    np.testing.assert_allclose(back[0, 0, :3], [1.0, round(0.735357 * 255) / 255, 0.0], atol=1e-6)
    np.testing.assert_allclose(back[1, 1, :3], round(0.46135 * 255) / 255, atol=1e-6)


def test_render_to_exr_from_arrays_alone(tmp_path):
    plane = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    scene = Scene(shapes.assemble([(plane, 0)]), Materials.from_list([{"diffuse": [0.5, 0.5, 0.5]}]),
                  Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 1], "power": 10.0}]),
                  shapes.pinhole([0, -2, 2], [0, 0, 0], 8, 6, np.radians(40)))
    out = render_to_exr(scene, RenderSettings(samples=2), str(tmp_path / "r.exr"))
    back = exr.read_exr(str(tmp_path / "r.exr"))
    assert back["Combined"].shape == (6, 8, 4)
    np.testing.assert_array_equal(back["Combined"][..., :3], out.passes["combined"])
    np.testing.assert_array_equal(back["Direct"], out.passes["direct"])
    assert back["Combined"][..., :3].max() > 0

"""Photons through a dispersive prism (core/photons/scatter.py's wavelength pick,
docs/dispersion.md): the rainbow caustic integrates to the light's colour, its hues land
where Snell's law puts them, and Dispersion 0 is the renderer without the setting, bit for
bit."""

from dataclasses import replace

import numpy as np
import pytest

from core import render
from core.scene.contract import Materials, SceneError
from core.settings import RenderSettings
from tests.core.maps import trace
from tests.core.scenes import prism_scene


def _settings(**kw):
    base = dict(global_photons=2_000, caustic_photons=1_000_000, photon_max_bounces=8,
                threads=2, seed=3)
    base.update(kw)
    return RenderSettings().with_values(**base)


def _floor_caustic(pm):
    cm = pm.caustic_map
    pos = cm.positions.astype(np.float64)
    flux = cm.flux.astype(np.float64)
    assert np.all(np.isfinite(flux)) and np.all(flux >= 0)
    on_floor = np.abs(pos[:, 2]) < 1e-3
    return pos[on_floor], flux[on_floor]


def test_rainbow_caustic_integrates_to_the_light_colour():
    # All photons through the prism onto the white floor, summed: the white light's colour
    # within 1 % per channel, and the same flux as the clear (V_d = 0) prism within 1 %.
    pos, flux = _floor_caustic(trace(prism_scene(64.17), _settings()))
    pos0, flux0 = _floor_caustic(trace(prism_scene(0.0), _settings()))
    total, total0 = flux.sum(axis=0), flux0.sum(axis=0)
    assert total0[0] == total0[1] == total0[2]  # no wavelength picked: RGB as before
    np.testing.assert_allclose(total / total.mean(), 1.0, rtol=0.01)
    np.testing.assert_allclose(total, total0, rtol=0.01)
    # Each photon carries one hue (w = B / p of its wavelength), so the channels of single
    # photons differ, and blue, bent more, lands nearer the prism than red (x grows away
    # from it; the beam leaves the prism heading down at ~19 degrees).
    assert np.mean(np.ptp(flux / flux.sum(axis=1, keepdims=True), axis=1)) > 0.3
    x_red = np.average(pos[:, 0], weights=flux[:, 0])
    x_blue = np.average(pos[:, 0], weights=flux[:, 2])
    x_clear = np.average(pos0[:, 0], weights=flux0[:, 1])
    assert x_blue < x_clear < x_red
    # Snell's law with the Cauchy IOR: the 450 / 650 nm rays' deviations differ by ~0.95
    # degree, which ~4.6 m from the exit face at a 19-degree grazing angle is ~0.2 m.
    assert 0.1 < x_red - x_blue < 0.4


def test_dispersion_zero_traces_and_renders_bit_identical_to_no_setting():
    s = _settings(caustic_photons=20_000, global_photons=5_000, final_gather_rays=4,
                  samples=1)
    a, b = trace(prism_scene(None), s), trace(prism_scene(0.0), s)
    for name in ("caustic_map", "global_map"):
        ma, mb = getattr(a, name), getattr(b, name)
        assert np.array_equal(ma.positions, mb.positions)
        assert np.array_equal(ma.flux, mb.flux)
    ra = render(prism_scene(None, 24, 16), s)
    rb = render(prism_scene(0.0, 24, 16), s)
    assert ra.passes.keys() == rb.passes.keys()
    for k in ra.passes:
        assert np.array_equal(ra.passes[k], rb.passes[k]), k
    assert ra.passes["combined"].sum() > 0


@pytest.mark.parametrize("abbe", [-1.0, 2.0, np.nan])
def test_bad_dispersion_names_the_material(abbe):
    mats = Materials.from_list([{"diffuse": [0.8] * 3, "name": "Floor"},
                                {"transmission": [1, 1, 1], "dispersion": abbe,
                                 "name": "Prism"}])
    scene = prism_scene(None)
    with pytest.raises(SceneError, match="Prism"):
        replace(scene, materials=mats).validate()

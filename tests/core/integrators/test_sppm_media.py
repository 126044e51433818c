"""The progressive mode in participating media (core/integrators/sppm.py, docs/sppm.md):
World fog rendered pass by pass (camera segments' transmittance and Volume Direct by
shadow rays, the pass's volume photons through the beam estimate with a radius shrinking
like the surface radius) converges to the photon-mapping integrator's image of the scene
(a reference it did not make: tests/data/sppm_fog_ref.npz,
benchmarks/sppm_fog_convergence.py --make-reference)."""

import pathlib

import numpy as np
import pytest

from core.integrators import sppm
from core.prepared import prepare
from core.settings import RenderSettings
from tests.core.scenes import fog_scene
from tests.metrics import rel_mse

pytestmark = pytest.mark.core

DATA = pathlib.Path(__file__).resolve().parents[2] / "data"
SETTINGS = RenderSettings().with_values(threads=2, photons_per_pass=10_000)


def test_fog_converges_to_the_photon_mapping_reference():
    """relMSE against the reference after 2, 8 and 32 passes falls by at least a third each
    time (measured at 10k photons per pass: see docs/sppm.md), the last below 0.006, and
    the 32-pass image's channel means are the reference's within 3 %. Finite and
    non-negative throughout."""
    ref = np.load(DATA / "sppm_fog_ref.npz")["image"]
    errors = {}
    for state in sppm.progressive_passes(fog_scene(), SETTINGS, 32):
        if state.passes in (2, 8, 32):
            img = state.radiance()
            assert np.all(np.isfinite(img)) and img.min() >= 0.0
            errors[state.passes] = rel_mse(img, ref)
    e = [errors[k] for k in (2, 8, 32)]
    assert e[1] < 0.67 * e[0] and e[2] < 0.67 * e[1], e
    assert e[2] < 0.006, e
    ratio = img.reshape(-1, 3).mean(axis=0) / ref.reshape(-1, 3).mean(axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.03), ratio


def test_standard_sppm_in_fog_has_the_reference_mean():
    """Direct light and Volume Direct by photons too (the lights' first collisions in the
    volume map, no shadow rays): 16 passes, channel means within 3 % of the reference."""
    ref = np.load(DATA / "sppm_fog_ref.npz")["image"]
    out = sppm.render(fog_scene(), SETTINGS.with_values(progressive_passes=16,
                                                       progressive_direct="photons"))
    img = out.passes["combined"]
    assert np.all(np.isfinite(img)) and img.min() >= 0.0
    assert out.stats["rays_shadow"] == 0
    ratio = img.reshape(-1, 3).mean(axis=0) / ref.reshape(-1, 3).mean(axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.03), ratio


def test_beam_radius_shrinks_with_the_surface_radius():
    """Pass k's volume photons have the radius of their global_k-th neighbour times
    r_k / r_1: the same photons at pass 0 and pass 40 differ by exactly that ratio
    (float32), and only the camera map's photons are kept with shadow-ray direct light."""
    scene = fog_scene(8, 8)
    prepared = prepare(scene, 2)
    try:
        r = sppm.PassRenderer(prepared, SETTINGS.with_values(progressive_passes=64))
        st = {"rays_photon": 0}
        photons = r.trace_pass(0, st)[3]
        assert photons is not None and photons[3].any() and not photons[3].all()
        m0, m40 = r.beam_map(photons, 0), r.beam_map(photons, 40)
        assert len(m0) == int(photons[3].sum())
        ratio = r.radius(40) / r.radius(0)
        assert ratio < 0.8
        np.testing.assert_allclose(m40.radii / m0.radii, ratio, rtol=1e-6)
    finally:
        prepared.close()

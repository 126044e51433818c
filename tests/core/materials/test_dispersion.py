"""Dispersion (core/materials/dispersion.py): the Cauchy fit through n_d and V_d, and rays
of 450, 550 and 650 nm through a 60-degree BK7 prism against Snell's law."""

import math

import numpy as np
import pytest

from core.materials import bsdf, closure, dispersion
from core.scene import closures as cl
from core.scene.contract import Materials

BK7 = (1.5168, 64.17)


def sellmeier_bk7(lam_nm):
    """Schott's Sellmeier formula for N-BK7 (the glass the Cauchy fit approximates)."""
    l2 = (np.asarray(lam_nm) * 1e-3) ** 2
    b = (1.03961212, 0.231792344, 1.01046945)
    c = (0.00600069867, 0.0200179144, 103.560653)
    return np.sqrt(1 + sum(bi * l2 / (l2 - ci) for bi, ci in zip(b, c)))


def test_cauchy_passes_through_n_d_and_the_abbe_number():
    n = dispersion.ior(*BK7, [587.6, 486.1, 656.3])
    assert n[0] == pytest.approx(BK7[0], abs=1e-12)
    assert (n[0] - 1) / (n[1] - n[2]) == pytest.approx(BK7[1], rel=1e-9)


def test_cauchy_follows_the_real_glass():
    lam = np.linspace(420, 700, 15)
    np.testing.assert_allclose(dispersion.ior(*BK7, lam), sellmeier_bk7(lam), atol=5e-4)


def test_abbe_zero_is_exactly_the_ior():
    lam = np.linspace(380, 780, 401)
    for n_d in (1.5168, 1.0, 2.4175, 0.75):
        got = dispersion.ior(n_d, 0.0, lam)
        assert np.all(got == n_d)


def _rotate(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[2], 0.0, s * v[0] + c * v[2]])


def trace_prism(n, apex, incidence):
    """Deviation (rad) of a ray through a prism of apex angle ``apex`` in the x-z plane,
    hitting the first face at ``incidence`` from its normal, by bsdf.refract_directions."""
    normal_in = np.array([0.0, 0.0, 1.0])          # first face's outward normal
    normal_out = _rotate(-normal_in, apex)         # second face's: apex from the first's inward
    d0 = _rotate(-normal_in, incidence)            # incoming direction
    d1, tir1 = bsdf.refract_directions(d0, normal_in, n)
    # Leaving: the normal on the incident (glass) side is -normal_out, eta = 1 / n.
    d2, tir2 = bsdf.refract_directions(d1, -normal_out, 1.0 / n)
    assert not tir1[0] and not tir2[0]
    return math.acos(np.clip(np.dot(d0, d2[0]), -1, 1))


def snell_deviation(n, apex, incidence):
    inner = apex - math.asin(math.sin(incidence) / n)
    return incidence + math.asin(n * math.sin(inner)) - apex


@pytest.mark.parametrize("nm", [450.0, 550.0, 650.0])
def test_prism_deviation_matches_snell_within_a_tenth_of_a_degree(nm):
    apex, incidence = math.radians(60), math.radians(50)
    n = dispersion.ior(*BK7, [nm])[0]
    traced = math.degrees(trace_prism(n, apex, incidence))
    assert traced == pytest.approx(math.degrees(snell_deviation(n, apex, incidence)), abs=0.1)
    # And the real glass (Sellmeier) deviates the same within 0.1 degree.
    real = math.degrees(snell_deviation(float(sellmeier_bk7(nm)), apex, incidence))
    assert traced == pytest.approx(real, abs=0.1)


def test_blue_bends_more_than_red():
    apex, incidence = math.radians(60), math.radians(50)
    dev = [trace_prism(dispersion.ior(*BK7, [nm])[0], apex, incidence) for nm in (450, 550, 650)]
    assert dev[0] > dev[1] > dev[2]


def _refract_by_closure(tab, m, d, n_out, entering, lam):
    """The renderer's own sampler (closure.sample_many, as photons and camera paths call
    it) refracting direction d at a face of outward normal n_out for wavelength lam."""
    n_side = n_out if entering else -n_out  # the normal on the side the ray comes from
    u = np.array([[0.9999, 0.5, 0.5]])  # the dielectric's refraction branch
    s = closure.sample_many(tab, m, -d, n_side, n_side, (0.0, 1.0, 0.0), entering, u, lam)[0]
    assert int(s[7]) & closure.LOBE_TRANSMIT
    return s[:3]


@pytest.mark.parametrize("kind", ["glass", "refraction", "principled"])
@pytest.mark.parametrize("nm", [450.0, 550.0, 650.0])
def test_transmission_lobes_deviate_each_wavelength_as_snell(kind, nm):
    # Glass, Refraction and Principled transmission of a dispersive material, sampled at a
    # wavelength by closure.sample_bsdf through a 60-degree prism: Snell's deviation with
    # the Cauchy IOR within 0.1 degree (it agrees to ~1e-10).
    params = {"glass": (cl.CLOSURE_GLASS, {"color": 1.0, "ior": BK7[0], "roughness": 0.0}),
              "refraction": (cl.CLOSURE_REFRACTION, {"color": 1.0, "ior": BK7[0], "roughness": 0.0}),
              "principled": (cl.CLOSURE_PRINCIPLED, {"color": 1.0, "ior": BK7[0], "roughness": 0.0,
                                                     "transmission": 1.0})}[kind]
    mats = Materials.from_list([{"closures": [{"kind": params[0], "params": params[1]}],
                                 "dispersion": BK7[1]}])
    tab = closure.table(mats)
    assert closure.dispersive(tab, 0)
    apex, incidence = math.radians(60), math.radians(50)
    normal_in = np.array([0.0, 0.0, 1.0])
    normal_out = _rotate(-normal_in, apex)  # the exit face's outward normal
    d0 = _rotate(-normal_in, incidence)
    d1 = _refract_by_closure(tab, 0, d0, normal_in, True, nm)
    d2 = _refract_by_closure(tab, 0, d1, normal_out, False, nm)
    traced = math.degrees(math.acos(np.clip(np.dot(d0, d2), -1, 1)))
    n = dispersion.ior(*BK7, [nm])[0]
    assert traced == pytest.approx(math.degrees(snell_deviation(n, apex, incidence)), abs=0.1)
    # An RGB path (lam 0) refracts with n_d itself, as without the setting.
    d1 = _refract_by_closure(tab, 0, d0, normal_in, True, 0.0)
    d2 = _refract_by_closure(tab, 0, d1, normal_out, False, 0.0)
    traced = math.degrees(math.acos(np.clip(np.dot(d0, d2), -1, 1)))
    assert traced == pytest.approx(math.degrees(snell_deviation(BK7[0], apex, incidence)),
                                   abs=1e-4)  # n_d as float32


def test_no_dispersion_no_wavelength():
    mats = Materials.from_list([{"transmission": [1, 1, 1], "ior": 1.5},
                                {"transmission": [1, 1, 1], "ior": 1.5, "dispersion": 0.0},
                                {"diffuse": [1, 1, 1], "dispersion": 40.0}])
    tab = closure.table(mats)
    assert [closure.dispersive(tab, m) for m in range(3)] == [False, False, False]


@pytest.mark.parametrize("nm", [450.0, 650.0])
def test_rough_dispersive_glass_evaluates_at_the_wavelength_it_samples(nm):
    # Camera paths weigh light sampling against BSDF sampling (MIS) with eval_parts' pdf:
    # at a path's wavelength it must give the pdf and value sample_bsdf gave the refracted
    # direction, and at lam 0 (n_d) a different pdf (so the wavelength is really used).
    mats = Materials.from_list([{"closures": [{"kind": cl.CLOSURE_GLASS,
                                               "params": {"color": 1.0, "ior": BK7[0],
                                                          "roughness": 0.3}}],
                                 "dispersion": 20.0}])
    tab = closure.table(mats)
    up, t = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    wo = np.array([math.sin(0.8), 0.0, math.cos(0.8)])
    u = np.random.default_rng(5).random((200, 3))
    s = closure.sample_many(tab, 0, wo, up, up, t, True, u, nm)
    s = s[(s[:, 6] > 0) & (s[:, 2] < 0)]  # rough refractions
    assert len(s) > 50
    moved = 0
    for row in s:
        d0, d1, d2, g0, g1, g2, p = closure.eval_parts(
            tab, 0, 1.0, 1.0, 1.0, *wo, *row[:3], *up, *up, *t, True, False, nm)
        assert p == pytest.approx(row[6], rel=1e-9)
        np.testing.assert_allclose(np.array([d0 + g0, d1 + g1, d2 + g2]) / p, row[3:6],
                                   rtol=1e-9)
        p0 = closure.eval_parts(tab, 0, 1.0, 1.0, 1.0, *wo, *row[:3], *up, *up, *t, True,
                                False)[6]
        moved += abs(p0 - p) > 1e-3 * p
    assert moved > 0.9 * len(s)

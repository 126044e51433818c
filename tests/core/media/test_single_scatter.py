"""Single scattering of a homogeneous isotropic medium under a point light along a ray
(core/media/single_scatter.py) against a numerical integral (a fine trapezoid in numpy)."""

import math

import numpy as np
import pytest
from scipy.integrate import trapezoid

from core.media import single_scatter


SIGMA_A = np.array([0.05, 0.2, 0.4])
SIGMA_S = np.array([0.5, 0.3, 0.1])
INTENSITY = np.array([10.0, 8.0, 12.0])  # W/sr


def reference(origin, direction, t_max, light, g=0.0):
    """The in-scattered radiance by the trapezoid rule on a grid dense near the closest
    approach to the light (where the 1/r^2 peaks)."""
    o, d, p = (np.asarray(v, float) for v in (origin, direction, light))
    delta = np.dot(p - o, d)
    t = np.union1d(np.linspace(0, t_max, 200_001),
                   np.clip(delta + np.linspace(-0.05, 0.05, 20_001), 0, t_max))
    x = o + t[:, None] * d
    r = np.linalg.norm(x - p, axis=1)
    cos = -np.einsum("ij,j->i", (x - p) / r[:, None], d)
    phase = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * cos) ** 1.5)
    sigma_t = SIGMA_A + SIGMA_S
    f = (np.exp(-np.outer(t + r, sigma_t)) * SIGMA_S * INTENSITY
         * (phase / r ** 2)[:, None])
    return trapezoid(f, t, axis=0)


@pytest.mark.parametrize("origin, direction, t_max, light, g", [
    ((0, -3, 0.2), (0, 1, 0), 6.0, (0.1, 0.0, 0.5), 0.0),   # passes 0.5 m from the light
    ((0, 0, 0), (0.6, 0.8, 0), 4.0, (1.0, 2.0, -0.05), 0.0),  # grazes it at 5 cm
    ((0, 0, 0), (0, 0, 1), 3.0, (0.3, 0.0, -1.0), 0.0),       # light behind the camera
    ((0, -3, 0.2), (0, 1, 0), 6.0, (0.1, 0.0, 0.5), 0.6),     # forward scattering
])
def test_equiangular_estimate_matches_the_integral(origin, direction, t_max, light, g):
    n = 64
    origins = np.tile(origin, (n, 1)).astype(float)
    dirs = np.tile(direction, (n, 1)).astype(float)
    out = np.empty((n, 3))
    single_scatter.inscatter_rays(origins, dirs, np.full(n, t_max), np.asarray(light, float),
                                  INTENSITY, SIGMA_A, SIGMA_S, g, 256, 3, out)
    want = reference(origin, direction, t_max, light, g)
    np.testing.assert_allclose(out.mean(axis=0), want, rtol=0.01)
    assert np.all(out >= 0) and np.all(np.isfinite(out))

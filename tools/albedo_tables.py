"""Precompute core/materials/albedo_tables.npz (see core/materials/albedo_tables.py).

Monte Carlo with the package's own samplers (core/materials/microfacet.py), on Cycles'
grids (app/cycles_precompute.cpp): entry (i, j, k) at roughness i / (n - 1), cos theta_o
j / (n - 1) (both clamped to [1e-4, 1]) and the IOR axis z = k / (n - 1) (clamped to
[1e-4, 0.99], IOR = ior_from_f0(z^4)). Samples: a 3-D Kronecker (R3) sequence with a
per-entry random shift (Cranley-Patterson), so every entry is an independent estimate.

The sheen LTC table cannot be re-derived here (it is a fit of Zeltner et al.'s volumetric
sheen): it is read from Cycles' scene/shader.tables, whose path is the one argument
(e.g. a checkout of github.com/blender/cycles: src/scene/shader.tables).

    .venv/bin/python tools/albedo_tables.py /path/to/cycles/src/scene/shader.tables

Runs in about a minute on two cores.
"""

from __future__ import annotations

import pathlib
import re
import sys
import time

import numpy as np
from numba import njit, prange

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.materials import albedo_tables, fresnel, microfacet  # noqa: E402

# R3 Kronecker sequence (Roberts 2018): fractional parts of n * (1/phi3, 1/phi3^2, 1/phi3^3).
PHI3 = 1.2207440846057596
ALPHA = np.array([1.0 / PHI3, 1.0 / PHI3 ** 2, 1.0 / PHI3 ** 3])


@njit(cache=False)
def _u(n, shift, d):
    x = shift[d] + n * (ALPHA[d] if d == 0 else (ALPHA[1] if d == 1 else ALPHA[2]))
    return x - np.floor(x)


@njit(cache=False, parallel=True)
def _ggx_e(nr, nmu, samples, shifts, average_mu, out):
    for e in prange(nr * nmu):
        j, i = e // nr, e % nr
        rough = min(max(i / (nr - 1), 1e-4), 1.0)
        a = rough * rough
        acc = 0.0
        for s in range(samples):
            u1, u2, u3 = _u(s, shifts[e], 0), _u(s, shifts[e], 1), _u(s, shifts[e], 2)
            mu = u3 if average_mu else min(max(j / (nmu - 1), 1e-4), 1.0)
            wo_x = np.sqrt(1.0 - mu * mu)
            _, _, _, w, _, _ = microfacet.reflect_sample(a, a, wo_x, 0.0, mu, u1, u2)
            acc += 2.0 * mu * w if average_mu else w
        out[e] = min(acc / samples, 1.0)


@njit(cache=False, parallel=True)
def _glass_e(nr, nmu, nz, inverse, samples, shifts, average_mu, out):
    for e in prange(nr * nmu * nz):
        k, rest = e // (nr * nmu), e % (nr * nmu)
        j, i = rest // nr, rest % nr
        rough = min(max(i / (nr - 1), 1e-4), 1.0)
        a = rough * rough
        z = min(max(k / (nz - 1), 1e-4), 0.99)
        ior = fresnel.ior_from_f0(z ** 4)
        eta = 1.0 / ior if inverse else ior
        f0 = fresnel.f0_from_ior(eta)
        acc = 0.0
        for s in range(samples):
            u1, u2, u3 = _u(s, shifts[e], 0), _u(s, shifts[e], 1), _u(s, shifts[e], 2)
            if average_mu:
                # a fourth dimension for mu: a cheap hash of the sample index
                mu = ((s * 0.7548776662466927 + shifts[e, 0] * 7.0) % 1.0)
            else:
                mu = min(max(j / (nmu - 1), 1e-4), 1.0)
            wo_x = np.sqrt(1.0 - mu * mu)
            r = microfacet.dielectric_sample(a, eta, False, f0, f0, f0, 1.0, 1.0, 1.0,
                                             1.0, 1.0, 1.0, wo_x, 0.0, mu, u1, u2, u3)
            w = r[3] if r[8] else 0.0
            acc += 2.0 * mu * w if average_mu else w
        out[e] = min(acc / samples, 1.0)


@njit(cache=False, parallel=True)
def _schlick_s(nr, nmu, nz, exponent5, samples, shifts, out):
    for e in prange(nr * nmu * nz):
        k, rest = e // (nr * nmu), e % (nr * nmu)
        j, i = rest // nr, rest % nr
        rough = min(max(i / (nr - 1), 1e-4), 1.0)
        a = rough * rough
        mu = min(max(j / (nmu - 1), 1e-4), 1.0)
        z = min(max(k / (nz - 1), 1e-4), 0.99)
        eta = fresnel.ior_from_f0(z ** 4)
        wo_x = np.sqrt(1.0 - mu * mu)
        acc = 0.0
        for s in range(samples):
            u1, u2 = _u(s, shifts[e], 0), _u(s, shifts[e], 1)
            wix, wiy, wiz, w, pdf, c = microfacet.reflect_sample(a, a, wo_x, 0.0, mu, u1, u2)
            if wiz <= 0.0:
                continue
            if exponent5:
                acc += min(max(1.0 - c, 0.0), 1.0) ** 5
            else:
                acc += fresnel.schlick_real(c, eta)[0]
        out[e] = min(acc / samples, 1.0)


def sheen_from_cycles(path: str) -> np.ndarray:
    """(3, 32, 32) float64: Cycles' table_sheen_ltc (a, b, albedo; rows roughness, columns
    cos theta_o)."""
    text = pathlib.Path(path).read_text()
    body = re.search(r"table_sheen_ltc\[3072\]\s*=\s*\{(.*?)\};", text, re.S).group(1)
    vals = np.array([float(v.rstrip("f")) for v in re.findall(r"[-0-9.e]+f", body)])
    if vals.size != 3072:
        raise ValueError(f"{path}: table_sheen_ltc has {vals.size} values, not 3072")
    return vals.reshape(3, 32, 32)


def main(argv: list[str]) -> None:
    if len(argv) != 1:
        raise SystemExit(__doc__)
    rng = np.random.default_rng(20261202)
    t0 = time.time()
    out = {}
    e = np.empty(32 * 32)
    _ggx_e(32, 32, 1 << 16, rng.random((32 * 32, 3)), False, e)
    out["ggx_E"] = e.reshape(32, 32)
    e = np.empty(32)
    _ggx_e(32, 1, 1 << 22, rng.random((32, 3)), True, e)
    out["ggx_Eavg"] = e
    g = np.empty((2, 16 ** 3))
    ga = np.empty((2, 16 * 16))
    for side in (0, 1):
        _glass_e(16, 16, 16, side == 1, 1 << 15, rng.random((16 ** 3, 3)), False, g[side])
        _glass_e(16, 1, 16, side == 1, 1 << 19, rng.random((16 * 16, 3)), True, ga[side])
    out["glass_E"] = g.reshape(2, 16, 16, 16)
    out["glass_Eavg"] = ga.reshape(2, 16, 16)
    s = np.empty(16 ** 3)
    _schlick_s(16, 16, 16, False, 1 << 13, rng.random((16 ** 3, 3)), s)
    out["schlick_s"] = s.reshape(16, 16, 16)
    s5 = np.empty(16 * 16)
    _schlick_s(16, 16, 1, True, 1 << 14, rng.random((16 * 16, 3)), s5)
    out["schlick5_s"] = s5.reshape(16, 16)
    out["sheen"] = sheen_from_cycles(argv[0])
    np.savez_compressed(albedo_tables.PATH, **{k: out[k].astype(np.float32) for k in
                                               albedo_tables.NAMES})
    print(f"wrote {albedo_tables.PATH} in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main(sys.argv[1:])

"""Wavelengths and their RGB: sampling a wavelength for a dispersive path and turning what
it carries back into linear Rec.709 RGB (docs/dispersion.md).

The CIE 1931 2-degree colour matching functions come from Wyman, Sloan and Shirley 2013
("Simple analytic approximations to the CIE XYZ color matching functions", the multi-lobe
fit, within ~1 % of the peak of the tabulated functions); XYZ -> linear Rec.709 (sRGB
primaries, D65 white) by the standard matrix. Where a pure wavelength lies outside the
Rec.709 gamut its negative channels are clipped to zero: the rainbow's hues are the gamut's
edge, and nothing negative ever enters a photon's flux.

How white is upsampled: each RGB channel c is its own basis spectrum B_c(lambda), the
clipped Rec.709 matching function of c normalised so that its integral over 380-780 nm is
exactly 1. A path carrying RGB throughput beta that meets a dispersive surface picks one
wavelength with pdf p(lambda) = (B_r + B_g + B_b) / 3 and from then on carries
beta * w(lambda), w_c = B_c / p = 3 B_c / sum(B) in [0, 3]: E[w] = (1, 1, 1) exactly for
every channel, so white stays white, any RGB colour keeps its mean, and a white light
through a prism spreads into the hues of ``weights`` at each wavelength. The functions are
tabulated as averages over 1 nm bins (400 bins) and sampled bin by bin, so the expectation
is exact up to float rounding (the table sums to 1 by construction), not up to a fit.

Why one wavelength per photon and not hero wavelengths: a photon stays RGB until its first
dispersive refraction, where it picks its wavelength (non-dispersive scenes are then
bit-identical to the RGB renderer). At a smooth dispersive interface each wavelength
refracts into its own delta direction, so the hero scheme's secondary wavelengths have
zero pdf along the hero's path and would be dropped there anyway (pbrt-v4 terminates
them the same way); keeping them would cost four-wavelength arithmetic everywhere else
for no variance gain on the paths that need it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

LAMBDA_MIN = 380.0
LAMBDA_MAX = 780.0
"""The sampled range, nm (visible light; the matching functions are < 1e-4 outside)."""

BINS = 400
BIN_WIDTH = (LAMBDA_MAX - LAMBDA_MIN) / BINS  # nm

XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])
"""XYZ -> linear Rec.709 / sRGB (D65 white maps to (1, 1, 1) for Y = 1)."""


def _lobe(lam, mu, s_low, s_high):
    s = np.where(lam < mu, s_low, s_high)
    return np.exp(-0.5 * ((lam - mu) / s) ** 2)


def cie_xyz(lam) -> np.ndarray:
    """CIE 1931 2-degree matching functions (x, y, z) at wavelengths lam (N,) nm -> (N, 3),
    Wyman et al. 2013's multi-lobe fit (y peaks at 1 near 555 nm)."""
    lam = np.asarray(lam, np.float64).reshape(-1)
    x = (1.056 * _lobe(lam, 599.8, 37.9, 31.0) + 0.362 * _lobe(lam, 442.0, 16.0, 26.7)
         - 0.065 * _lobe(lam, 501.1, 20.4, 26.2))
    y = 0.821 * _lobe(lam, 568.8, 46.9, 40.5) + 0.286 * _lobe(lam, 530.9, 16.3, 31.1)
    z = 1.217 * _lobe(lam, 437.0, 11.8, 36.0) + 0.681 * _lobe(lam, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=1)


def _basis_table() -> np.ndarray:
    """(BINS, 3) float64: B_c averaged over each 1 nm bin, each column summing to 1 / BIN_WIDTH
    so that sum(B) * BIN_WIDTH = 1 (1/nm)."""
    sub = 16
    lam = LAMBDA_MIN + (np.arange(BINS * sub) + 0.5) * (BIN_WIDTH / sub)
    rgb = np.maximum(cie_xyz(lam) @ XYZ_TO_REC709.T, 0.0).reshape(BINS, sub, 3).mean(axis=1)
    return rgb / (rgb.sum(axis=0) * BIN_WIDTH)


BASIS = _basis_table()
"""(BINS, 3) float64, 1/nm: the per-channel basis spectra B_c, bin-averaged."""

_PDF = BASIS.sum(axis=1) / 3.0
_CDF = np.concatenate([[0.0], np.cumsum(_PDF * BIN_WIDTH)])
_CDF[-1] = 1.0
_WEIGHTS = BASIS / _PDF[:, None]


@njit(cache=True, error_model="numpy")
def sample_wavelength(u):
    """A wavelength for a uniform u in [0, 1): (lambda nm, pdf 1/nm, w0, w1, w2), w the RGB
    weight the path's throughput is multiplied by from then on (module docstring)."""
    b = min(max(np.searchsorted(_CDF, u, side="right") - 1, 0), BINS - 1)
    span = _CDF[b + 1] - _CDF[b]
    frac = (u - _CDF[b]) / span if span > 0.0 else 0.5
    lam = LAMBDA_MIN + (b + min(max(frac, 0.0), 1.0)) * BIN_WIDTH
    return lam, _PDF[b], _WEIGHTS[b, 0], _WEIGHTS[b, 1], _WEIGHTS[b, 2]


@njit(cache=True, error_model="numpy")
def _vec_sample(u, lam, pdf, w):
    for i in range(u.shape[0]):
        lam[i], pdf[i], w[i, 0], w[i, 1], w[i, 2] = sample_wavelength(u[i])


def sample_wavelengths(u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sample_wavelength over uniforms u (N,): lambda (N,) nm, pdf (N,) 1/nm, w (N, 3)."""
    u = np.ascontiguousarray(np.asarray(u, np.float64).reshape(-1))
    lam = np.empty_like(u)
    pdf = np.empty_like(u)
    w = np.empty((u.shape[0], 3))
    _vec_sample(u, lam, pdf, w)
    return lam, pdf, w


def basis_at(lam) -> np.ndarray:
    """B_c at wavelengths lam (N,) nm -> (N, 3) 1/nm (the bin's average; 0 outside the range)."""
    lam = np.asarray(lam, np.float64).reshape(-1)
    b = np.floor((lam - LAMBDA_MIN) / BIN_WIDTH).astype(np.int64)
    inside = (b >= 0) & (b < BINS)
    out = np.zeros((lam.shape[0], 3))
    out[inside] = BASIS[b[inside]]
    return out

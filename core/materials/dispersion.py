"""Dispersion of transmission lobes: IOR(lambda) from the IOR at the Fraunhofer d line and
the Abbe number (docs/dispersion.md).

A two-term Cauchy law n(lambda) = A + B / lambda^2 (lambda in micrometres) through
n(587.6 nm) = n_d with n_F - n_C = (n_d - 1) / V_d, F = 486.1 nm, C = 656.3 nm:

    B = (n_d - 1) / (V_d (1 / lambda_F^2 - 1 / lambda_C^2)),   A = n_d - B / lambda_d^2.

V_d = 0 means no dispersion (the default): ``ior_at`` returns n_d itself, bit for bit.
The range of V_d (0 or >= ``contract.MIN_ABBE``) is checked once, by the scene contract.
The material's IOR slot is n_d (Blender's IOR is the d-line value, as glass catalogues).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

LAMBDA_D = 0.5876  # um, helium d line
LAMBDA_F = 0.4861  # um, hydrogen F line
LAMBDA_C = 0.6563  # um, hydrogen C line
_FC = 1.0 / (LAMBDA_F * LAMBDA_F) - 1.0 / (LAMBDA_C * LAMBDA_C)  # 1/um^2


@njit(cache=True, error_model="numpy")
def cauchy(n_d, abbe):
    """(A, B um^2) of the Cauchy fit; (n_d, 0) when abbe == 0."""
    if abbe == 0.0:
        return n_d, 0.0
    b = (n_d - 1.0) / (abbe * _FC)
    return n_d - b / (LAMBDA_D * LAMBDA_D), b


@njit(cache=True, error_model="numpy")
def ior_at(n_d, abbe, lam_nm):
    """The IOR at wavelength lam_nm (nm) of a material with d-line IOR n_d and Abbe number
    abbe (0: no dispersion, n_d returned unchanged)."""
    if abbe == 0.0:
        return n_d
    a, b = cauchy(n_d, abbe)
    lam = lam_nm * 1e-3
    return a + b / (lam * lam)


@njit(cache=True, error_model="numpy")
def _vec_ior(n_d, abbe, lam, out):
    for i in range(lam.shape[0]):
        out[i] = ior_at(n_d, abbe, lam[i])


def ior(n_d: float, abbe: float, lam_nm) -> np.ndarray:
    """ior_at over wavelengths lam_nm (N,) nm -> (N,) float64. The Abbe number's range
    (0 or >= MIN_ABBE) is the scene contract's to check (``Materials`` validation,
    core/scene/contract.py), where every material enters the renderer."""
    lam = np.ascontiguousarray(np.asarray(lam_nm, np.float64).reshape(-1))
    out = np.empty_like(lam)
    _vec_ior(float(n_d), float(abbe), lam, out)
    return out

"""Cycles' view-dependent input nodes as scalar numba functions (our own code after
kernel/svm/fresnel.h and closure/bsdf_util.h): Fresnel and Layer Weight.

Both read the point's incoming direction (Cycles' wi: towards where the ray came from; at a
photon hit that is the photon's origin side, docs/shading.md), a normal (the node's Normal
input, or the shading normal facing wi when unlinked) and whether the point is backfacing.
"""

from __future__ import annotations

import math

from numba import njit

from .. import _numba_cache  # noqa: F401
from .converters import clamp

_JIT = dict(cache=True, error_model="numpy")


@njit(**_JIT)
def fresnel_dielectric_cos(cosi, eta):
    """Unpolarised dielectric reflectance at |cos| = |cosi| for relative IOR eta; 1 under
    total internal reflection (Cycles' fresnel_dielectric_cos)."""
    c = abs(cosi)
    g = eta * eta - 1.0 + c * c
    if g > 0.0:
        g = math.sqrt(g)
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        return 0.5 * a * a * (1.0 + b * b)
    return 1.0


@njit(**_JIT)
def fresnel_node(ior, cos_wi_n, backfacing):
    """The Fresnel node: ior (>= 1e-5 after clamping, inverted on a backface),
    cos_wi_n = dot(wi, N)."""
    eta = max(ior, 1e-5)
    if backfacing:
        eta = 1.0 / eta
    return fresnel_dielectric_cos(cos_wi_n, eta)


@njit(**_JIT)
def layer_weight(blend, cos_wi_n, backfacing):
    """The Layer Weight node: (Fresnel, Facing) for blend in [0, 1] and cos_wi_n =
    dot(wi, N) (svm_node_layer_weight)."""
    eta = max(1.0 - blend, 1e-5)
    if not backfacing:
        eta = 1.0 / eta
    fres = fresnel_dielectric_cos(cos_wi_n, eta)
    f = abs(cos_wi_n)
    if blend != 0.5:
        b = clamp(blend, 0.0, 1.0 - 1e-5)
        b = 2.0 * b if b < 0.5 else 0.5 / (1.0 - b)
        f = f ** b
    return fres, 1.0 - f

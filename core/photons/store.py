"""Storing photons (the seed's "store" step): which hits keep a photon, and the arrays
they are kept in until the map is balanced.

Rules, decided at each surface hit before the bounce is chosen (``stores``):
- global map (MODE_GLOBAL), by the store rule: STORE_ALL at every hit on a surface with a
  diffuse lobe (final gathering's map, standard SPPM); STORE_BOUNCED only after at least
  one diffuse bounce (Jensen's map for the direct-visualisation preview); STORE_NOT_DIRECT
  at every diffuse hit but the first hit of a photon straight from its source (that light
  is the shadow rays', as in SPPM with shadow-ray direct light);
- caustic map (MODE_CAUSTIC): at the first diffuse hit after one or more specular or
  glossy bounces and no diffuse one (light -> S+ -> D).

``PhotonStore`` collects the stored photons of a pass bounce by bounce (float32 arrays),
in emission order, so the map does not depend on chunk sizes or threads.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

MODE_GLOBAL = 0
MODE_CAUSTIC = 1
STORE_ALL = 0
STORE_BOUNCED = 1
STORE_NOT_DIRECT = 2


@njit(cache=True, error_model="numpy")
def stores(mode, store_rule, diffuse_lobe, n_diffuse, n_specular):
    """True when a photon hitting a surface is stored there (module doc).

    diffuse_lobe: the surface has a diffuse lobe (albedo > 0); n_diffuse / n_specular: the
    photon's diffuse and specular (or glossy) bounces so far."""
    if not diffuse_lobe:
        return False
    if mode == MODE_CAUSTIC:
        return n_specular > 0 and n_diffuse == 0
    return (store_rule == STORE_ALL or n_diffuse > 0
            or (store_rule == STORE_NOT_DIRECT and n_specular > 0))


@njit(cache=True, parallel=True, error_model="numpy")
def _gather_rows(idx, a, b, c, a_out, b_out, c_out):
    for j in prange(idx.shape[0]):
        i = idx[j]
        for k in range(3):
            a_out[j, k] = a[i, k]
            b_out[j, k] = b[i, k]
            c_out[j, k] = c[i, k]


def compact_stored(store, pos, flux, direction):
    """The stored photons' (M, 3) rows of pos, flux and direction, in order."""
    idx = np.flatnonzero(store)
    m = idx.shape[0]
    out = (np.empty((m, 3), pos.dtype), np.empty((m, 3), flux.dtype),
           np.empty((m, 3), direction.dtype))
    if m:
        _gather_rows(idx, pos, flux, direction, *out)
    return out


class PhotonStore:
    """Stored photons, appended per bounce as (n, 3) float32 arrays of positions (metres),
    flux (watts) and incident directions (unit, towards where the photon came from)."""

    def __init__(self):
        self.pos, self.flux, self.dir = [], [], []
        self.count = 0

    def add(self, pos, flux, direction):
        if pos.shape[0]:
            self.pos.append(pos)
            self.flux.append(flux)
            self.dir.append(direction)
            self.count += pos.shape[0]

    def take(self):
        """The stored (M, 3) float32 arrays; the per-bounce pieces are released one array
        at a time, so the peak is one array's copy, not all three."""
        out = []
        for name in ("pos", "flux", "dir"):
            parts = getattr(self, name)
            out.append(np.concatenate(parts) if parts else np.zeros((0, 3), np.float32))
            setattr(self, name, [])
        return out

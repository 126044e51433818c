"""The medium the renderer integrates: the World's homogeneous volume (fog in all space).

This slice of the integration (docs/volumes.md, "Integration") renders the World's
volume only: every camera, shadow and photon segment lies in it, so no per-path volume
stack is needed. Media bounded by a closed mesh and heterogeneous density are refused by
``renderable`` with a SceneError naming the medium (the exporter reports them by name and
leaves them out, photon_engine/export_volumes.py).

Units: coefficients in 1/m, emission in W/(m^3 sr).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..scene.checks import SceneError
from ..scene.media import WORLD, Media


class WorldMedium(NamedTuple):
    """The World's medium. sigma_a, sigma_s, sigma_t, emission: (3,) float64 per RGB
    channel (1/m; emission W/(m^3 sr)); g: the Henyey-Greenstein anisotropy (float)."""

    sigma_a: np.ndarray
    sigma_s: np.ndarray
    sigma_t: np.ndarray
    emission: np.ndarray
    g: float
    name: str

    @property
    def scatters(self) -> bool:
        return bool(np.any(self.sigma_s > 0))


def renderable(media: Media) -> WorldMedium | None:
    """The World's medium of ``media`` as the renderer takes it, or None when there is no
    medium or the World's has no effect (all coefficients and emission 0: the scene then
    renders exactly as without media).

    Raises SceneError naming the medium for what the renderer does not integrate yet: a
    medium bounded by a closed mesh, or a density texture."""
    for i in range(media.count):
        name = media.names[i] if i < len(media.names) else f"medium {i}"
        if int(media.bounds[i]) != WORLD:
            raise SceneError(f"medium '{name}': media inside closed meshes are not supported "
                             f"by the renderer yet (only the World's volume is)")
        if int(media.density_texture[i]) != -1:
            raise SceneError(f"medium '{name}': heterogeneous density (a density texture) is "
                             f"not supported by the renderer yet")
    w = media.world
    if w < 0:
        return None
    sa = media.sigma_a[w].astype(np.float64)
    ss = media.sigma_s[w].astype(np.float64)
    em = media.emission[w].astype(np.float64)
    if not (np.any(sa > 0) or np.any(ss > 0) or np.any(em > 0)):
        return None
    return WorldMedium(sigma_a=sa, sigma_s=ss, sigma_t=sa + ss, emission=em,
                       g=float(media.anisotropy[w]),
                       name=media.names[w] if w < len(media.names) else f"medium {w}")


def transmittance(medium: WorldMedium, t: np.ndarray) -> np.ndarray:
    """exp(-sigma_t t) (N, 3) float64 for segment lengths t (N,) metres (inf allowed:
    0 in every channel with sigma_t > 0, 1 in the clear ones)."""
    t = np.asarray(t, np.float64)
    with np.errstate(invalid="ignore"):
        tau = medium.sigma_t[None, :] * t[:, None]
    return np.exp(-np.where(medium.sigma_t[None, :] > 0, tau, 0.0))


def emitted(medium: WorldMedium, t: np.ndarray) -> np.ndarray:
    """The medium's emission integrated along segments of length t (N,) metres: the
    integral of exp(-sigma_t s) emission ds over [0, t], (N, 3) W/(m^2 sr)."""
    t = np.asarray(t, np.float64)[:, None]
    st = medium.sigma_t[None, :]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        decay = np.where(st > 0, -np.expm1(-st * t) / np.where(st > 0, st, 1.0), t)
    return np.where(medium.emission[None, :] > 0, medium.emission[None, :] * decay, 0.0)


def attenuate(medium: WorldMedium, contrib: np.ndarray, need: np.ndarray,
              length: np.ndarray) -> None:
    """contrib[need] *= exp(-sigma_t length[need]) in place: shadow rays' light (N, 3)
    times the transmittance of their segments (length (N,) metres; the sun's and world's
    3e38 m give 0 in every channel with sigma_t > 0)."""
    idx = np.flatnonzero(need)
    if idx.size:
        contrib[idx] *= transmittance(medium, length[idx])

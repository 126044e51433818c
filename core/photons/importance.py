"""Visual importance of the photon sources: how many photons each light gets.

Power alone shares photons badly when a bright light's photons never reach what the
camera sees (a lamp in the next room, a sun on the roof of a closed room). Before the
photon pass the tracer (core/photons/tracing.py) measures, per source and map:

1. Camera pre-pass: about PREPASS_PIXELS camera rays on a coarse pixel grid over the
   same film (one jittered ray per coarse pixel), following mirrors and glass exactly as
   the progressive camera pass does (``camera_paths.visible_points``), give the visible diffuse
   points with their normals facing the viewer.
2. Pilot pass: PILOT_PHOTONS photons per source, traced with the map's own rules
   (global: unaimed, stored at every diffuse hit; caustic: aimed at the specular objects,
   stored at the first diffuse hit after a specular bounce), with random streams of their
   own (the real pass's photons do not repeat them).
3. Score: the flux of a source's pilot photons stored within ``radius`` of a visible
   point, on the side the camera sees (n_g . w_p > 0), divided by the source's power:
   f_s, the fraction of its power that lands where the camera looks (bounces included;
   it can exceed 1 since a photon is stored at every diffuse hit). The importance is
   I_s = f_s / max_s f_s, in [0, 1].

Allocation: n_s proportional to luminance(P_s) x (FLOOR + (1 - FLOOR) I_s), largest
remainder, and never fewer than one photon per source when there are enough photons.
With all I_s equal it is the power share. The estimate stays unbiased whatever the
I_s: emission divides each photon's flux by its own source's photon count n_s, so every
source's photons still carry exactly its power (tested); only the variance moves, from
the lights the camera does not see to those it does. The floor keeps every source
traced (no light is ever dropped on the strength of a few pilot photons).

The radius: COVER x sqrt(A_d / (pi V)) for V visible points over the diffuse area A_d (the
discs of the visible points would cover all diffuse surfaces), or the map's automatic
gather radius (estimate.auto_radius) when wider (capped at 4 times the former), so a photon
counts when it could enter a visible point's radiance estimate.

The pre-pass's camera paths are the integrators' (core/integrators/camera_paths.py): the
caller hands ``tracing.trace_photons`` a ``prepass`` that returns the VisibleView.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from . import emission
from .estimate import auto_radius
from .hash_grid import HashGrid, within

PREPASS_PIXELS = 4096
"""Camera rays of the pre-pass (a coarse grid over the film, aspect kept)."""
PILOT_PHOTONS = 4096
"""Pilot photons per source and map (fewer when the map has few photons, see pilot_count)."""
MIN_PILOT = 256
"""Below this many pilot photons per source the estimate is too noisy: power only."""
FLOOR = 0.05
"""Share of its power weight a source keeps when none of its pilot photons reach the view."""
COVER = 2.0
"""Radius factor over the visible points' spacing sqrt(A_d / (pi V))."""
MAP_PILOT = 2
"""Random-stream map ids of the pilot passes: MAP_PILOT + tracing's map id."""
PILOT_SEEDS = 1 << 20
"""Pilot seeds are ``sampling.pass_seed`` of indices from here on (no pass reaches it)."""


def pilot_seed(seed: int, source_slot: int, map_id: int) -> int:
    """The photon seed of a source's pilot for one map: a seed of its own per (source,
    map), so the pilot shares no random numbers with the real pass, whose streams are
    keyed by (seed, map 0/1, slot)."""
    return sampling.pass_seed(seed, PILOT_SEEDS + 2 * source_slot + map_id)


@dataclass
class VisibleView:
    """Visible diffuse points of the pre-pass: position (V, 3) float64 metres, ng (V, 3)
    unit geometric normals facing the viewer; rays: camera rays traced; time: seconds."""

    position: np.ndarray
    ng: np.ndarray
    rays: int
    time: float


def prepass_resolution(width: int, height: int, pixels: int = PREPASS_PIXELS) -> tuple[int, int]:
    """(w, h) of the coarse grid: about ``pixels`` in the image's aspect, never finer
    than the image itself."""
    aspect = width / max(height, 1)
    w = max(1, min(int(width), int(round(np.sqrt(pixels * aspect)))))
    h = max(1, min(int(height), int(round(pixels / w))))
    return w, h


def view_radius(diffuse_area: float, visible: int, k: int, photons: int) -> float:
    """The scoring radius of the module doc, metres (0 when nothing is visible)."""
    if visible <= 0 or diffuse_area <= 0:
        return 0.0
    r = COVER * np.sqrt(diffuse_area / (np.pi * visible))
    # The map's own gather radius when wider, but within 4 r: a huge radius (few photons)
    # would make every photon "near" and the grid one cell.
    return float(max(r, min(auto_radius(diffuse_area, k, photons), 4.0 * r)))


def pilot_count(photons: int, sources: int) -> int:
    """Pilot photons per source: PILOT_PHOTONS, or an eighth of the map's photons per source
    when that is fewer (the pilot stays a small fraction of the pass)."""
    if sources <= 0:
        return 0
    return int(min(PILOT_PHOTONS, photons // (8 * sources)))


@njit(cache=True, parallel=True, error_model="numpy")
def _near_kernel(ph_pos, ph_dir, vp_pos, vp_ng, cells, start, order, lo, inv_h, mask, r2, out):
    """out[p] = True when a visible point lies within sqrt(r2) of photon p and the photon
    arrived on the side that point is seen from. The grid's cells are >= the radius, so
    the 27 cells around the photon's hold every candidate."""
    for p in prange(ph_pos.shape[0]):
        px, py, pz = ph_pos[p, 0], ph_pos[p, 1], ph_pos[p, 2]
        found = False
        for i in within(px, py, pz, r2, 1, vp_pos, lo, inv_h, mask, cells, start, order):
            if (vp_ng[i, 0] * ph_dir[p, 0] + vp_ng[i, 1] * ph_dir[p, 1]
                    + vp_ng[i, 2] * ph_dir[p, 2]) > 0.0:
                found = True
                break
        out[p] = found


class ViewGrid:
    """A hash grid over the visible points (cells as wide as the radius) answering
    "is this photon near what the camera sees?"."""

    def __init__(self, view: VisibleView, radius: float):
        self.view, self.radius = view, float(radius)
        n = view.position.shape[0]
        self.empty = n == 0 or not radius > 0
        if self.empty:
            return
        self.grid = HashGrid(view.position, self.radius)

    def near(self, positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(M,) bool for photons at positions (M, 3) arriving from directions (M, 3)."""
        m = positions.shape[0]
        out = np.zeros(m, bool)
        if self.empty or m == 0:
            return out
        g = self.grid
        _near_kernel(np.ascontiguousarray(positions, np.float64),
                     np.ascontiguousarray(directions, np.float64), self.view.position,
                     self.view.ng, g.cells, g.start, g.order, g.lo, g.inv_h, g.mask,
                     self.radius * self.radius, out)
        return out


def weights(power_luminance: np.ndarray, importance: np.ndarray) -> np.ndarray:
    """Allocation weights (S,): luminance(P_s) x (FLOOR + (1 - FLOOR) I_s)."""
    return np.asarray(power_luminance, np.float64) * (
        FLOOR + (1.0 - FLOOR) * np.clip(np.asarray(importance, np.float64), 0.0, 1.0))


def allocate(weight: np.ndarray, total: int) -> np.ndarray:
    """``emission.allocate`` with at least one photon per source of positive weight when
    ``total`` allows: no source is ever left out by rounding."""
    w = np.asarray(weight, np.float64)
    live = w > 0
    k = int(live.sum())
    if total <= 0 or k == 0 or total < k:
        return emission.allocate(w, total)
    return emission.allocate(w, total - k) + live.astype(np.int64)


def importance_of(fraction: np.ndarray) -> np.ndarray:
    """I_s = f_s / max f_s (all ones when no source reaches the view: power only)."""
    f = np.asarray(fraction, np.float64)
    top = float(f.max()) if f.size else 0.0
    if not top > 0:
        return np.ones_like(f)
    return np.clip(f / top, 0.0, 1.0)

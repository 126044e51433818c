"""Heterogeneous density: rho(x) of the media whose density a shader program gives, and the
majorant each is tracked with (docs/volumes.md "Heterogeneous density").

This module owns the bound and the clipping; the program itself is run by
core/shading/interpreter.py, bound to each medium by core/prepared.py (rank 3: media and
shading are both rank 2) as ``evaluate(points (K, 3) float64 render-frame metres) -> (K,)``
(it builds the program's Position, Object and Generated inputs as at a surface hit).

**The majorant.** Null-collision tracking needs sigma_bar >= sigma_t(x) on every segment it
walks; an underestimate biases the result. A program is not bounded analytically (a Noise
texture's range depends on its detail, roughness and distortion), so the bound is measured:
the program on a GRID^3 lattice of points spanning the medium's world box (cell centres and
the box's corners), its maximum times SAFETY. Between lattice points a smooth texture can
exceed the sampled maximum, which SAFETY covers for features larger than a cell; where a
tracked point still exceeds it, the density is clipped to the majorant (a bias, bounded by
what was clipped) and counted in ``clipped`` / ``clipped_max``, which the render reports as
a warning naming the medium. A negative program value is taken as 0 (Cycles clamps the
density at 0 too: ``fmaxf(density, 0.0f)`` in svm_node_principled_volume).
"""

from __future__ import annotations

import numpy as np

GRID = 24
"""Lattice points per axis of the majorant's measurement (24^3 = 13,824 evaluations)."""

SAFETY = 1.5
"""The measured maximum is multiplied by this to give the majorant."""


class DensityFields:
    """The densities of a scene's heterogeneous media.

    evaluators: {medium row: evaluate(points (K, 3) float64 metres) -> (K,) float} the
    program's value; boxes: {medium row: (lo, hi) (3,) metres} the region the majorant
    covers (the medium's boundary box); names: the media's names.
    """

    def __init__(self, evaluators: dict, boxes: dict, names):
        self.evaluators = dict(evaluators)
        self.names = tuple(names)
        self.clipped = {m: 0 for m in self.evaluators}
        self.clipped_max = {m: 0.0 for m in self.evaluators}
        self.majorant = {m: measure_majorant(self._raw(m), *boxes[m])
                         for m in self.evaluators}

    def _raw(self, m: int):
        """rho of medium m at world points (K, 3) -> (K,) float64, not clipped."""
        ev = self.evaluators[m]

        def rho(points):
            v = np.asarray(ev(np.asarray(points, np.float64)), np.float64)
            return np.where(np.isfinite(v), np.maximum(v, 0.0), 0.0)
        return rho

    def __call__(self, points, field) -> np.ndarray:
        """rho (K,) float64 at world points (K, 3) metres of the media field (K,) int64,
        clipped to each medium's majorant (module doc)."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        f = np.asarray(field, np.int64).reshape(-1)
        out = np.zeros(p.shape[0])
        for m in np.unique(f):
            sel = np.flatnonzero(f == m)
            v = self._raw(int(m))(p[sel])
            maj = self.majorant[int(m)]
            over = v > maj
            if over.any():
                self.clipped[int(m)] += int(over.sum())
                self.clipped_max[int(m)] = max(self.clipped_max[int(m)], float(v.max()))
                v = np.minimum(v, maj)
            out[sel] = v
        return out

    def warnings(self) -> list[str]:
        """One message per medium whose majorant a tracked point exceeded."""
        return [f"medium '{self.names[m]}': the density reached {self.clipped_max[m]:.4g} at "
                f"{n} tracked points, above its majorant {self.majorant[m]:.4g} (measured on a "
                f"{GRID}^3 lattice x {SAFETY}); clipped there (biased: the texture has "
                f"features finer than the lattice)"
                for m, n in self.clipped.items() if n]


def measure_majorant(rho, lo, hi, grid: int = GRID, safety: float = SAFETY) -> float:
    """SAFETY x the maximum of rho(points (K, 3)) over a grid^3 lattice of cell centres of
    the box [lo, hi] (metres) and its 8 corners (module doc)."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    axes = [lo[k] + (np.arange(grid) + 0.5) / grid * (hi[k] - lo[k]) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    corners = np.array([[(lo, hi)[(c >> k) & 1][k] for k in range(3)] for c in range(8)])
    v = rho(np.concatenate([pts, corners]))
    return float(safety * v.max()) if v.size else 0.0

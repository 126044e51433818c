"""Bounding spheres and boxes of the scene and of its objects (the projection map's targets,
photon emission's reach)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SPHERE_MARGIN = 1.02
"""Object spheres are this much wider than the farthest corner (float32 vertices)."""


@dataclass(frozen=True)
class Targets:
    """Spheres the aimed emission shoots at. centre (K, 3) float64, radius (K,) metres;
    optionally the objects' boxes lo, hi (K, 3) (tighter reach tests for flat objects)."""

    centre: np.ndarray
    radius: np.ndarray
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.radius.shape[0])


def bounding_sphere(lo, hi) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius (metres) of the sphere around an axis-aligned box."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return 0.5 * (lo + hi), float(0.5 * np.linalg.norm(hi - lo))


def object_spheres(tri_vertices: np.ndarray, object_index: np.ndarray,
                   n_objects: int) -> Targets:
    """Bounding sphere of every object (centre of its box, radius to its farthest corner).

    tri_vertices (T, 3, 3) float32; object_index (T,) int32. Objects without triangles get
    radius -1.
    """
    tv = np.asarray(tri_vertices, np.float64).reshape(-1, 3, 3)
    obj = np.asarray(object_index, np.int64)
    lo = np.full((n_objects, 3), np.inf)
    hi = np.full((n_objects, 3), -np.inf)
    for c in range(3):
        np.minimum.at(lo, obj, tv[:, c])
        np.maximum.at(hi, obj, tv[:, c])
    present = np.all(np.isfinite(lo), axis=1)
    # inf + -inf of an object without triangles is not evaluated (no RuntimeWarning)
    centre = np.zeros((n_objects, 3))
    centre[present] = 0.5 * (lo[present] + hi[present])
    r2 = np.zeros(n_objects)
    for c in range(3):
        np.maximum.at(r2, obj, np.sum((tv[:, c] - centre[obj]) ** 2, axis=1))
    radius = np.where(present, np.sqrt(r2) * SPHERE_MARGIN, -1.0)
    return Targets(centre, radius, np.where(present[:, None], lo, 0.0),
                   np.where(present[:, None], hi, 0.0))



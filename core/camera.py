"""Camera rays for a batch of (pixel, sample) pairs, perspective or orthographic.

Pixel p of a W x H image is column ``p % W`` and row ``p // W``, row 0 at the TOP. A
jitter (jx, jy) in [0, 1)^2 places the sample inside the pixel: film coordinate
``x = (col + jx) / W`` left to right, ``y = (row + jy) / H`` top to bottom.

Clipping follows Cycles (``kernel/camera/camera.h``): it clips at the planes at depth
``clip_start`` and ``clip_end`` along the view axis, so a perspective ray leaving at angle
theta from the axis starts at distance ``clip_start / cos(theta)`` and ends at
``clip_end / cos(theta)``. The ray origin is moved to the near plane (Embree has no tnear)
and ``tmax`` is measured from there.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .scene import CAMERA_ORTHOGRAPHIC, Camera


class CameraRays(NamedTuple):
    """origins, directions: (N, 3) float64, metres / unit vectors; tmax: (N,) float64, metres."""

    origins: np.ndarray
    directions: np.ndarray
    tmax: np.ndarray


def camera_frame(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(position, right, up, back) float64 (3,) each: the camera's world origin and unit axes.

    The axes are normalised, so a matrix that still carries a scale gives the same rays.
    """
    m = np.asarray(camera.to_world, np.float64)
    axes = []
    for k in range(3):
        a = m[:3, k]
        n = np.linalg.norm(a)
        axes.append(a / n if n > 0 else np.eye(3)[k])
    return m[:3, 3].copy(), axes[0], axes[1], axes[2]


def film_coordinates(camera: Camera, pixel: np.ndarray, jitter: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Film-plane (x, y) (N,) float64 of each sample, in film units, y up, shift applied."""
    w, h = int(camera.width), int(camera.height)
    pixel = np.asarray(pixel, np.int64)
    col = (pixel % w).astype(np.float64)
    row = (pixel // w).astype(np.float64)
    fx = (col + jitter[:, 0]) / w
    fy = (row + jitter[:, 1]) / h
    size = np.asarray(camera.film_size, np.float64)
    shift = np.asarray(camera.film_shift, np.float64)
    x = (fx - 0.5) * size[0] + shift[0]
    y = (0.5 - fy) * size[1] + shift[1]
    return x, y


@njit(cache=True, parallel=True, error_model="numpy")
def _rays_kernel(pixel, jitter, w, h, size, shift, pos, right, up, back, near, far, ortho,
                 o_out, d_out, t_out):
    for i in prange(pixel.shape[0]):
        col = pixel[i] % w
        row = pixel[i] // w
        x = ((col + jitter[i, 0]) / w - 0.5) * size[0] + shift[0]
        y = (0.5 - (row + jitter[i, 1]) / h) * size[1] + shift[1]
        if ortho:
            for k in range(3):
                o_out[i, k] = pos[k] + x * right[k] + y * up[k] - near * back[k]
                d_out[i, k] = -back[k]
            t_out[i] = far - near
        else:
            # Through the film point at depth 1; the length is 1 / cos(theta).
            ln = np.sqrt(x * x + y * y + 1.0)
            for k in range(3):
                d = (x * right[k] + y * up[k] - back[k]) / ln
                d_out[i, k] = d
                o_out[i, k] = pos[k] + near * ln * d
            t_out[i] = (far - near) * ln


def generate_rays(camera: Camera, pixel: np.ndarray, jitter: np.ndarray) -> CameraRays:
    """Rays for pixel indices (N,) int64 with jitter (N, 2) float64 in [0, 1)."""
    pos, right, up, back = camera_frame(camera)
    pixel = np.ascontiguousarray(pixel, np.int64)
    jitter = np.ascontiguousarray(jitter, np.float64).reshape(-1, 2)
    n = pixel.shape[0]
    origins, directions, tmax = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    if n:
        _rays_kernel(pixel, jitter, int(camera.width), int(camera.height),
                     np.asarray(camera.film_size, np.float64), np.asarray(camera.film_shift, np.float64),
                     pos, right, up, back, float(camera.clip_start), float(camera.clip_end),
                     camera.kind == CAMERA_ORTHOGRAPHIC, origins, directions, tmax)
    return CameraRays(origins, directions, tmax)


def project(camera: Camera, points: np.ndarray) -> np.ndarray:
    """Continuous pixel coordinates (N, 2) float64 (column, row; row 0 at top) of world points.

    The inverse of ``generate_rays`` for tests and debugging: a sample with jitter j in
    pixel (c, r) projects to (c + jx, r + jy).
    """
    pos, right, up, back = camera_frame(camera)
    p = np.asarray(points, np.float64).reshape(-1, 3) - pos
    lx, ly, lz = p @ right, p @ up, p @ back
    if camera.kind == CAMERA_ORTHOGRAPHIC:
        x, y = lx, ly
    else:
        x, y = lx / -lz, ly / -lz
    size = np.asarray(camera.film_size, np.float64)
    shift = np.asarray(camera.film_shift, np.float64)
    fx = (x - shift[0]) / size[0] + 0.5
    fy = 0.5 - (y - shift[1]) / size[1]
    return np.stack([fx * camera.width, fy * camera.height], axis=1)

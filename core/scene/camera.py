"""Camera rays for a batch of (pixel, sample) pairs, perspective or orthographic.

Pixel p of a W x H image is column ``p % W`` and row ``p // W``, row 0 at the TOP. A
jitter (jx, jy) in [0, 1)^2 places the sample inside the pixel: film coordinate
``x = (col + jx) / W`` left to right, ``y = (row + jy) / H`` top to bottom.

Clipping follows Cycles (``kernel/camera/camera.h``): it clips at the planes at depth
``clip_start`` and ``clip_end`` along the view axis, so a perspective ray leaving at angle
theta from the axis starts at distance ``clip_start / cos(theta)`` and ends at
``clip_end / cos(theta)``. The ray origin is moved to the near plane (Embree has no tnear)
and ``tmax`` is measured from there.

Depth of field (``Camera.aperture_radius`` > 0, perspective only) is Cycles' thin lens
(kernel/camera/camera.h, ``camera_sample_perspective``): the pinhole ray through the
film point meets the plane in focus at depth ``focus_distance``; the ray starts instead
at a point of the aperture (a disk, or a regular polygon of ``aperture_blades`` corners
turned by ``aperture_rotation``; x divided by ``aperture_ratio``) of radius
``aperture_radius`` and aims at that focus point; the near clip distance is the pinhole
ray's, measured along the new direction. Two more uniforms per ray (``lens``) pick the
aperture point; a pinhole camera ignores them, so its rays are unchanged bit for bit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .contract import CAMERA_ORTHOGRAPHIC, CAMERA_PERSPECTIVE, Camera


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


def has_aperture(camera: Camera) -> bool:
    """True when the camera has depth of field (callers then pass ``lens`` samples):
    perspective or orthographic, as in Cycles."""
    return float(camera.aperture_radius) > 0.0


@njit(cache=True, error_model="numpy")
def aperture_point(u, v, blades, rotation, ratio):
    """(x, y) on the unit aperture from two uniforms in [0, 1): uniform on the unit disk
    (Shirley's concentric map) when blades < 3, else uniform on the regular polygon of
    ``blades`` corners on the unit circle, the first at angle ``rotation``; x / ratio."""
    if blades < 3:
        a, b = 2.0 * u - 1.0, 2.0 * v - 1.0
        if a == 0.0 and b == 0.0:
            return 0.0, 0.0
        if abs(a) > abs(b):
            r, phi = a, 0.25 * np.pi * (b / a)
        else:
            r, phi = b, 0.5 * np.pi - 0.25 * np.pi * (a / b)
        return r * np.cos(phi) / ratio, r * np.sin(phi)
    # Pick a triangle (centre, corner k, corner k + 1), then a uniform point in it.
    t = u * blades
    k = min(np.floor(t), blades - 1.0)
    u2 = t - k
    step = 2.0 * np.pi / blades
    a0, a1 = rotation + k * step, rotation + (k + 1.0) * step
    su = np.sqrt(u2)
    w1, w2 = su * (1.0 - v), su * v
    x = w1 * np.cos(a0) + w2 * np.cos(a1)
    y = w1 * np.sin(a0) + w2 * np.sin(a1)
    return x / ratio, y


@njit(cache=True, parallel=True, error_model="numpy")
def _lens_rays_kernel(pixel, jitter, lens, w, h, size, shift, pos, right, up, back, near, far,
                      radius, focus, blades, rotation, ratio, ortho, o_out, d_out, t_out):
    """Thin-lens rays as Cycles' camera_sample_perspective / camera_sample_orthographic
    (kernel/camera/camera.h) make them. Perspective: from the lens point through the film
    point's focus point (x, y, 1) x focus. Orthographic: the lens point offsets the origin
    in the camera plane, and the direction runs from the lens point to the axis point at
    the focus distance, so every ray of a film point (x, y) meets at (x, y, focus); the
    origin then moves along the ray to the near clip plane (depth ``near``)."""
    for i in prange(pixel.shape[0]):
        col = pixel[i] % w
        row = pixel[i] // w
        x = ((col + jitter[i, 0]) / w - 0.5) * size[0] + shift[0]
        y = (0.5 - (row + jitter[i, 1]) / h) * size[1] + shift[1]
        lx, ly = aperture_point(lens[i, 0], lens[i, 1], blades, rotation, ratio)
        lx *= radius
        ly *= radius
        if ortho:
            dx, dy, dz = -lx, -ly, focus
            dl = np.sqrt(dx * dx + dy * dy + dz * dz)
            dx, dy, dz = dx / dl, dy / dl, dz / dl
            ox, oy = x + lx + dx * near / dz, y + ly + dy * near / dz
            for k in range(3):
                d_out[i, k] = dx * right[k] + dy * up[k] - dz * back[k]
                o_out[i, k] = pos[k] + ox * right[k] + oy * up[k] - near * back[k]
            t_out[i] = far - near
            continue
        ln = np.sqrt(x * x + y * y + 1.0)  # 1 / cos(theta) of the pinhole ray
        # Focus point (camera space, depth focus) minus the lens point, normalised.
        dx, dy, dz = x * focus - lx, y * focus - ly, focus
        dl = np.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx / dl, dy / dl, dz / dl
        for k in range(3):
            d = dx * right[k] + dy * up[k] - dz * back[k]
            d_out[i, k] = d
            o_out[i, k] = pos[k] + lx * right[k] + ly * up[k] + near * ln * d
        t_out[i] = (far - near) * ln


def region_of(camera: Camera) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels rendered (row 0 at the top, x1 and y1 exclusive): the
    camera's region, else the whole frame."""
    if camera.region is None:
        return 0, 0, int(camera.width), int(camera.height)
    return tuple(int(v) for v in camera.region)


def region_pixels(camera: Camera) -> np.ndarray:
    """(N,) int64 frame pixel indices (y * width + x) of the region, row-major from its
    top-left: the indices the rays and the random numbers of a whole-frame render use,
    so a region's pixels are the same pixels of the whole render."""
    x0, y0, x1, y1 = region_of(camera)
    rows = np.arange(y0, y1, dtype=np.int64)[:, None] * int(camera.width)
    return (rows + np.arange(x0, x1, dtype=np.int64)[None, :]).reshape(-1)


def crop_to_region(image: np.ndarray, camera: Camera) -> np.ndarray:
    """The region's pixels of a whole-frame (H, W, C) image (row 0 at the top)."""
    x0, y0, x1, y1 = region_of(camera)
    return np.ascontiguousarray(image[y0:y1, x0:x1])


def generate_rays(camera: Camera, pixel: np.ndarray, jitter: np.ndarray,
                  lens: np.ndarray | None = None) -> CameraRays:
    """Rays for pixel indices (N,) int64 with jitter (N, 2) float64 in [0, 1).

    lens: (N, 2) float64 uniforms in [0, 1) choosing each ray's point on the aperture;
    needed when ``has_aperture(camera)``, ignored otherwise.
    """
    if has_aperture(camera):
        if lens is None:
            raise ValueError("a camera with depth of field needs lens samples")
        pos, right, up, back = camera_frame(camera)
        pixel = np.ascontiguousarray(pixel, np.int64)
        jitter = np.ascontiguousarray(jitter, np.float64).reshape(-1, 2)
        lens = np.ascontiguousarray(lens, np.float64).reshape(-1, 2)
        n = pixel.shape[0]
        origins, directions, tmax = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        if n:
            _lens_rays_kernel(pixel, jitter, lens, int(camera.width), int(camera.height),
                              np.asarray(camera.film_size, np.float64),
                              np.asarray(camera.film_shift, np.float64), pos, right, up, back,
                              float(camera.clip_start), float(camera.clip_end),
                              float(camera.aperture_radius), float(camera.focus_distance),
                              float(camera.aperture_blades), float(camera.aperture_rotation),
                              float(camera.aperture_ratio), camera.kind == CAMERA_ORTHOGRAPHIC,
                              origins, directions, tmax)
        return CameraRays(origins, directions, tmax)
    return _pinhole_rays(camera, pixel, jitter)


def _pinhole_rays(camera: Camera, pixel: np.ndarray, jitter: np.ndarray) -> CameraRays:
    """Pinhole or orthographic rays (generate_rays without an aperture)."""
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


def camera_from_projection(to_world: np.ndarray, projection: np.ndarray, width: int,
                           height: int, name: str = "Viewport") -> Camera:
    """The Camera whose rays are those of an OpenGL-style view: ``to_world`` (4, 4) the
    view's camera-to-world matrix (the inverse of a view matrix, looking along -Z),
    ``projection`` (4, 4) its projection matrix (perspective when its last row is
    (0, 0, -1, 0), orthographic when (0, 0, 0, 1)), ``width`` x ``height`` pixels covering
    normalised device coordinates [-1, 1]^2. Used for Blender's 3D viewport, whose
    ``window_matrix`` already holds the zoom, the pan and the camera-view frame.

    Perspective, at depth 1: x = (x_ndc + P[0, 2]) / P[0, 0], so the film is 2 / P[0, 0]
    wide with its centre at P[0, 2] / P[0, 0]; the near and far planes are
    P[2, 3] / (P[2, 2] -+ 1). Orthographic: x = (x_ndc - P[0, 3]) / P[0, 0] metres, planes
    at (P[2, 3] +- 1) / P[2, 2]; a near plane behind the eye (Blender's orthographic
    viewport sees both sides of its pivot) moves the origin back to it, which changes no
    orthographic ray. Raises ValueError for another matrix.
    """
    p = np.asarray(projection, np.float64)
    m = np.array(to_world, np.float64)
    if p.shape != (4, 4) or m.shape != (4, 4) or not (np.isfinite(p).all() and np.isfinite(m).all()):
        raise ValueError("to_world and projection must be finite (4, 4) matrices")
    if p[0, 0] == 0.0 or p[1, 1] == 0.0 or p[2, 2] == 0.0:
        raise ValueError(f"projection matrix has a zero scale: {p.tolist()}")
    size = np.array([2.0 / abs(p[0, 0]), 2.0 / abs(p[1, 1])])
    if np.allclose(p[3], (0.0, 0.0, -1.0, 0.0)):
        kind = CAMERA_PERSPECTIVE
        shift = np.array([p[0, 2] / p[0, 0], p[1, 2] / p[1, 1]])
        near, far = p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)
    elif np.allclose(p[3], (0.0, 0.0, 0.0, 1.0)):
        kind = CAMERA_ORTHOGRAPHIC
        shift = np.array([-p[0, 3] / p[0, 0], -p[1, 3] / p[1, 1]])
        near, far = (p[2, 3] + 1.0) / p[2, 2], (p[2, 3] - 1.0) / p[2, 2]
    else:
        raise ValueError(f"not a perspective or orthographic projection: {p.tolist()}")
    near, far = float(near), float(far)
    if kind == CAMERA_ORTHOGRAPHIC and near < 0.0:
        back = m[:3, 2] / np.linalg.norm(m[:3, 2])
        m[:3, 3] -= near * back
        near, far = 0.0, far - near
    near = max(0.0, near)
    if not near < far:
        raise ValueError(f"projection gives clipping planes {near} .. {far}")
    return Camera(to_world=m, width=int(width), height=int(height), film_size=size,
                  film_shift=shift, kind=kind, clip_start=near, clip_end=far, name=name)

"""Small mesh builders for tests, benchmarks and array-only scenes (no Blender needed).

Every builder returns a ``Part``: world-space triangle corners (T, 3, 3) and per-corner
normals (T, 3, 3), float64, with counter-clockwise winding seen from the front (the side
the normals point to). ``assemble`` turns parts with material indices into a ``Mesh``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .contract import CAMERA_PERSPECTIVE, Camera, Mesh


class Part(NamedTuple):
    corners: np.ndarray  # (T, 3, 3)
    normals: np.ndarray  # (T, 3, 3)


def _flat(corners: np.ndarray) -> Part:
    c = np.asarray(corners, np.float64).reshape(-1, 3, 3)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0.0)
    return Part(c, np.repeat(n[:, None, :], 3, axis=1))


def quad(center, u_half, v_half) -> Part:
    """Parallelogram center +- u_half +- v_half (3,) each; front normal = u x v."""
    c, u, v = (np.asarray(a, np.float64) for a in (center, u_half, v_half))
    p00, p10, p11, p01 = c - u - v, c + u - v, c + u + v, c - u + v
    return _flat(np.array([[p00, p10, p11], [p00, p11, p01]]))


def disk(center, normal, radius: float, segments: int = 32) -> Part:
    """Flat disk facing ``normal`` as a triangle fan."""
    c = np.asarray(center, np.float64)
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    phi = np.linspace(0, 2 * np.pi, segments + 1)
    ring = c + radius * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    tris = np.stack([np.broadcast_to(c, (segments, 3)), ring[:-1], ring[1:]], axis=1)
    return _flat(tris)


def box(lo, hi, inward: bool = False) -> Part:
    """Axis-aligned box; normals outward, or inward (a room seen from inside)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = (lo + hi) / 2
    h = (hi - lo) / 2
    ex, ey, ez = np.diag(h)
    faces = [quad(c + ex, ey, ez), quad(c - ex, ez, ey), quad(c + ey, ez, ex),
             quad(c - ey, ex, ez), quad(c + ez, ex, ey), quad(c - ez, ey, ex)]
    corners = np.concatenate([f.corners for f in faces])
    if inward:
        corners = corners[:, ::-1]
    return _flat(corners)


def prism(center, side: float, length: float, apex_angle: float = np.pi / 3) -> Part:
    """A closed triangular prism, normals outward: its cross-section in the x-z plane is an
    isosceles triangle with the apex (angle ``apex_angle`` rad) at the top and two faces
    of length ``side`` m meeting there; it extends ``length`` m along y, ``center`` (3,)
    the middle of its base edge's centre line. The refracting faces are the two that
    meet at the apex (a 60-degree apex: the equilateral dispersing prism)."""
    c = np.asarray(center, np.float64)
    h = side * np.cos(apex_angle / 2)
    b = side * np.sin(apex_angle / 2)
    tri = np.array([[-b, 0.0, 0.0], [b, 0.0, 0.0], [0.0, 0.0, h]])  # x-z cross-section
    y0, y1 = np.array([0.0, -length / 2, 0.0]), np.array([0.0, length / 2, 0.0])
    f = [c + tri[i] + y0 for i in range(3)]   # the -y cap's corners
    k = [c + tri[i] + y1 for i in range(3)]   # the +y cap's
    corners = [[f[0], f[1], f[2]], [k[0], k[2], k[1]]]
    for i, j in ((0, 1), (1, 2), (2, 0)):  # sides, counter-clockwise from outside
        corners += [[f[i], k[j], f[j]], [f[i], k[i], k[j]]]
    return _flat(np.array(corners))


def uv_sphere(center, radius: float, rings: int = 16, segments: int = 32,
              smooth: bool = True) -> Part:
    """Sphere of rings x segments quads (2 triangles each), smooth per-corner normals."""
    c = np.asarray(center, np.float64)
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments + 1)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    a, b = dirs[:-1, :-1], dirs[:-1, 1:]
    cc, d = dirs[1:, 1:], dirs[1:, :-1]
    # Quad (a, d, cc, b) is counter-clockwise seen from outside.
    t1 = np.stack([a, d, cc], axis=2).reshape(-1, 3, 3)
    t2 = np.stack([a, cc, b], axis=2).reshape(-1, 3, 3)
    nd = np.concatenate([t1, t2])
    corners = c + radius * nd
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    keep = area > 1e-12 * radius * radius  # drop the pole's zero-area triangles
    if not smooth:
        return _flat(corners[keep])
    return Part(corners[keep], nd[keep])


def transform(part: Part, scale: float = 1.0, offset=(0.0, 0.0, 0.0)) -> Part:
    return Part(part.corners * scale + np.asarray(offset, np.float64), part.normals)


def assemble(parts: list[tuple[Part, int]], names: tuple = ()) -> Mesh:
    """A Mesh from (part, material index) pairs; every triangle keeps its own corners."""
    if not parts:
        return Mesh.empty()
    corners = np.concatenate([p.corners for p, _ in parts]).astype(np.float32)
    normals = np.concatenate([p.normals for p, _ in parts]).astype(np.float32)
    mat = np.concatenate([np.full(p.corners.shape[0], m, np.int32) for p, m in parts])
    obj = np.concatenate([np.full(p.corners.shape[0], i, np.int32) for i, (p, _) in enumerate(parts)])
    t = corners.shape[0]
    return Mesh(vertices=corners.reshape(-1, 3), triangles=np.arange(3 * t, dtype=np.int32).reshape(t, 3),
                normals=normals, uvs=np.zeros((t, 3, 2), np.float32), material_index=mat,
                object_index=obj, object_names=tuple(names) or tuple(f"Object.{i}" for i in range(len(parts))))


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4, 4) camera/light-to-world matrix at ``eye`` looking along -Z towards ``target``."""
    eye, target, up = (np.asarray(a, np.float64) for a in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-12:
        right = np.cross(np.array([0.0, 1.0, 0.0]), back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
    return m


def pinhole(eye, target, width: int, height: int, fov_x: float, up=(0.0, 0.0, 1.0),
            **kwargs) -> Camera:
    """Perspective camera with horizontal field of view fov_x (radians), square pixels."""
    fw = 2.0 * np.tan(fov_x / 2.0)
    return Camera(to_world=look_at(eye, target, up), width=width, height=height,
                  film_size=np.array([fw, fw * height / width]), kind=CAMERA_PERSPECTIVE, **kwargs)

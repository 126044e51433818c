"""Ray/triangle queries: Embree (embreex) and a brute-force numpy twin with the same API.

This is the only module that imports embreex. It owns what Embree is picky about:
float32 C-contiguous inputs, empty batches, empty scenes (no triangles: everything
misses, no Embree scene is built) and splitting large batches over a small thread pool
(``EmbreeScene.run`` releases the GIL, so two threads on two halves run in parallel).

embreex's ``run`` has no ``tnear``: callers offset ray origins off the surface instead
(``core.scene.geometry.offset_points``), and pass ``tfar`` to bound shadow rays.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba
import numpy as np

# Below this many rays a batch is traced on the calling thread: splitting costs more
# than it saves.
_MIN_RAYS_PER_THREAD = 4096
# embreex reports tfar = 1e37 for rays that miss.
_MISS_T = np.float32(np.inf)


class Hits(NamedTuple):
    """Nearest hits of a batch of N rays.

    prim: (N,) int32 triangle index, -1 where the ray missed.
    t: (N,) float32 distance along the (unit) direction, metres; inf on a miss.
    u, v: (N,) float32 barycentrics: the hit is (1 - u - v) * v0 + u * v1 + v * v2.
    """

    prim: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray


def _as_rays(origins, directions, tfar):
    o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float32).reshape(-1, 3)
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} must have the same shape")
    n = o.shape[0]
    # Always a fresh array: Embree writes the hit distances into it.
    if tfar is None:
        tf = np.full(n, np.finfo(np.float32).max, np.float32)
    else:
        # Embree wants a finite far distance; inf means "unbounded".
        tf = np.minimum(np.broadcast_to(np.asarray(tfar, np.float32), (n,)), np.finfo(np.float32).max)
    return o, d, tf


def _empty_hits(n: int) -> Hits:
    return Hits(np.full(n, -1, np.int32), np.full(n, _MISS_T, np.float32),
                np.zeros(n, np.float32), np.zeros(n, np.float32))


def _triangle_vertices(mesh_or_vertices) -> np.ndarray:
    if hasattr(mesh_or_vertices, "triangle_vertices"):
        tv = mesh_or_vertices.triangle_vertices()
    else:
        tv = mesh_or_vertices
    tv = np.ascontiguousarray(tv, np.float32)
    if tv.ndim != 3 or tv.shape[1:] != (3, 3):
        raise ValueError(f"triangle vertices must have shape (T, 3, 3), got {tv.shape}")
    return tv


def default_threads(threads: int = 0) -> int:
    """Worker count: ``threads`` if > 0, else the machine's cores."""
    return int(threads) if threads and threads > 0 else (os.cpu_count() or 1)


def use_threads(threads: int = 0) -> int:
    """Set the worker count of a render (``default_threads``) for numba's parallel kernels
    too, within numba's own limit; returns it (the Embree thread pool's size)."""
    n = default_threads(threads)
    numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    return n


class Accelerator:
    """Embree BVH over world-space triangles, built once per render.

    mesh_or_triangle_vertices: a ``scene.Mesh`` or (T, 3, 3) float32 triangle corners.
    threads: worker threads for big batches (0 = all cores).
    """

    def __init__(self, mesh_or_triangle_vertices, threads: int = 0):
        tv = _triangle_vertices(mesh_or_triangle_vertices)
        self.triangle_count = int(tv.shape[0])
        self.threads = default_threads(threads)
        self._scene = None
        if self.triangle_count:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            self._scene = rtcore_scene.EmbreeScene()
            TriangleMesh(self._scene, tv)
        self._pool = ThreadPoolExecutor(self.threads - 1) if self.threads > 1 else None

    def close(self) -> None:
        """Release the thread pool (the Embree scene goes with the object)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _run(self, o, d, tf, query, output):
        """Split [0, N) into one contiguous chunk per thread and trace them in parallel;
        the calling thread traces the first chunk itself."""
        n = o.shape[0]
        chunks = min(self.threads, max(1, n // _MIN_RAYS_PER_THREAD))
        if chunks <= 1 or self._pool is None:
            return [self._scene.run(o, d, dists=tf, query=query, output=output)]
        edges = np.linspace(0, n, chunks + 1).astype(np.int64)
        parts = [(o[a:b], d[a:b], tf[a:b]) for a, b in zip(edges[:-1], edges[1:])]
        futures = [self._pool.submit(self._scene.run, po, pd, dists=pt, query=query, output=output)
                   for po, pd, pt in parts[1:]]
        po, pd, pt = parts[0]
        first = self._scene.run(po, pd, dists=pt, query=query, output=output)
        return [first] + [f.result() for f in futures]

    def intersect(self, origins, directions, tfar=None) -> Hits:
        """Nearest hit of each ray within (0, tfar].

        origins, directions: (N, 3), converted to float32; directions should be unit
        length so that ``t`` is a distance. tfar: None, a scalar or (N,), metres.
        """
        o, d, tf = _as_rays(origins, directions, tfar)
        n = o.shape[0]
        if n == 0 or self._scene is None:
            return _empty_hits(n)
        parts = self._run(o, d, tf, "INTERSECT", 1)
        prim = np.concatenate([p["primID"] for p in parts]).astype(np.int32, copy=False)
        t = np.concatenate([p["tfar"] for p in parts]).astype(np.float32, copy=False)
        u = np.concatenate([p["u"] for p in parts]).astype(np.float32, copy=False)
        v = np.concatenate([p["v"] for p in parts]).astype(np.float32, copy=False)
        miss = prim < 0
        t[miss] = _MISS_T
        u[miss] = 0.0
        v[miss] = 0.0
        return Hits(prim, t, u, v)

    def occluded(self, origins, directions, tfar) -> np.ndarray:
        """(N,) bool: does any triangle cross the ray within (0, tfar]?"""
        o, d, tf = _as_rays(origins, directions, tfar)
        n = o.shape[0]
        if n == 0 or self._scene is None:
            return np.zeros(n, bool)
        parts = self._run(o, d, tf, "OCCLUDED", None)
        # OCCLUDED answers a geometry id (>= 0) for blocked rays and -1 otherwise.
        return np.concatenate([np.asarray(p) for p in parts]) != -1


class BruteForceAccelerator:
    """Möller–Trumbore against every triangle, in numpy: the oracle for small scenes.

    Same constructor and methods as ``Accelerator``; O(N T) memory, keep N * T small.
    """

    def __init__(self, mesh_or_triangle_vertices, threads: int = 0):
        tv = _triangle_vertices(mesh_or_triangle_vertices).astype(np.float64)
        self.triangle_count = int(tv.shape[0])
        self.threads = 1
        self._v0 = tv[:, 0]
        self._e1 = tv[:, 1] - tv[:, 0]
        self._e2 = tv[:, 2] - tv[:, 0]

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def _all_hits(self, o, d):
        """(N, T) t, u, v with t = inf where the ray misses the triangle."""
        o = o.astype(np.float64)[:, None, :]
        d = d.astype(np.float64)[:, None, :]
        e1, e2 = self._e1[None], self._e2[None]
        p = np.cross(d, e2)
        det = np.sum(e1 * p, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o - self._v0[None]
            u = np.sum(s * p, axis=-1) * inv
            q = np.cross(s, e1)
            v = np.sum(d * q, axis=-1) * inv
            t = np.sum(e2 * q, axis=-1) * inv
        ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        return np.where(ok, t, np.inf), u, v

    def intersect(self, origins, directions, tfar=None) -> Hits:
        o, d, tf = _as_rays(origins, directions, tfar)
        n = o.shape[0]
        if n == 0 or self.triangle_count == 0:
            return _empty_hits(n)
        t, u, v = self._all_hits(o, d)
        t = np.where(t <= tf[:, None], t, np.inf)
        best = np.argmin(t, axis=1)
        rows = np.arange(n)
        tb = t[rows, best]
        hit = np.isfinite(tb)
        return Hits(np.where(hit, best, -1).astype(np.int32), tb.astype(np.float32),
                    np.where(hit, u[rows, best], 0).astype(np.float32),
                    np.where(hit, v[rows, best], 0).astype(np.float32))

    def occluded(self, origins, directions, tfar) -> np.ndarray:
        o, d, tf = _as_rays(origins, directions, tfar)
        if o.shape[0] == 0 or self.triangle_count == 0:
            return np.zeros(o.shape[0], bool)
        t, _, _ = self._all_hits(o, d)
        return np.any(t <= tf[:, None], axis=1)

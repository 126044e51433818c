"""What a shader program reads at each hit point: ``ShadingInputs``, plain arrays."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _vec(a, n, name):
    a = np.ascontiguousarray(a, np.float32)
    if a.shape != (n, 3):
        raise ValueError(f"ShadingInputs.{name} must be ({n}, 3) float32, got {a.shape}")
    return a


@dataclass(frozen=True)
class ShadingInputs:
    """Per-point inputs of N hit points (world space, metres; directions unit length).

    position, normal (shading normal), true_normal (geometric, both facing the side hit),
    incoming (unit vector from the point towards the viewer, Cycles' I), generated
    (texture-space coordinates in [0, 1] over the object's bounds), object_coords
    (object-space position), object_normal (object-space shading normal),
    object_location, object_color: (N, 3) float32. backfacing, object_random,
    object_index: (N,) float32 (0/1, [0, 1], the pass index). uv: (U, N, 2) float32, one slice per UV map. attributes: (A, N, 4) float32
    RGBA, one slice per exported attribute. object_alpha (the object colour's alpha),
    material_index (the material's pass index): (N,) float32.
    """
    position: np.ndarray
    normal: np.ndarray
    true_normal: np.ndarray | None = None
    incoming: np.ndarray | None = None
    backfacing: np.ndarray | None = None
    generated: np.ndarray | None = None
    object_coords: np.ndarray | None = None
    object_normal: np.ndarray | None = None
    object_location: np.ndarray | None = None
    object_random: np.ndarray | None = None
    object_color: np.ndarray | None = None
    object_index: np.ndarray | None = None
    uv: np.ndarray | None = None
    attributes: np.ndarray | None = field(default=None)
    object_alpha: np.ndarray | None = None
    material_index: np.ndarray | None = None

    @classmethod
    def build(cls, position, normal, **optional):
        """Validated inputs; omitted fields default to: true_normal = normal, incoming =
        normal, backfacing 0, generated = object_coords = position, object_normal =
        normal, object location, colour, random and index 0, object alpha 1, material
        index 0, no UV map or attribute (a program reading one then reads zeros)."""
        p = np.ascontiguousarray(position, np.float32)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"ShadingInputs.position must be (N, 3) float32, got {p.shape}")
        n = p.shape[0]
        nrm = _vec(normal, n, "normal")
        known = {"true_normal", "incoming", "backfacing", "generated", "object_coords",
                 "object_normal", "object_location", "object_random", "object_color",
                 "object_index", "uv", "attributes", "object_alpha", "material_index"}
        unknown = set(optional) - known
        if unknown:
            raise ValueError(f"ShadingInputs: unknown fields {sorted(unknown)}")
        get = optional.get
        vec = {k: _vec(get(k, default), n, k) for k, default in (
            ("true_normal", nrm), ("incoming", nrm), ("generated", p), ("object_coords", p),
            ("object_normal", nrm), ("object_location", np.zeros((n, 3))),
            ("object_color", np.zeros((n, 3))))}
        scal = {}
        for k in ("backfacing", "object_random", "object_index", "object_alpha",
                  "material_index"):
            a = np.ascontiguousarray(get(k, np.ones(n) if k == "object_alpha" else
                                         np.zeros(n)), np.float32).reshape(-1)
            if a.shape != (n,):
                raise ValueError(f"ShadingInputs.{k} must be ({n},) float32, got {a.shape}")
            scal[k] = a
        uv = np.ascontiguousarray(get("uv", np.zeros((0, n, 2))), np.float32)
        if uv.ndim != 3 or uv.shape[1:] != (n, 2):
            raise ValueError(f"ShadingInputs.uv must be (U, {n}, 2) float32, got {uv.shape}")
        attr = np.ascontiguousarray(get("attributes", np.zeros((0, n, 4))), np.float32)
        if attr.ndim != 3 or attr.shape[1:] != (n, 4):
            raise ValueError(f"ShadingInputs.attributes must be (A, {n}, 4) float32, "
                             f"got {attr.shape}")
        for k, a in {**vec, **scal, "uv": uv, "attributes": attr, "position": p}.items():
            if not np.all(np.isfinite(a)):
                raise ValueError(f"ShadingInputs.{k} has a non-finite value")
        return cls(p, nrm, uv=uv, attributes=attr, **vec, **scal)

    @property
    def count(self) -> int:
        return self.position.shape[0]

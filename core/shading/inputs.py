"""What a shader program reads at each hit point: ``ShadingInputs``, plain arrays."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import light_path


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
    RGBA, one slice per exported attribute. tangents: (G, N, 4) float32, one slice per
    tangent map (``Mesh.tangent_maps``): the interpolated MikkTSpace tangent (world
    space, not normalised) and bitangent sign (0 where there is no tangent).
    normal_to_world: (N, 3, 3) float32, the object's normal transform inv(A)^T (A the
    linear part of its world matrix; identity by default).
    bump_points: 0, or N when the arrays hold 3 N rows: the N points, then the inputs at
    P + dPdx, then at P + dPdy (the Bump node's footprint, ``HitShader.inputs``); a
    program's results are for the first N. object_alpha (the object colour's alpha),
    material_index (the material's pass index): (N,) float32. light_path: (N,
    light_path.COUNT) float32, the Light Path node's outputs for the ray that reached
    each point (core.shading.light_path: the caller's context).
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
    tangents: np.ndarray | None = None
    normal_to_world: np.ndarray | None = None
    bump_points: int = 0
    object_alpha: np.ndarray | None = None
    material_index: np.ndarray | None = None
    light_path: np.ndarray | None = None

    @classmethod
    def build(cls, position, normal, **optional):
        """Validated inputs; omitted fields default to: true_normal = normal, incoming =
        normal, backfacing 0, generated = object_coords = position, object_normal =
        normal, object location, colour, random and index 0, object alpha 1, material
        index 0, no UV map, attribute or tangent map (a program reading one then reads
        zeros), normal_to_world the identity, light_path zeros (no flag, length and
        depths 0); a (COUNT,) light_path is the same for every point."""
        p = np.ascontiguousarray(position, np.float32)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"ShadingInputs.position must be (N, 3) float32, got {p.shape}")
        n = p.shape[0]
        nrm = _vec(normal, n, "normal")
        known = {"true_normal", "incoming", "backfacing", "generated", "object_coords",
                 "object_normal", "object_location", "object_random", "object_color",
                 "object_index", "uv", "attributes", "tangents", "normal_to_world",
                 "bump_points", "object_alpha", "material_index", "light_path"}
        unknown = set(optional) - known
        if unknown:
            raise ValueError(f"ShadingInputs: unknown fields {sorted(unknown)}")
        get = optional.get
        # the defaults are made float32 (no float64 array to convert: a hit batch
        # builds these for every source its programs do not read)
        vec = {k: _vec(get(k) if k in optional else
                       (np.zeros((n, 3), np.float32) if default is None else default), n, k)
               for k, default in (
                   ("true_normal", nrm), ("incoming", nrm), ("generated", p),
                   ("object_coords", p), ("object_normal", nrm), ("object_location", None),
                   ("object_color", None))}
        scal = {}
        for k in ("backfacing", "object_random", "object_index", "object_alpha",
                  "material_index"):
            a = np.ascontiguousarray(get(k) if k in optional else (
                np.ones(n, np.float32) if k == "object_alpha" else np.zeros(n, np.float32)),
                np.float32).reshape(-1)
            if a.shape != (n,):
                raise ValueError(f"ShadingInputs.{k} must be ({n},) float32, got {a.shape}")
            scal[k] = a
        uv = np.ascontiguousarray(get("uv", np.zeros((0, n, 2), np.float32)), np.float32)
        if uv.ndim != 3 or uv.shape[1:] != (n, 2):
            raise ValueError(f"ShadingInputs.uv must be (U, {n}, 2) float32, got {uv.shape}")
        attr = np.ascontiguousarray(get("attributes", np.zeros((0, n, 4), np.float32)),
                                    np.float32)
        if attr.ndim != 3 or attr.shape[1:] != (n, 4):
            raise ValueError(f"ShadingInputs.attributes must be (A, {n}, 4) float32, "
                             f"got {attr.shape}")
        tan = np.ascontiguousarray(get("tangents", np.zeros((0, n, 4), np.float32)),
                                   np.float32)
        if tan.ndim != 3 or tan.shape[1:] != (n, 4):
            raise ValueError(f"ShadingInputs.tangents must be (G, {n}, 4) float32, "
                             f"got {tan.shape}")
        n2w = get("normal_to_world")
        n2w = np.ascontiguousarray(np.broadcast_to(np.eye(3, dtype=np.float32), (n, 3, 3))
                                   if n2w is None else n2w, np.float32)
        if n2w.shape != (n, 3, 3):
            raise ValueError(f"ShadingInputs.normal_to_world must be ({n}, 3, 3) float32, "
                             f"got {n2w.shape}")
        lp = get("light_path")
        lp = np.ascontiguousarray(np.zeros((n, light_path.COUNT), np.float32) if lp is None
                                  else np.broadcast_to(lp, (n, light_path.COUNT)), np.float32)
        for k, a in {**vec, **scal, "uv": uv, "attributes": attr, "position": p,
                     "normal": nrm, "tangents": tan, "normal_to_world": n2w,
                     "light_path": lp}.items():
            # the defaults are finite (copies of position and normal, or constants)
            if (k in optional or k in ("position", "normal")) and not np.all(np.isfinite(a)):
                raise ValueError(f"ShadingInputs.{k} has a non-finite value")
        bump = int(get("bump_points", 0))
        if bump and n != 3 * bump:
            raise ValueError(f"ShadingInputs.bump_points {bump}: the arrays must have "
                             f"{3 * bump} rows, got {n}")
        return cls(p, nrm, uv=uv, attributes=attr, tangents=tan, normal_to_world=n2w,
                   bump_points=bump, light_path=lp, **vec, **scal)

    @property
    def count(self) -> int:
        """The points a program is evaluated at (without the bump offset rows)."""
        return self.bump_points or self.position.shape[0]

"""The participating media of a scene, in the contract's style: plain arrays, one row per
medium (docs/volumes.md).

Units: metres; coefficients in 1/m; emission as radiance added per metre of path,
W/(m^2 sr) per m = W/(m^3 sr), as Cycles' Emission of a volume shader.

A medium fills the inside of one closed mesh object (``bounds``: its index into
``Mesh.object_names``) or, with ``bounds == WORLD``, all space (the World's volume; at most
one). Nesting follows Cycles, which has no volume priority (src/kernel/integrator/
volume_stack.h and volume_shader.h, read at blender/cycles 97dbe6f): a path keeps a stack
of the volumes it is inside, the World's at the bottom even inside closed meshes, and a
point's medium is the sum of every medium of the stack: coefficients and emission add, the
phase function is the sigma_s-weighted mix of their Henyey-Greenstein lobes.

Heterogeneous density: a shader program (``programs``, one output, target
``core.shading.program.TARGET_DENSITY``) gives rho(x) >= 0 at every point inside the
medium and scales its sigma_a and sigma_s (not its emission: Cycles' Principled Volume
adds its emission independently of the density); ``density_texture == -1`` means
homogeneous (rho = 1). **A varying colour** (a Principled Volume's or Volume Scatter's Color /
Absorption Color fed by nodes): the program has DENSITY_SLOTS outputs, rho, Color C (3),
Absorption Color A (3), and the row's sigma_a, sigma_s are weights: at a point
sigma_s = sigma_s(row) C rho, sigma_a = sigma_a(row) max(1 - C, 0) max(1 - sqrt(A), 0) rho
(Cycles' svm_node_principled_volume; ``core.media.density.principled_volume_coefficients``),
per channel: a Principled Volume under Mix factor w has w in both, a Volume Scatter w and 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .checks import SceneError, check_array

WORLD = -1
"""``Media.bounds`` of the World's volume: the medium of every point inside no mesh medium."""

DENSITY_SLOTS = 7
"""Outputs of a density program with a varying colour: the density, Color (3), Absorption
Color (3) (``core.shading.program.TARGET_DENSITY`` slots 0-6, in order; module doc)."""

MAX_ANISOTROPY = 0.999
"""The phase function clamps |g| to this (a delta peak beyond; Cycles' volume_henyey_greenstein
setup clamps to 1 - 1e-3 too). The contract accepts Blender's whole range [-1, 1]."""


@dataclass(frozen=True)
class Media:
    """M participating media.

    sigma_a: (M, 3) float32, absorption coefficient per RGB channel, 1/m, >= 0.
    sigma_s: (M, 3) float32, scattering coefficient per RGB channel, 1/m, >= 0.
    anisotropy: (M,) float32, Henyey-Greenstein g in [-1, 1] (0 isotropic, > 0 forward
        scattering; the kernels clamp |g| to MAX_ANISOTROPY as Cycles).
    emission: (M, 3) float32, W/(m^3 sr), >= 0.
    bounds: (M,) int32, object index of the closed mesh that bounds the medium, or WORLD.
    density_texture: (M,) int32, -1 (homogeneous) or the row of ``programs`` whose output
        is the medium's density rho(x) (dimensionless; the coefficients above are at rho 1).
    programs: tuple of ``core.shading.program.ShaderProgram``, the density programs; they
        read the Object and Generated coordinates of the medium's object (``bounds``:
        ``Mesh.object_to_world``, ``Mesh.object_texspace``; the World's: the position)
        and world positions. A World medium's varying part fills a box around the scene
        (core/media/regions.py).
    names: tuple of str, one per medium (the material or World name, for messages).
    boundary: (B, 3, 3) float32, world-space corners (metres) of the triangles that bound
        the mesh media, wound so that the geometric normal (v1 - v0) x (v2 - v0) points
        out of the medium (Blender's face winding of a closed mesh); every medium with
        ``bounds != WORLD`` needs at least one. The triangles bound the medium whether or
        not they are also surfaces of ``Mesh`` (glass: yes; a volume-only material: no,
        its faces are null interfaces rays pass straight through).
    boundary_medium: (B,) int32, the medium row each boundary triangle bounds.
    """

    sigma_a: np.ndarray
    sigma_s: np.ndarray
    anisotropy: np.ndarray
    emission: np.ndarray
    bounds: np.ndarray
    density_texture: np.ndarray
    names: tuple = ()
    boundary: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3), np.float32))
    boundary_medium: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    programs: tuple = ()

    @property
    def count(self) -> int:
        return int(self.sigma_a.shape[0])

    @property
    def sigma_t(self) -> np.ndarray:
        """(M, 3) float32 extinction coefficient sigma_a + sigma_s, 1/m."""
        return self.sigma_a + self.sigma_s

    @property
    def world(self) -> int:
        """Row of the World's medium, or -1 when the World has no volume."""
        rows = np.flatnonzero(self.bounds == WORLD)
        return int(rows[0]) if rows.size else -1

    @staticmethod
    def empty() -> "Media":
        return Media.from_list([])

    @staticmethod
    def from_list(rows: list[dict], programs: tuple = ()) -> "Media":
        """Media from dicts with keys sigma_a, sigma_s (RGB, 1/m), anisotropy, emission,
        bounds (object index or WORLD), density_texture, name, boundary ((T, 3, 3)
        metres: the mesh medium's boundary triangles); absent keys take the defaults (no
        absorption, no scattering, isotropic, no emission, World, homogeneous, no
        boundary). ``programs`` is the density programs' tuple."""
        def col(key, width, default, dtype=np.float32):
            shape = (len(rows), width) if width else (len(rows),)
            return np.array([r.get(key, default) for r in rows], dtype).reshape(shape)

        return Media(sigma_a=col("sigma_a", 3, (0.0, 0.0, 0.0)),
                     sigma_s=col("sigma_s", 3, (0.0, 0.0, 0.0)),
                     anisotropy=col("anisotropy", 0, 0.0),
                     emission=col("emission", 3, (0.0, 0.0, 0.0)),
                     bounds=col("bounds", 0, WORLD, np.int32),
                     density_texture=col("density_texture", 0, -1, np.int32),
                     names=tuple(r.get("name", f"medium {i}") for i, r in enumerate(rows)),
                     boundary=np.concatenate(
                         [np.asarray(r.get("boundary", np.zeros((0, 3, 3))), np.float32)
                          .reshape(-1, 3, 3) for r in rows] or [np.zeros((0, 3, 3), np.float32)]),
                     boundary_medium=np.concatenate(
                         [np.full(np.asarray(r.get("boundary", np.zeros((0, 3, 3)))).reshape(-1, 9)
                                  .shape[0], i, np.int32) for i, r in enumerate(rows)]
                         or [np.zeros(0, np.int32)]),
                     programs=tuple(programs))

    def validate(self, object_count: int) -> "Media":
        """Check shapes, dtypes and ranges; raise SceneError naming the field and medium.

        object_count: how many objects ``Mesh.object_names`` holds (``bounds`` indexes it).
        """
        m = self.count
        labels = self.names or None
        for name in ("sigma_a", "sigma_s", "emission"):
            check_array(f"media.{name}", getattr(self, name), (m, 3), dtype=np.float32,
                        nonnegative=True, labels=labels)
        check_array("media.anisotropy", self.anisotropy, (m,), dtype=np.float32,
                    labels=labels)
        for name in ("bounds", "density_texture"):
            check_array(f"media.{name}", getattr(self, name), (m,), dtype=np.int32,
                        labels=labels)
        if self.names and len(self.names) != m:
            raise SceneError(f"media.names has {len(self.names)} names for {m} media")
        bad = np.flatnonzero(np.abs(self.anisotropy) > 1.0)
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"media.anisotropy of '{self._name(i)}' must lie in [-1, 1], "
                             f"got {self.anisotropy[i]}")
        bad = np.flatnonzero((self.bounds < WORLD) | (self.bounds >= object_count))
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"media.bounds of '{self._name(i)}' must be an object index in "
                             f"[0, {object_count}) or WORLD (-1), got {self.bounds[i]}")
        worlds = np.flatnonzero(self.bounds == WORLD)
        if worlds.size > 1:
            raise SceneError(f"media.bounds: only one World medium is allowed, got "
                             f"{', '.join(repr(self._name(int(i))) for i in worlds)}")
        count = len(self.programs)
        bad = np.flatnonzero((self.density_texture < -1) | (self.density_texture >= count))
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"media.density_texture of '{self._name(i)}' must be -1 or a "
                             f"density program index in [0, {count}), got "
                             f"{self.density_texture[i]}")
        for k, prog in enumerate(self.programs):
            try:
                prog.validate()
            except ValueError as exc:
                raise SceneError(f"media.programs[{k}]: {exc}") from None
            n_out = prog.outputs.shape[0]
            if n_out not in (1, DENSITY_SLOTS) or np.any(prog.outputs[:, 1] != prog.outputs[0, 1]) \
                    or np.any(prog.outputs[:, 3] != np.arange(n_out)):
                raise SceneError(f"media.programs[{k}] ({prog.name!r}) must have one output "
                                 f"(the density) or {DENSITY_SLOTS} (the density, Color, "
                                 f"Absorption Color), TARGET_DENSITY slots in order, got "
                                 f"{prog.outputs.tolist()}")
        check_array("media.boundary", self.boundary, (None, 3, 3), dtype=np.float32)
        check_array("media.boundary_medium", self.boundary_medium, (self.boundary.shape[0],),
                    dtype=np.int32)
        bad = np.flatnonzero((self.boundary_medium < 0) | (self.boundary_medium >= m))
        if bad.size:
            raise SceneError(f"media.boundary_medium of triangle {int(bad[0])} must be a medium "
                             f"row in [0, {m}), got {self.boundary_medium[bad[0]]}")
        on_world = self.bounds[self.boundary_medium] == WORLD
        if np.any(on_world):
            i = int(self.boundary_medium[np.flatnonzero(on_world)[0]])
            raise SceneError(f"media.boundary: the World's medium '{self._name(i)}' has no "
                             f"boundary, got triangles for it")
        counts = np.bincount(self.boundary_medium, minlength=m)
        bad = np.flatnonzero((self.bounds != WORLD) & (counts == 0))
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"media.boundary: the medium '{self._name(i)}' inside object "
                             f"{self.bounds[i]} has no boundary triangles")
        return self

    def _name(self, i: int) -> str:
        return self.names[i] if i < len(self.names) else f"medium {i}"

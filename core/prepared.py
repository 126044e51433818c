"""The prepared scene: every per-render table built once from a ``core.Scene`` and read by
every step of the render (photon emission and tracing, the camera pass, final gathering,
SPPM's visible points, the importance pre-pass), with the render's Embree accelerator.

``prepare(scene, threads)`` validates nothing (``Scene.validate`` does); it sets the
render's thread count (numba and Embree) and builds:

- triangles: ``tri_vertices`` (T, 3, 3) float32 metres, ``tri_normals`` (T, 3, 3) float32
  corner normals, ``tri_material`` (T,) int32;
- materials: ``materials`` (``core.materials.bsdf.material_table``: float64 lobe arrays by
  name), ``closures`` (``closure.table``: the ClosureTable every BSDF evaluation reads),
  ``texels`` (a SurfaceTextures whose ``albedo`` is the texel colour multiplying the
  closures' COLOR, 1 where untextured), and per material (M,) bool ``has_diffuse``, ``nondelta`` (a lobe that light
  sampling can see: diffuse or rough glossy), ``has_delta`` (a mirror or glass lobe),
  ``sampled_only`` (a rough glossy lobe and no diffuse one: SPPM's camera paths go on
  through it by BSDF sampling), ``emissive_index`` (T,) int32 each triangle's row in ``emissive`` (-1: not emissive),
  ``specular_material`` (any glossy, mirror or glass lobe);
- lights: ``light_set`` (core.lights.LightSet), ``light_shows`` (L,) bool (the light has a
  surface a ray can see), ``emissive`` (the emissive triangles), ``world`` (3,) float64
  background radiance W/(m^2 sr);
- textures: ``surfaces`` (core.materials.textures.SurfaceTextures: textured albedo, cut-outs);
- sizes: ``extent`` (metres, the ray-offset scale), ``centre`` / ``radius`` (the sphere
  around the geometry, 1 % wider: where photons from the sun and the world start),
  ``objects`` (every object's bounding sphere), ``specular_objects`` (O,) bool,
  ``diffuse_area`` (m^2 of triangles with a diffuse lobe);
- ``accel``: the Embree accelerator over the triangles. ``close()`` releases it (the
  prepared scene is a context manager);
- ``medium``: the scene's media as the renderer integrates them (core/media/regions.py:
  the World's and the mesh media, with their boundary's own Embree scene), or None without
  a medium that has an effect;
- ``hit_shader``: the ``HitShader`` running the materials' shader programs at hits
  (``closures_at``: a per-batch ClosureTable and each hit's row in it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lights.light_set import EmissiveTriangles, LightSet
from .materials import bsdf, closure
from .materials.textures import SurfaceTextures
from .media import regions
from .media.density import DensityFields
from .scene import geometry
from .shading import interpreter
from .shading import program as pg
from .shading.inputs import ShadingInputs
from .scene.accel import Accelerator, use_threads
from .scene.bounds import Targets, bounding_sphere, object_spheres
from .scene.checks import SceneError
from .scene.contract import Scene


def density_fields(scene: Scene, shader: "HitShader") -> DensityFields | None:
    """The heterogeneous media's densities (core/media/density.py): each medium's density
    program bound to the interpreter with the Position (world), Object and Generated
    coordinates of the medium's object (``shader``'s transforms, as at a surface hit of
    it), its majorant measured over its boundary's box; None when every medium is
    homogeneous."""
    media = scene.media
    rows = np.flatnonzero(media.density_texture >= 0)
    if rows.size == 0:
        return None
    evaluators, boxes = {}, {}
    for r in rows.tolist():
        prog = media.programs[int(media.density_texture[r])]
        if prog.outputs[0, 1] != pg.TARGET_DENSITY:
            raise SceneError(f"medium '{media.names[r]}': its density program's output has "
                             f"target {prog.outputs[0, 1]}, not TARGET_DENSITY")

        def evaluate(p, prog=prog, obj=int(media.bounds[r])):
            n = p.shape[0]
            world = p + shader.origin
            local, generated = shader.object_point(np.full(n, obj), world)
            inputs = ShadingInputs.build(world, np.zeros((n, 3), np.float32),
                                         object_coords=local, generated=generated)
            return interpreter.evaluate(prog, inputs, scene.program_images)[:, 0]
        evaluators[r] = evaluate
        tri = media.boundary[media.boundary_medium == r].reshape(-1, 3).astype(np.float64)
        boxes[r] = (tri.min(axis=0), tri.max(axis=0))
    return DensityFields(evaluators, boxes, media.names)


@dataclass
class PreparedScene:
    """The per-render tables of a scene (module doc)."""

    scene: Scene
    threads: int
    accel: Accelerator
    tri_vertices: np.ndarray
    tri_normals: np.ndarray
    tri_material: np.ndarray
    materials: dict
    closures: closure.ClosureTable
    texels: SurfaceTextures
    emissive_index: np.ndarray
    has_diffuse: np.ndarray
    nondelta: np.ndarray
    has_delta: np.ndarray
    sampled_only: np.ndarray
    specular_material: np.ndarray
    light_set: LightSet
    light_shows: np.ndarray
    emissive: EmissiveTriangles
    world: np.ndarray
    surfaces: SurfaceTextures
    extent: float
    centre: np.ndarray
    radius: float
    objects: Targets
    specular_objects: np.ndarray
    diffuse_area: float
    hit_shader: "HitShader"
    medium: regions.Medium | None = None

    def close(self) -> None:
        """Release the Embree scenes (idempotent)."""
        self.accel.close()
        if self.medium is not None:
            self.medium.close()

    def __enter__(self) -> "PreparedScene":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def used_materials(self) -> np.ndarray:
        """(M,) bool: the material is on at least one triangle."""
        used = np.zeros(self.materials["diffuse"].shape[0], bool)
        used[np.unique(self.tri_material)] = True
        return used


class HitShader:
    """The materials' shader programs at batches of hits (docs/shading.md, "At the hits").

    ``closures_at(prim, u, v, d)`` returns ``(tab, rows)``: a ClosureTable and, per hit,
    its material row in it, what every closure kernel takes as ``(tab, m)``. Rows [0, M)
    of ``tab.first`` / ``tab.count`` are the materials as prepared; each hit whose
    material has a program gets a row of its own, M + j, over closures appended after
    the material closures: copies of its material's closures (kind, weight, texture) with
    the parameters the program computed there. Without a programmed hit in the batch,
    ``tab`` is the prepared table itself and ``rows`` the materials (bit for bit what
    the kernels read without programs). Everything indexed by material (emission, lobe
    masks, the photon-store rule) keeps reading the original material: the masks are
    those of the material's constant inputs.

    The per-hit inputs (core.shading.inputs.ShadingInputs): world position (the render
    frame + ``Mesh.origin``), the shading and geometric normals facing the ray, incoming
    = -d, backfacing, the first UV map (``Mesh.uvs``), object coordinates and normal,
    Generated (``Mesh.object_texspace``) and the object's location
    (``Mesh.object_to_world``). Object random is 0 (not exported yet).
    """

    def __init__(self, scene: Scene, closures: closure.ClosureTable, tri_vertices,
                 tri_normals, tri_material, extent: float):
        mats, mesh = scene.materials, scene.mesh
        progs = mats.programs if mats.programs is not None else (None,) * mats.count
        used = np.bincount(mesh.material_index, minlength=mats.count)[:mats.count] > 0
        self.programs = progs
        self.images = scene.program_images
        self.programmed = np.array([p is not None for p in progs], bool).reshape(mats.count)
        self.active = bool(np.any(self.programmed & used))
        self.table = closures
        self.tri_vertices, self.tri_normals = tri_vertices, tri_normals
        self.tri_material, self.extent = tri_material, float(extent)
        self.tri_uv = mesh.uvs
        self.tri_attributes = mesh.attributes  # (T, 3, A, 4) or None
        self.tri_object = mesh.object_index
        n_obj = int(mesh.object_index.max()) + 1 if mesh.triangle_count else 0
        if mesh.object_to_world is not None:
            to_world = np.asarray(mesh.object_to_world, np.float64)
        else:
            to_world = np.broadcast_to(np.eye(4), (n_obj, 4, 4))
        self.to_object = np.linalg.inv(to_world) if len(to_world) else to_world
        self.location = to_world[:, :3, 3] if len(to_world) else np.zeros((0, 3))
        self.linear = to_world[:, :3, :3]
        if mesh.object_texspace is not None:
            self.texspace = np.asarray(mesh.object_texspace, np.float64)
        else:
            self.texspace = np.broadcast_to(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]),
                                            (n_obj, 2, 3))
        self.object_info = (np.zeros((n_obj, 5), np.float32) if mesh.object_info is None
                            else np.asarray(mesh.object_info, np.float32))
        self.origin = (np.zeros(3) if mesh.origin is None
                       else np.asarray(mesh.origin, np.float64))

    def inputs(self, prim, u, v, d) -> tuple[ShadingInputs, np.ndarray]:
        """The ShadingInputs of N hits (prim (N,) int32 triangles, Embree barycentrics u, v
        (N,), d (N, 3) the arriving unit directions) and their materials (N,) int32."""
        pos, ngf, nsf, mat, _, front = geometry.facing_surface_points(
            self.tri_vertices, self.tri_normals, self.tri_material, prim, u, v,
            np.ascontiguousarray(d, np.float64), self.extent)
        world = pos + self.origin
        obj = self.tri_object[prim]
        local, generated = self.object_point(obj, world)
        # Normals to object space: n_obj ~ A^T n_world for a world normal inv(A)^T n_obj.
        onrm = np.einsum("nji,nj->ni", self.linear[obj], nsf)
        onrm /= np.maximum(np.linalg.norm(onrm, axis=1), 1e-30)[:, None]
        w = (1.0 - u - v).astype(np.float64)
        uv = (w[:, None] * self.tri_uv[prim, 0] + u[:, None] * self.tri_uv[prim, 1]
              + v[:, None] * self.tri_uv[prim, 2])
        ins = ShadingInputs.build(world, nsf, true_normal=ngf, incoming=-np.asarray(d),
                                  backfacing=(~front).astype(np.float32),
                                  generated=generated, object_coords=local,
                                  object_normal=onrm, object_location=self.location[obj],
                                  object_color=self.object_info[obj, :3],
                                  object_random=self.object_info[obj, 3],
                                  object_index=self.object_info[obj, 4], uv=uv[None],
                                  attributes=self._attributes(prim, u, v, w))
        return ins, mat

    def _attributes(self, prim, u, v, w) -> np.ndarray:
        """(A, N, 4) the mesh attributes at the hits, interpolated like the UVs."""
        if self.tri_attributes is None:
            return np.zeros((0, prim.shape[0], 4), np.float32)
        c = self.tri_attributes[prim]  # (N, 3, A, 4)
        a = w[:, None, None] * c[:, 0] + u[:, None, None] * c[:, 1] + v[:, None, None] * c[:, 2]
        return np.ascontiguousarray(np.transpose(a, (1, 0, 2)), np.float32)

    def object_point(self, obj, world):
        """Object-space positions (N, 3) and Generated coordinates (N, 3) float64 of world
        points (N, 3) on objects obj (N,)."""
        to_obj = self.to_object[obj]
        local = np.einsum("nij,nj->ni", to_obj[:, :3, :3], world) + to_obj[:, :3, 3]
        loc, size = self.texspace[obj, 0], self.texspace[obj, 1]
        safe = np.where(size != 0, 2.0 * size, 1.0)
        generated = np.where(size != 0, (local - loc) / safe + 0.5, 0.5)
        return local, generated

    def tangents(self, prim, pos, tab: closure.ClosureTable, rows) -> np.ndarray:
        """(N, 3) float64 C-contiguous: the tangent each hit's BSDF frame starts from
        (``closure.frame`` makes it orthogonal to the shading normal), for N hits on
        triangles prim (N,) at render-frame positions pos (N, 3) metres whose rows (N,) of
        ``tab`` are their closures (``closures_at``).

        Where a row has an anisotropic closure (Glossy, Metallic or Principled with
        Anisotropic > 0): Cycles' default for an unlinked Tangent input, the radial tangent
        around the object's Z axis (svm_node_tangent, NODE_TANGENT_RADIAL, axis Z): from
        Generated g, t = (-(g.y - 0.5), g.x - 0.5, 0) in object space, taken to world space
        as Cycles does (``object_normal_transform``: inv(A)^T t). Elsewhere the direction
        does not change the BSDF and every hit gets ``closure.DEFAULT_TANGENT``, so
        isotropic scenes sample exactly as before. On the object's Z axis the radial
        tangent is 0 and ``closure.frame`` falls back to another axis."""
        n = prim.shape[0]
        out = closure.default_tangents(n)
        if n == 0:
            return out
        aniso = closure.anisotropic_rows(tab)
        sel = np.flatnonzero(aniso[rows])
        if sel.size == 0:
            return out
        obj = self.tri_object[prim[sel]]
        _, g = self.object_point(obj, np.asarray(pos, np.float64)[sel] + self.origin)
        t_obj = np.stack([-(g[:, 1] - 0.5), g[:, 0] - 0.5, np.zeros(sel.size)], axis=1)
        out[sel] = np.einsum("nji,nj->ni", self.to_object[obj][:, :3, :3], t_obj)
        return out

    def closures_at(self, prim, u, v, d, mat) -> tuple[closure.ClosureTable, np.ndarray]:
        """(tab, rows) for N hits (class doc): prim, u, v, d as for ``inputs``, mat (N,)
        int32 their materials. rows is ``mat`` itself when no hit has a program."""
        if not self.active or prim.shape[0] == 0:
            return self.table, mat
        hit = np.flatnonzero(self.programmed[mat])
        if hit.size == 0:
            return self.table, mat
        tab = self.table
        n_mat, n_cl = tab.first.shape[0], tab.kind.shape[0]
        ins, _ = self.inputs(prim[hit], u[hit], v[hit], np.asarray(d)[hit])
        rows = np.array(mat, np.int32, copy=True)
        kinds, weights, params, textures, firsts, counts, abbes = [], [], [], [], [], [], []
        done = 0
        next_closure = n_cl
        for m in np.unique(mat[hit]):
            sel = np.flatnonzero(mat[hit] == m)
            f, k = int(tab.first[m]), int(tab.count[m])
            out = interpreter.closure_params(self.programs[m], _subset(ins, sel),
                                             tab.params[f:f + k].astype(np.float32),
                                             self.images)
            h = sel.size
            kinds.append(np.tile(tab.kind[f:f + k], h))
            weights.append(np.tile(tab.weight[f:f + k], (h, 1)))
            params.append(out["params"].reshape(h * k, -1).astype(np.float64))
            textures.append(np.tile(tab.texture[f:f + k], h))
            abbes.append(np.tile(tab.abbe[f:f + k], h))
            firsts.append(next_closure + k * np.arange(h, dtype=np.int32))
            counts.append(np.full(h, k, np.int32))
            rows[hit[sel]] = n_mat + done + np.arange(h, dtype=np.int32)
            done += h
            next_closure += h * k
        cat = np.concatenate
        batch = tab._replace(
            kind=cat([tab.kind, *kinds]).astype(np.int32),
            weight=np.ascontiguousarray(cat([tab.weight, *weights])),
            params=np.ascontiguousarray(cat([tab.params, *params])),
            texture=cat([tab.texture, *textures]).astype(np.int32),
            first=cat([tab.first, *firsts]).astype(np.int32),
            count=cat([tab.count, *counts]).astype(np.int32),
            abbe=np.ascontiguousarray(cat([tab.abbe, *abbes])))
        return batch, rows


    def diffuse_albedo(self, tab, rows, mat, texel, d, ns, albedo) -> np.ndarray:
        """``albedo`` (N, 3) with the programmed hits' (rows != mat) replaced by their
        closures' diffuse albedo (``closure.diffuse_albedo``: what the photon maps
        continue there); (tab, rows) from ``closures_at``, texel (N, 3), d (N, 3) the
        arriving directions, ns (N, 3) the shading normals. ``albedo`` itself when no
        hit is programmed."""
        if rows is mat:
            return albedo
        shaded = np.flatnonzero(rows != mat)
        out = np.array(albedo, np.float64, copy=True)
        out[shaded] = closure.diffuse_albedo(tab, rows[shaded], texel[shaded], d[shaded],
                                             ns[shaded])
        return out

    def albedo_at(self, texels, prim, u, v, d, mat, ns, albedo) -> np.ndarray:
        """``diffuse_albedo`` at N hits given by triangle and barycentrics (prim, u, v),
        for callers without (tab, rows): texels the SurfaceTextures of the texel colour
        (``PreparedScene.texels``)."""
        if not self.active:
            return albedo
        tab, rows = self.closures_at(prim, u, v, d, mat)
        if rows is mat:
            return albedo
        return self.diffuse_albedo(tab, rows, mat, texels.albedo(prim, u, v, mat), d, ns,
                                   albedo)


def _subset(ins: ShadingInputs, sel) -> ShadingInputs:
    """The inputs of points ``sel`` (already validated: no second check)."""
    pick = {k: getattr(ins, k)[sel] for k in (
        "position", "normal", "true_normal", "incoming", "backfacing", "generated",
        "object_coords", "object_normal", "object_location", "object_random",
        "object_color", "object_index")}
    return ShadingInputs(**pick, uv=np.ascontiguousarray(ins.uv[:, sel]),
                         attributes=np.ascontiguousarray(ins.attributes[:, sel]))


def diffuse_area(tri_vertices: np.ndarray, tri_material: np.ndarray,
                 has_diffuse: np.ndarray) -> float:
    """Total area (m^2) of the triangles whose material has a diffuse lobe.

    tri_vertices (T, 3, 3) float32 metres; tri_material (T,) int32; has_diffuse (M,) bool.
    """
    if tri_vertices.shape[0] == 0:
        return 0.0
    has = has_diffuse[tri_material]
    v = tri_vertices[has].astype(np.float64)
    return float(0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]),
                                      axis=1).sum())


def prepare(scene: Scene, threads: int = 0) -> PreparedScene:
    """Build the PreparedScene of ``scene`` with ``threads`` workers (0 = every core)."""
    mesh = scene.mesh
    workers = use_threads(threads)
    mats = bsdf.material_table(scene.materials)
    closures = closure.table(scene.materials)
    lobes = closure.lobe_masks(closures)
    has_diffuse = lobes["diffuse"]
    tri_vertices = np.ascontiguousarray(mesh.triangle_vertices(), np.float32)
    tri_material = np.ascontiguousarray(mesh.material_index, np.int32)
    tri_normals = np.ascontiguousarray(mesh.normals, np.float32)
    lo, hi = scene.bounds()
    # The sphere photons from the sun and the world start on holds the media too (a fog
    # box need not be a surface).
    geo = np.concatenate([mesh.vertices.reshape(-1, 3),
                          scene.media.boundary.reshape(-1, 3)]).astype(np.float64)
    if geo.size:
        glo = geo.min(axis=0)
        ghi = geo.max(axis=0)
    else:
        glo = ghi = np.zeros(3)
    centre, radius = bounding_sphere(glo, ghi)
    n_obj = int(mesh.object_index.max()) + 1 if mesh.triangle_count else 0
    specular_material = lobes["rough"] | lobes["delta"]
    specular_objects = np.zeros(n_obj, bool)
    if mesh.triangle_count:
        specular_objects[np.unique(mesh.object_index[specular_material[mesh.material_index]])] = True
    light_set = LightSet.from_lights(scene.lights)
    emissive = EmissiveTriangles.from_mesh(mesh, scene.materials)
    emissive_index = np.full(mesh.triangle_count, -1, np.int32)
    emissive_index[emissive.triangle] = np.arange(emissive.count, dtype=np.int32)
    shader = HitShader(scene, closures, tri_vertices, tri_normals, tri_material,
                       geometry.scene_extent(lo, hi))
    return PreparedScene(
        scene=scene, threads=workers, accel=Accelerator(tri_vertices, threads=workers),
        tri_vertices=tri_vertices, tri_normals=tri_normals,
        tri_material=tri_material, materials=mats, closures=closures,
        texels=SurfaceTextures(scene, np.ones_like(mats["diffuse"])),
        emissive_index=emissive_index, has_diffuse=has_diffuse,
        nondelta=has_diffuse | lobes["rough"], has_delta=lobes["delta"],
        sampled_only=lobes["rough"] & ~has_diffuse,
        specular_material=specular_material, light_set=light_set,
        light_shows=np.any(light_set.radiance > 0, axis=1),
        emissive=emissive,
        world=np.asarray(scene.world.radiance, np.float64).reshape(3),
        surfaces=SurfaceTextures(scene, mats["diffuse"]),
        extent=geometry.scene_extent(lo, hi), centre=centre,
        radius=radius * 1.01 if radius > 0 else 0.0,
        objects=object_spheres(tri_vertices, mesh.object_index, n_obj),
        specular_objects=specular_objects,
        diffuse_area=diffuse_area(tri_vertices, tri_material, has_diffuse),
        hit_shader=shader,
        medium=regions.renderable(scene.media, geometry.scene_extent(lo, hi), workers,
                                  density_fields(scene, shader)))

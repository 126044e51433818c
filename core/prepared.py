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
  through it by BSDF sampling), ``glossy_on_diffuse`` (a rough glossy lobe and a diffuse one,
  a Principled wall: final-gather rays read the diffuse part there and follow the glossy
  part, core/integrators/gather.py), ``emissive_index`` (T,) int32 each triangle's row in ``emissive`` (-1: not emissive),
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

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from .lights.light_set import EmissiveTriangles, LightSet
from .materials import bsdf, closure
from .materials.textures import SurfaceTextures
from .media import regions
from .media.density import DensityFields
from .scene import closures as cl, geometry
from .shading import interpreter, light_path, normals
from .shading import program as pg
from .shading.inputs import ShadingInputs
from .scene.accel import Accelerator, use_threads
from .scene.bounds import Targets, bounding_sphere, object_spheres
from .scene.checks import SceneError
from .scene.closures import CLOSURE_PRINCIPLED
from .scene.contract import CAMERA_ORTHOGRAPHIC, Scene
from .scene.media import DENSITY_SLOTS, WORLD


def density_fields(scene: Scene, shader: "HitShader") -> DensityFields | None:
    """The heterogeneous media's densities (core/media/density.py): each medium's density
    program bound to the interpreter with the Position (world), Object and Generated
    coordinates of the medium's object (``shader``'s transforms, as at a surface hit of
    it; the World's: the position for both, as Cycles without an object), its majorant
    measured over its boundary's box (the World's: ``world_medium_box``); None when every
    medium is homogeneous."""
    media = scene.media
    rows = np.flatnonzero(media.density_texture >= 0)
    if rows.size == 0:
        return None
    evaluators, boxes, colour = {}, {}, []
    for r in rows.tolist():
        prog = media.programs[int(media.density_texture[r])]
        if prog.outputs[0, 1] != pg.TARGET_DENSITY:
            raise SceneError(f"medium '{media.names[r]}': its density program's output has "
                             f"target {prog.outputs[0, 1]}, not TARGET_DENSITY")
        # A varying colour: the program's seven outputs (density, Color, Absorption Color)
        varies = prog.outputs.shape[0] == DENSITY_SLOTS
        if varies:
            colour.append(r)

        def evaluate(p, prog=prog, obj=int(media.bounds[r]), varies=varies):
            n = p.shape[0]
            world = p + shader.origin
            if obj == WORLD:  # no object: Object and Generated are the position (Cycles)
                local = generated = world
            else:
                local, generated = shader.object_point(np.full(n, obj), world)
            inputs = ShadingInputs.build(world, np.zeros((n, 3), np.float32),
                                         object_coords=local, generated=generated)
            out = interpreter.evaluate(prog, inputs, scene.program_images)
            return out if varies else out[:, 0]
        evaluators[r] = evaluate
        if int(media.bounds[r]) == WORLD:
            boxes[r] = world_medium_box(scene)
        else:
            tri = media.boundary[media.boundary_medium == r].reshape(-1, 3).astype(np.float64)
            boxes[r] = (tri.min(axis=0), tri.max(axis=0))
    return DensityFields(evaluators, boxes, media.names, colour)


WORLD_BOX_MARGIN = 0.01
"""The box of a World volume of varying density is the scene's box widened by this
fraction of its diagonal on every side (``world_medium_box``)."""


def world_medium_box(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (3,) float64 render-frame metres: the box a World volume of varying density
    fills (docs/volumes.md "World volume of varying density"): the mesh's vertices, the
    media's boundaries and the camera's position, widened by WORLD_BOX_MARGIN of its
    diagonal (at least 1 mm). Outside it the World's varying part is empty: its rays reach
    infinity, which no tracking walks."""
    pts = np.concatenate([scene.mesh.vertices.reshape(-1, 3).astype(np.float64),
                          scene.media.boundary.reshape(-1, 3).astype(np.float64),
                          np.asarray(scene.camera.to_world, np.float64)[None, :3, 3]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = max(WORLD_BOX_MARGIN * float(np.linalg.norm(hi - lo)), 1e-3)
    return lo - pad, hi + pad


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
    glossy_on_diffuse: np.ndarray
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
    lobes: dict | None = None  # program_lobe_masks: (M,) bool per closure.LOBE_MASKS key
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

    @cached_property
    def refracts(self) -> np.ndarray:
        """(M,) bool, ``closure.refracting``: a path the material transmits is inside it
        (its IOR) after a front face. Computed once a render."""
        return closure.refracting(self.closures)

    @cached_property
    def opaque(self) -> np.ndarray:
        """(M,) bool: the material transmits nothing (``closure.lobe_masks``' "transmits"
        off). Computed once a render."""
        return ~closure.lobe_masks(self.closures)["transmits"]

    @property
    def used_materials(self) -> np.ndarray:
        """(M,) bool: the material is on at least one triangle."""
        used = np.zeros(self.materials["diffuse"].shape[0], bool)
        used[np.unique(self.tri_material)] = True
        return used


_BATCH_COLUMNS = {"kind": np.int32, "weight": np.float64, "params": np.float64,
                  "texture": np.int32, "abbe": None}
"""The closure columns of a ``HitShader`` batch's table and the dtype ``shade`` writes and
``merge`` keeps them in (None: the prepared table's own)."""


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
    = -d, backfacing, the UV maps (``Mesh.uvs``, the active render map, then the named
    ``Mesh.uv_maps``), object coordinates and normal,
    Generated (``Mesh.object_texspace``) and the object's location
    (``Mesh.object_to_world``), Object Info (``Mesh.object_info``: colour and its alpha,
    Random, Object Index) and the material's pass index (``Materials.pass_index``).
    """

    def __init__(self, scene: Scene, closures: closure.ClosureTable, tri_vertices,
                 tri_normals, tri_material, extent: float):
        mats, mesh = scene.materials, scene.mesh
        progs = mats.programs if mats.programs is not None else (None,) * mats.count
        used = np.bincount(mesh.material_index, minlength=mats.count)[:mats.count] > 0
        self.programs = progs
        self.images = scene.program_images
        # materials whose closures, their weights or the shading normal a program
        # computes (TARGET_CLOSURE, TARGET_WEIGHT, TARGET_NORMAL outputs): their hits get
        # closure rows of their own
        self.programmed = np.array(
            [p is not None and bool(np.any(np.isin(p.outputs[:, 1],
                                                   (pg.TARGET_CLOSURE, pg.TARGET_WEIGHT,
                                                    pg.TARGET_NORMAL))))
             for p in progs], bool).reshape(mats.count)
        # materials whose emission a program computes (TARGET_EMISSION outputs)
        self.emission_programmed = np.array(
            [p is not None and bool(np.any(p.outputs[:, 1] == pg.TARGET_EMISSION))
             for p in progs], bool).reshape(mats.count)
        # materials whose opacity a program computes (TARGET_ALPHA)
        self.alpha_programmed = np.array(
            [p is not None and bool(np.any(p.outputs[:, 1] == pg.TARGET_ALPHA))
             for p in progs], bool).reshape(mats.count)
        self.emission = np.asarray(mats.emission, np.float64).reshape(-1, 3)
        self.mesh_material = mesh.material_index
        self.active = bool(np.any(self.programmed & used))
        self.table = closures
        # materials with a tangent-dependent closure (``closure.anisotropic_rows``) as
        # prepared: ``tangents`` reads this at the hits that kept the prepared table
        self.anisotropic = closure.anisotropic_rows(closures)
        # materials whose diffuse lobe lies under a Principled BSDF's layers (dielectric
        # specular, coat, sheen): its albedo is base x (1 - the layers' albedo toward the
        # viewer), not the constant Materials.diffuse, so the photon terms take
        # closure.diffuse_albedo at their hits (``diffuse_albedo``). Measured: the default
        # Principled's diffuse albedo is 0.770 at normal view, 0.745 at 60 deg, not 0.8.
        self.layered = np.array(
            [bool(np.any(closures.kind[closures.first[m]:closures.first[m] + closures.count[m]]
                         == CLOSURE_PRINCIPLED)) for m in range(mats.count)],
            bool).reshape(mats.count)
        self.tri_vertices, self.tri_normals = tri_vertices, tri_normals
        self.tri_material, self.extent = tri_material, float(extent)
        self.tri_uv = mesh.uvs
        self.tri_uv_maps = mesh.uv_maps  # (T, 3, U, 2) or None: the named UV maps
        self.tri_attributes = mesh.attributes  # (T, 3, A, 4) or None
        self.tri_tangents = mesh.tangents  # (T, 3, G, 4) or None
        self.tri_object = mesh.object_index
        n_obj = int(mesh.object_index.max()) + 1 if mesh.triangle_count else 0
        if mesh.object_to_world is not None:
            to_world = np.asarray(mesh.object_to_world, np.float64)
        else:
            to_world = np.broadcast_to(np.eye(4), (n_obj, 4, 4))
        to_object = np.linalg.inv(to_world) if len(to_world) else to_world
        # world -> object: its linear part and shift apart, contiguous (``object_point``
        # gathers 12 numbers a hit instead of the 16 of the 4 x 4 matrix)
        self.to_object_linear = np.ascontiguousarray(to_object[:, :3, :3])
        self.to_object_shift = np.ascontiguousarray(to_object[:, :3, 3])
        self.location = to_world[:, :3, 3] if len(to_world) else np.zeros((0, 3))
        self.linear = to_world[:, :3, :3]
        if mesh.object_texspace is not None:
            self.texspace = np.asarray(mesh.object_texspace, np.float64)
        else:
            self.texspace = np.broadcast_to(np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]),
                                            (n_obj, 2, 3))
        info = np.zeros((n_obj, 6), np.float32)
        info[:, 5] = 1.0  # the object colour's alpha (Object Info Alpha)
        if mesh.object_info is not None:
            given = np.asarray(mesh.object_info, np.float32)
            info = np.zeros((max(n_obj, given.shape[0]), 6), np.float32)
            info[:, 5] = 1.0
            info[:given.shape[0], :given.shape[1]] = given
        self.object_info = info
        self.pass_index = (np.zeros(mats.count, np.float32) if mats.pass_index is None
                           else np.asarray(mats.pass_index, np.float32))
        self.origin = (np.zeros(3) if mesh.origin is None
                       else np.asarray(mesh.origin, np.float64))
        self.bumped = np.array([p is not None and _reads_bump(p) for p in progs],
                               bool).reshape(mats.count)
        # the input sources (SOURCE_*) each material's program reads: ``inputs`` builds
        # only those (the Object coordinates alone were 0.3 s of a textured camera pass)
        self.program_sources = [frozenset() if p is None else frozenset(
            p.instructions[p.instructions[:, 0] == pg.OP_INPUT, 1].tolist()) for p in progs]
        # materials running the same program (equal instructions, constants, tables and
        # outputs; -1: none) share one evaluation at a batch's hits (``shade``)
        self.program_group = _program_groups(progs)
        # materials with a non-zero Coat Normal in their closure rows or whose program
        # writes one: elsewhere ``coat_normals`` has nothing to do (unless the program
        # bends the shading normal) and ``shade`` skips its scan of the rows
        self.coat_normal = np.array(
            [bool(np.any(closures.params[closures.first[m]:closures.first[m]
                                         + closures.count[m],
                                         cl.COAT_NORMAL:cl.COAT_NORMAL + 3] != 0.0))
             or (p is not None and bool(np.any(
                 (p.outputs[:, 1] == pg.TARGET_CLOSURE) & (p.outputs[:, 3] >= cl.COAT_NORMAL)
                 & (p.outputs[:, 3] < cl.COAT_NORMAL + 3))))
             for m, p in enumerate(progs)], bool).reshape(mats.count)
        # some used material's program reads the Light Path node: the callers then fill
        # the hits' context (core/shading/light_path.py; else they pass None, zeros)
        self.reads_light_path = bool(np.any(used & np.array(
            [p is not None and bool(np.any((p.instructions[:, 0] == pg.OP_INPUT) & (
                p.instructions[:, 1] == pg.SOURCE_LIGHT_PATH))) for p in progs],
            bool).reshape(mats.count)))
        cam = scene.camera
        self.camera_position = np.asarray(cam.to_world, np.float64)[:3, 3]
        self.pixel_angle = float(cam.film_size[0]) / max(int(cam.width), 1)
        self.orthographic = cam.kind == CAMERA_ORTHOGRAPHIC

    def footprint(self, pos) -> np.ndarray:
        """(N,) float64 metres: the Bump node's footprint radius at render-frame points pos
        (N, 3), our stand-in for Cycles' ray differential (its compact dP): the camera's
        pixel spread times the distance from the camera (perspective), the pixel's width
        (orthographic). The same at a point whichever path reaches it (camera, photon,
        gather ray), and proportional to the scene's scale: a scaled scene bumps alike."""
        if self.orthographic:
            return np.full(pos.shape[0], self.pixel_angle)
        return self.pixel_angle * np.linalg.norm(pos - self.camera_position, axis=1)

    def sources(self, mat) -> frozenset:
        """The input sources (SOURCE_*) the programs of materials mat (int array) read."""
        return frozenset().union(*(self.program_sources[m] for m in np.unique(mat).tolist()))

    def inputs(self, prim, u, v, d, bump=False, path=None, reads=None
               ) -> tuple[ShadingInputs, np.ndarray]:
        """The ShadingInputs of N hits (prim (N,) int32 triangles, Embree barycentrics u, v
        (N,), d (N, 3) the arriving unit directions) and their materials (N,) int32. bump:
        also the rows at P + dPdx and P + dPdy (``ShadingInputs.bump_points``): dPdx, dPdy
        the ``footprint`` radius along two orthonormal tangents of the true normal (Cycles'
        differential_from_compact, make_orthonormals), reached by moving the barycentrics
        in the triangle's plane. path: the Light Path node's outputs for the rays that
        reached the hits (``ShadingInputs.light_path``: (N, K) or (K,) float32, the
        caller's context, core/shading/light_path.py; None: zeros). reads: the
        sources (SOURCE_*) the programs to run read (``sources``; None: every one): the
        others are left at ``ShadingInputs.build``'s defaults, which no such program
        reads (position, both normals and incoming are always the hits'; Object
        coordinates without Generated skip Generated's arithmetic)."""
        pos, ngf, nsf, mat, _, front = geometry.facing_surface_points(
            self.tri_vertices, self.tri_normals, self.tri_material, prim, u, v,
            np.ascontiguousarray(d, np.float64), self.extent)
        if bump and prim.shape[0]:
            r = self.footprint(pos)
            ex, ey = _orthonormals(ngf)
            tri = self.tri_vertices[prim].astype(np.float64)
            e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
            g11, g12, g22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2),
                             np.einsum("ij,ij->i", e2, e2))
            det = g11 * g22 - g12 * g12
            us, vs = [u], [v]
            for e in (ex, ey):
                delta = r[:, None] * e
                b1, b2 = np.einsum("ij,ij->i", e1, delta), np.einsum("ij,ij->i", e2, delta)
                us.append((u + (g22 * b1 - g12 * b2) / det).astype(np.float32))
                vs.append((v + (g11 * b2 - g12 * b1) / det).astype(np.float32))
            d3 = np.concatenate([d, d, d])
            p3 = path if path is None or np.ndim(path) == 1 else np.concatenate([path] * 3)
            ins, _ = self.inputs(np.concatenate([prim] * 3), np.concatenate(us),
                                 np.concatenate(vs), d3, path=p3, reads=reads)
            return replace(ins, bump_points=prim.shape[0]), mat

        def read(*sources):
            return reads is None or not reads.isdisjoint(sources)
        world = pos + self.origin
        obj = self.tri_object[prim]
        given = {}
        if read(pg.SOURCE_GENERATED, pg.SOURCE_OBJECT):
            local, generated = self.object_point(obj, world, read(pg.SOURCE_GENERATED))
            given.update(object_coords=local)
            if generated is not None:
                given.update(generated=generated)
        if read(pg.SOURCE_OBJECT_NORMAL):
            # Normals to object space: n_obj ~ A^T n_world for a world normal inv(A)^T n_obj.
            onrm = np.einsum("nji,nj->ni", self.linear[obj], nsf)
            onrm /= np.maximum(np.linalg.norm(onrm, axis=1), 1e-30)[:, None]
            given.update(object_normal=onrm)
        if read(pg.SOURCE_OBJECT_LOCATION):
            given.update(object_location=self.location[obj])
        if read(pg.SOURCE_OBJECT_COLOR):
            given.update(object_color=self.object_info[obj, :3])
        if read(pg.SOURCE_OBJECT_RANDOM):
            given.update(object_random=self.object_info[obj, 3])
        if read(pg.SOURCE_OBJECT_INDEX):
            given.update(object_index=self.object_info[obj, 4])
        if read(pg.SOURCE_OBJECT_ALPHA):
            given.update(object_alpha=self.object_info[obj, 5])
        if read(pg.SOURCE_MATERIAL_INDEX):
            given.update(material_index=self.pass_index[mat])
        if read(pg.SOURCE_BACKFACING):
            given.update(backfacing=(~front).astype(np.float32))
        if read(pg.SOURCE_UV, pg.SOURCE_ATTRIBUTE_COLOR, pg.SOURCE_ATTRIBUTE_ALPHA,
                pg.SOURCE_TANGENT, pg.SOURCE_TANGENT_SIGN):
            w = (1.0 - u - v).astype(np.float64)  # the first corner's barycentric
            if read(pg.SOURCE_UV):
                given.update(uv=self._uv_maps(prim, u, v, w))
            if read(pg.SOURCE_ATTRIBUTE_COLOR, pg.SOURCE_ATTRIBUTE_ALPHA):
                given.update(attributes=self._attributes(prim, u, v, w))
            if read(pg.SOURCE_TANGENT, pg.SOURCE_TANGENT_SIGN):
                given.update(tangents=self._tangents(prim, u, v, w))
        if read(pg.SOURCE_NORMAL_TO_WORLD):
            given.update(normal_to_world=np.transpose(self.to_object_linear[obj], (0, 2, 1)))
        if read(pg.SOURCE_LIGHT_PATH):
            given.update(light_path=path)
        ins = ShadingInputs.build(world, nsf, true_normal=ngf, incoming=-np.asarray(d),
                                  **given)
        return ins, mat

    def emission_at(self, prim, u, v, d, mat, emission=None, path=None) -> np.ndarray:
        """(N, 3) float64 emitted radiance W/(m^2 sr) at N hits (prim, u, v, d as for
        ``inputs``, mat (N,) their materials): ``emission`` (default: the materials'
        constant emission) with the hits whose material's emission is programmed
        replaced by the program's value there (clamped to >= 0: a negative radiance
        means nothing here). ``emission`` itself when no hit is programmed (bit for bit
        as without programs). path: the hits' Light Path context (``inputs``)."""
        if emission is None:
            emission = self.emission[mat]
        if prim.shape[0] == 0 or not np.any(self.emission_programmed[mat]):
            return emission
        hit = np.flatnonzero(self.emission_programmed[mat])
        out = np.array(emission, np.float64, copy=True)
        ins, _ = self.inputs(prim[hit], u[hit], v[hit], np.asarray(d)[hit],
                             path=_path_rows(path, hit), reads=self.sources(mat[hit]))
        for m in np.unique(mat[hit]):
            sel = np.flatnonzero(mat[hit] == m)
            prog = self.programs[m]
            values = interpreter.evaluate(prog, _subset(ins, sel), self.images)
            em = np.zeros((sel.size, 3))
            for o, (_, target, _, slot) in enumerate(prog.outputs.tolist()):
                if target == pg.TARGET_EMISSION:
                    em[:, slot] = values[:, o]
            out[hit[sel]] = np.maximum(np.nan_to_num(em, nan=0.0, posinf=0.0), 0.0)
        return out

    def alpha_at(self, prim, u, v, path=None) -> np.ndarray:
        """(N,) float64 in [0, 1]: the program's opacity (TARGET_ALPHA) at N hits on
        triangles prim (N,) whose material's opacity is programmed, Embree barycentrics
        (u, v); seen along the triangle's normal (a cut-out has no direction:
        ``SurfaceTextures.opacity`` is asked without one). It multiplies the material's
        constant opacity (``SurfaceTextures.use_program_alpha``). path: the rays' Light
        Path context (``inputs``; a shadow ray's ``light_path.shadow``)."""
        out = np.ones(prim.shape[0])
        if prim.shape[0] == 0:
            return out
        mat = self.mesh_material[prim]
        tv = self.tri_vertices[prim].astype(np.float64)
        n = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        ins, _ = self.inputs(prim, np.asarray(u), np.asarray(v), -n, path=path,
                             reads=self.sources(mat[self.alpha_programmed[mat]]))
        for m in np.unique(mat):
            if not self.alpha_programmed[m]:
                continue
            sel = np.flatnonzero(mat == m)
            prog = self.programs[m]
            values = interpreter.evaluate(prog, _subset(ins, sel), self.images)
            col = int(np.flatnonzero(prog.outputs[:, 1] == pg.TARGET_ALPHA)[0])
            out[sel] = np.clip(np.nan_to_num(values[:, col], nan=1.0), 0.0, 1.0)
        return out

    def emission_points(self, prim, u, v, d) -> np.ndarray:
        """``emission_at`` for triangles prim (N,) at barycentrics (u, v), their own
        materials (light sampling and photon emission on textured emitters: every Light
        Path flag 0, as Cycles' light samples, ``light_path.emission_sample``)."""
        return self.emission_at(prim, u, v, d, self.mesh_material[prim],
                                path=light_path.emission_sample(1)[0])

    STRATA = 4
    """Textured emitters: each triangle's mean radiance is the average of the program at
    the centroids of its STRATA^2 equal-area sub-triangles (midpoint rule)."""

    def textured_emitters(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(triangles (K,) int32, mean radiance (K, 3) float64) of every triangle whose
        material's emission is programmed and used, or None: the pick weights of
        ``EmissiveTriangles`` (the estimator divides by them, so any positive weights
        are unbiased; the mean keeps the variance low). Seen along the triangle's own
        normal (Incoming = normal, front side)."""
        used = self.emission_programmed[self.mesh_material] if self.mesh_material.size \
            else np.zeros(0, bool)
        tri = np.flatnonzero(used).astype(np.int32)
        if tri.size == 0:
            return None
        s = self.STRATA
        bary = []  # centroids of the s^2 sub-triangles of a regular subdivision
        for i in range(s):
            for j in range(s - i):
                bary.append(((i + 1 / 3) / s, (j + 1 / 3) / s))      # upright
                if i + j < s - 1:
                    bary.append(((i + 2 / 3) / s, (j + 2 / 3) / s))  # inverted
        b = np.array(bary)  # (s^2, 2): weights of corners 1 and 2
        k = b.shape[0]
        prim = np.repeat(tri, k)
        u, v = np.tile(b[:, 0], tri.size), np.tile(b[:, 1], tri.size)
        e1 = self.tri_vertices[tri, 1].astype(np.float64) - self.tri_vertices[tri, 0]
        e2 = self.tri_vertices[tri, 2].astype(np.float64) - self.tri_vertices[tri, 0]
        n = np.cross(e1, e2)
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        em = self.emission_points(prim, u, v, np.repeat(-n, k, axis=0))
        return tri, em.reshape(tri.size, k, 3).mean(axis=1)

    def _uv_maps(self, prim, u, v, w) -> np.ndarray:
        """(1 + U, N, 2) the UV maps at the hits: the active render map (``Mesh.uvs``),
        then the named ones (``Mesh.uv_maps``), interpolated barycentrically."""
        uv = (w[:, None] * self.tri_uv[prim, 0] + u[:, None] * self.tri_uv[prim, 1]
              + v[:, None] * self.tri_uv[prim, 2])[None]
        if self.tri_uv_maps is None or self.tri_uv_maps.shape[2] == 0:
            return uv
        c = self.tri_uv_maps[prim]  # (N, 3, U, 2)
        a = w[:, None, None] * c[:, 0] + u[:, None, None] * c[:, 1] + v[:, None, None] * c[:, 2]
        return np.concatenate([uv, np.transpose(a, (1, 0, 2))]).astype(np.float32)

    def _attributes(self, prim, u, v, w) -> np.ndarray:
        """(A, N, 4) the mesh attributes at the hits, interpolated like the UVs."""
        if self.tri_attributes is None:
            return np.zeros((0, prim.shape[0], 4), np.float32)
        c = self.tri_attributes[prim]  # (N, 3, A, 4)
        a = w[:, None, None] * c[:, 0] + u[:, None, None] * c[:, 1] + v[:, None, None] * c[:, 2]
        return np.ascontiguousarray(np.transpose(a, (1, 0, 2)), np.float32)

    def _tangents(self, prim, u, v, w) -> np.ndarray:
        """(G, N, 4) the tangent maps at the hits (tangent and sign interpolated like the
        UVs, as Cycles interpolates its corner attributes; the tangent is not
        normalised, Cycles' svm_node_normal_map reads it so)."""
        if self.tri_tangents is None:
            return np.zeros((0, prim.shape[0], 4), np.float32)
        c = self.tri_tangents[prim]  # (N, 3, G, 4)
        a = w[:, None, None] * c[:, 0] + u[:, None, None] * c[:, 1] + v[:, None, None] * c[:, 2]
        return np.ascontiguousarray(np.transpose(a, (1, 0, 2)), np.float32)

    def object_point(self, obj, world, generated=True):
        """Object-space positions (N, 3) and Generated coordinates (N, 3) float64 of world
        points (N, 3) on objects obj (N,); Generated None when not ``generated``."""
        local = (np.einsum("nij,nj->ni", self.to_object_linear[obj], world)
                 + self.to_object_shift[obj])
        if not generated:
            return local, None
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
        tangent is 0 and ``closure.frame`` falls back to another axis.

        A linked Tangent input (the closure's ``TANGENT`` slots, world space, written by
        the program or folded into the row) replaces the radial tangent: the row's first
        closure with a non-zero one gives it (one tangent per hit, as one shading normal;
        Cycles gives each closure its own)."""
        n = prim.shape[0]
        out = closure.default_tangents(n)
        if n == 0:
            return out
        if tab is self.table:  # rows are materials: no per-hit scan of their closures
            if not self.anisotropic.any():
                return out
            sel = np.flatnonzero(self.anisotropic[rows])
        else:
            sel = np.flatnonzero(closure.anisotropic_rows(tab, rows))
        if sel.size == 0:
            return out
        obj = self.tri_object[prim[sel]]
        _, g = self.object_point(obj, np.asarray(pos, np.float64)[sel] + self.origin)
        t_obj = np.stack([-(g[:, 1] - 0.5), g[:, 0] - 0.5, np.zeros(sel.size)], axis=1)
        out[sel] = np.einsum("nji,nj->ni", self.to_object_linear[obj], t_obj)
        given = tab.params[:, cl.TANGENT:cl.TANGENT + 3]
        has = np.any(given != 0.0, axis=1) & np.all(np.isfinite(given), axis=1)
        if has.any():
            first, count = tab.first[rows[sel]], tab.count[rows[sel]]
            todo = np.ones(sel.size, bool)
            for j in range(int(count.max()) if count.size else 0):  # closures per row
                c = np.minimum(first + j, has.shape[0] - 1)
                take = todo & (j < count) & has[c]
                out[sel[take]] = given[c[take]]
                todo &= ~take
        return out

    def closures_at(self, prim, u, v, d, mat, path=None
                    ) -> tuple[closure.ClosureTable, np.ndarray]:
        """(tab, rows) for N hits (class doc): prim, u, v, d as for ``inputs``, mat (N,)
        int32 their materials. rows is ``mat`` itself when no hit has a program. For the
        shading normal the programs give too, ``shade``; path as for ``inputs``."""
        tab, rows, _ = self.shade(prim, u, v, d, mat, path=path)
        return tab, rows

    def shade(self, prim, u, v, d, mat, ns=None, path=None):
        """(tab, rows, ns) for N hits: ``closures_at``'s (tab, rows) and the hits' shading
        normals, ns (N, 3) (the interpolated normals facing the ray, float64) with the
        programmed hits' normal output (a Normal Map or Bump node into a BSDF's Normal
        input) in place: normalised, facing where the program made it face (the program
        reads the normal facing the ray, as Cycles' sd->N). ns is returned as given (the
        same object) when no hit's program sets a normal; None stays None. path: the
        hits' Light Path context (``inputs``)."""
        if not self.active or prim.shape[0] == 0:
            return self.table, mat, ns
        hit = np.flatnonzero(self.programmed[mat])
        if hit.size == 0:
            return self.table, mat, ns
        tab = self.table
        n_mat, n_cl = tab.first.shape[0], tab.kind.shape[0]
        hmat = mat[hit]
        per_mat = np.bincount(hmat, minlength=n_mat)  # hits of each material
        present = np.flatnonzero(per_mat)  # np.unique(hmat), without its sort
        ins, _ = self.inputs(prim[hit], u[hit], v[hit], np.asarray(d)[hit],
                             bump=bool(self.bumped[present].any()),
                             path=_path_rows(path, hit), reads=self.sources(present))
        rows = np.array(mat, np.int32, copy=True)
        values = self._group_values(ins, hmat, present)
        # the per-batch table built in place: the prepared closures, then each programmed
        # hit's copies of its material's (materials in order, each one's hits in order),
        # every row written once (no per-material float32 copy, float64 conversion and
        # concatenation: three copies of every row). One material: its hits in order,
        # without the sort and the index copies.
        one = present.size == 1
        order = None if one else np.argsort(hmat, kind="stable")
        per = per_mat[present]
        total = n_cl + int(np.dot(per, tab.count[present]))
        n_rows = n_mat + hit.size

        def grown(a, size, dtype=None):
            out = np.empty((size,) + a.shape[1:], a.dtype if dtype is None else dtype)
            out[:a.shape[0]] = a
            return out
        kind, weight, params, texture, abbe = (grown(getattr(tab, f), total, dt)
                                               for f, dt in _BATCH_COLUMNS.items())
        first, count = grown(tab.first, n_rows, np.int32), grown(tab.count, n_rows, np.int32)
        done = 0
        next_closure = n_cl
        bent = ns
        for m, h in zip(present.tolist(), per.tolist()):
            # (the first h rows of ins: with bump offsets it holds 3 h)
            sel = slice(0, h) if one else order[done:done + h]
            hs = hit if one else hit[sel]  # the material's hits, in order
            f, k = int(tab.first[m]), int(tab.count[m])
            c = slice(next_closure, next_closure + h * k)
            out = interpreter.closure_values(self.programs[m], values if one else values[sel],
                                             tab.params[f:f + k].astype(np.float32),
                                             out=params[c].reshape(h, k, params.shape[1]))
            if out["normal"] is not None and ns is not None:
                if bent is ns:
                    bent = np.array(ns, np.float64, copy=True)
                # Cycles' ensure_valid_specular_reflection: the programmed normal
                # tilted until the mirror direction leaves above the true surface
                bent[hs] = normals.valid_specular_reflection(
                    ins.true_normal[sel], ins.incoming[sel],
                    _unit_or(out["normal"], bent[hs]))
            # Where the program bends the shading normal, an unlinked Coat Normal is the
            # un-bent one (Cycles links it to the geometry's normal, sd->N, which a Bump
            # or Normal Map into the Normal input does not change)
            if self.coat_normal[m] or out["normal"] is not None:
                coat_normals(out["params"], ins.true_normal[sel], ins.incoming[sel],
                             None if out["normal"] is None else
                             (tab.kind[f:f + k], ins.normal[sel]))
            kind[c].reshape(h, k)[...] = tab.kind[f:f + k]
            weight[c].reshape(h, k, 3)[...] = tab.weight[f:f + k]
            if out["weight"] is not None:  # the linked Mix factors of each closure here
                weight[c] *= out["weight"].reshape(h * k, 1)
            texture[c].reshape(h, k)[...] = tab.texture[f:f + k]
            abbe[c].reshape(h, k)[...] = tab.abbe[f:f + k]
            r = slice(n_mat + done, n_mat + done + h)
            first[r] = next_closure + k * np.arange(h, dtype=np.int32)
            count[r] = k
            rows[hs] = np.arange(r.start, r.stop, dtype=np.int32)
            done += h
            next_closure += h * k
        batch = tab._replace(kind=kind, weight=weight, params=params, texture=texture,
                             first=first, count=count, abbe=abbe)
        return batch, rows, bent


    def merge(self, pieces) -> tuple[closure.ClosureTable, np.ndarray]:
        """One (tab, rows) for hits shaded in several batches: pieces [(tab, rows)], each a
        ``shade`` batch's table and the rows (int32) of the hits kept from it; the rows
        come back concatenated in that order. The prepared rows and closures stay first,
        as in every batch; each kept hit's programmed row follows, with copies of its
        closures (in ``shade``'s dtypes, ``_BATCH_COLUMNS``), so every hit reads the
        closures its own batch gave it."""
        tab = self.table
        n_mat, n_cl = tab.first.shape[0], tab.kind.shape[0]
        cols = {f: getattr(tab, f).dtype if dt is None else dt for f, dt in _BATCH_COLUMNS.items()}
        parts = {f: [getattr(tab, f)] for f in cols}
        first, count, out = [tab.first], [tab.count], []
        next_row, next_closure = n_mat, n_cl
        for t, r in pieces:
            r = np.asarray(r, np.int32)
            own = np.flatnonzero(r >= n_mat)
            src = r[own]
            cnt = t.count[src].astype(np.int64)
            start = np.cumsum(cnt) - cnt
            idx = np.repeat(t.first[src].astype(np.int64) - start, cnt) + np.arange(int(cnt.sum()))
            for f in cols:
                parts[f].append(getattr(t, f)[idx])
            first.append(next_closure + start)
            count.append(cnt)
            new = np.array(r, np.int32, copy=True)
            new[own] = next_row + np.arange(own.size)
            out.append(new)
            next_row += own.size
            next_closure += int(cnt.sum())
        merged = tab._replace(**{f: np.concatenate(parts[f]).astype(dt, copy=False)
                                 for f, dt in cols.items()},
                              first=np.concatenate(first).astype(np.int32),
                              count=np.concatenate(count).astype(np.int32))
        return merged, (np.concatenate(out) if out else np.zeros(0, np.int32))

    def _group_values(self, ins: ShadingInputs, mat, present) -> np.ndarray:
        """(N, O) float32: the programs' outputs at the N points of ``ins`` whose
        materials mat (N,) all have a program with O outputs (present: the distinct
        materials of mat, sorted), each program evaluated
        once over the points of every material running it (``program_group``; the
        inputs copied only when the batch holds more than one program). A point's
        values do not depend on the others', so this is bit for bit what evaluating
        each material's points apart gives; it saves the per-material copies of the
        inputs and kernel launches (a scene often has one program on many materials)."""
        groups = self.program_group[present]
        if np.all(groups == groups[0]):
            return interpreter.evaluate(self.programs[int(present[0])], ins, self.images)
        group = self.program_group[mat]
        found = np.unique(groups)
        width = max(self.programs[int(m)].outputs.shape[0] for m in present.tolist())
        out = np.zeros((mat.shape[0], width), np.float32)
        for g in found:
            sel = np.flatnonzero(group == g)
            values = interpreter.evaluate(self.programs[int(mat[sel[0]])],
                                          _subset(ins, sel), self.images)
            out[sel, :values.shape[1]] = values
        return out

    def diffuse_albedo(self, tab, rows, mat, texel, d, ns, albedo) -> np.ndarray:
        """``albedo`` (N, 3) with the programmed hits' (rows != mat) and the layered
        materials' hits (``layered``) replaced by their closures' diffuse albedo
        (``closure.diffuse_albedo``: what the photon maps continue there); (tab, rows)
        from ``closures_at``, texel (N, 3), d (N, 3) the arriving directions, ns (N, 3)
        the shading normals (either side: the viewer's is taken). ``albedo``
        itself when no hit is programmed or layered."""
        layered = self.layered[mat]
        redo = layered if rows is mat else (rows != mat) | layered
        if not redo.any():
            return albedo
        shaded = np.flatnonzero(redo)
        # (closure.albedo takes ns on the viewer's side itself)
        d, ns = np.asarray(d)[shaded], np.asarray(ns, np.float64)[shaded]
        out = np.array(albedo, np.float64, copy=True)
        out[shaded] = closure.diffuse_albedo(tab, rows[shaded], texel[shaded], d, ns)
        return out

    def albedo_at(self, texels, prim, u, v, d, mat, ns, albedo, path=None) -> np.ndarray:
        """``diffuse_albedo`` at N hits given by triangle and barycentrics (prim, u, v),
        for callers without (tab, rows): texels the SurfaceTextures of the texel colour
        (``PreparedScene.texels``); path as for ``inputs``."""
        if not self.active and not self.layered[mat].any():
            return albedo
        tab, rows = self.closures_at(prim, u, v, d, mat, path)
        return self.diffuse_albedo(tab, rows, mat, texels.albedo(prim, u, v, mat), d, ns,
                                   albedo)


def coat_normals(params, true_normal, incoming, unbent=None) -> None:
    """Make the Coat Normals of programmed closure rows what the coat shades with, in
    place: params (N, C, PARAM_COUNT) float32 or float64 holding float32 values
    (``interpreter.closure_values``), the
    ``COAT_NORMAL`` slots of each (point, closure) that has one (non-zero) made unit
    length and tilted as Cycles' maybe_ensure_valid_specular_reflection(sd, coat_normal)
    (``normals.valid_specular_reflection``; true_normal, incoming (N, 3) as
    ``ShadingInputs``). A zero or non-finite one falls back to sd->N (Cycles'
    safe_normalize_fallback): 0, the shading normal, when ``unbent`` is None.

    unbent: None, or (kinds (C,) int32 the closures' kinds, normal (N, 3) the points'
    un-bent shading normals, Cycles' sd->N) when the program bends the shading normal (a
    Bump or Normal Map into a Normal input). Then every Principled closure with Coat
    Weight > 0 shades its coat (and its sheen's mix) about sd->N where its Coat Normal is
    unlinked (0) or degenerate, as Cycles, which links an unlinked Coat Normal to the
    geometry's normal, not to the Principled's Normal input. Rows without a Coat Normal
    and without a bent normal are untouched, so such a material renders bit for bit as
    before."""
    cn = params[:, :, cl.COAT_NORMAL:cl.COAT_NORMAL + 3]
    has = np.any(cn != 0.0, axis=2)
    if unbent is not None:
        kinds, normal = unbent
        has |= ((np.asarray(kinds) == cl.CLOSURE_PRINCIPLED)[None, :]
                & (params[:, :, cl.COAT_WEIGHT] > 0.0))
    if not has.any():
        return
    p, c = np.nonzero(has)
    v = cn[p, c].astype(np.float64)
    length = np.linalg.norm(v, axis=1)
    ok = np.isfinite(length) & (length > 0)
    unit = v / np.where(ok, length, 1.0)[:, None]
    if unbent is None:
        keep = ok
        unit = np.where(ok[:, None], unit, 0.0)
    else:
        keep = np.ones_like(ok)
        unit = np.where(ok[:, None], unit, _unit_or(normal[p], true_normal[p]))
    valid = normals.valid_specular_reflection(true_normal[p], incoming[p], unit)
    # float32 values whatever params' dtype (``shade`` fills its float64 table in place)
    params[p, c, cl.COAT_NORMAL:cl.COAT_NORMAL + 3] = np.where(keep[:, None], valid,
                                                               0.0).astype(np.float32)


def _unit_or(normal, fallback) -> np.ndarray:
    """(N, 3) float64: the program's normals (N, 3) made unit length, ``fallback`` (N, 3)
    where one is zero or not finite (Cycles' safe_normalize_fallback(N, sd->N))."""
    n = np.asarray(normal, np.float64)
    length = np.linalg.norm(n, axis=1)
    ok = np.isfinite(length) & (length > 0)
    return np.where(ok[:, None], n / np.where(ok, length, 1.0)[:, None], fallback)


def _path_rows(path, sel):
    """The Light Path context of hits ``sel``: path (N, K) indexed, (K,) or None as is."""
    return path if path is None or np.ndim(path) == 1 else np.asarray(path)[sel]


def _program_groups(programs) -> np.ndarray:
    """(M,) int32: a group per distinct program (equal instructions, constants, tables,
    register count and outputs), -1 for a material without one."""
    keys, out = {}, np.full(len(programs), -1, np.int32)
    for m, p in enumerate(programs):
        if p is not None:
            key = (p.instructions.tobytes(), p.constants.tobytes(), p.tables.tobytes(),
                   p.tables.shape, p.n_registers, p.outputs.tobytes())
            out[m] = keys.setdefault(key, len(keys))
    return out


def _reads_bump(program) -> bool:
    """The program reads inputs at the bump offsets (a Bump node's footprint)."""
    ins = program.instructions
    inp = ins[:, 0] == pg.OP_INPUT
    return bool(np.any(inp & ((ins[:, 3] != 0) | (ins[:, 1] == pg.SOURCE_BUMP_DPDX)
                              | (ins[:, 1] == pg.SOURCE_BUMP_DPDY))))


def _orthonormals(n) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (N, 3) of unit normals n (N, 3), as Cycles' make_orthonormals:
    a along (1, 1, 1) x n (or (-1, 1, 1) x n when n's components are equal), b = n x a."""
    same = (n[:, 0] == n[:, 1]) & (n[:, 0] == n[:, 2])
    a = np.where(same[:, None],
                 np.stack([n[:, 2] - n[:, 1], n[:, 0] + n[:, 2], -n[:, 1] - n[:, 0]], axis=1),
                 np.stack([n[:, 2] - n[:, 1], n[:, 0] - n[:, 2], n[:, 1] - n[:, 0]], axis=1))
    a /= np.linalg.norm(a, axis=1)[:, None]
    return a, np.cross(n, a)


def _subset(ins: ShadingInputs, sel) -> ShadingInputs:
    """The inputs of points ``sel`` (already validated: no second check), with their bump
    offset rows when ``ins`` has them."""
    if ins.bump_points:
        n = ins.bump_points
        sel = np.concatenate([sel, n + sel, 2 * n + sel])
    pick = {k: getattr(ins, k)[sel] for k in (
        "position", "normal", "true_normal", "incoming", "backfacing", "generated",
        "object_coords", "object_normal", "object_location", "object_random",
        "object_color", "object_index", "object_alpha", "material_index", "light_path")}
    return ShadingInputs(**pick, uv=np.ascontiguousarray(ins.uv[:, sel]),
                         attributes=np.ascontiguousarray(ins.attributes[:, sel]),
                         tangents=np.ascontiguousarray(ins.tangents[:, sel]),
                         normal_to_world=np.ascontiguousarray(ins.normal_to_world[sel]),
                         bump_points=sel.shape[0] // 3 if ins.bump_points else 0)


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


# What a programmed slot can hold, for the lobe masks: the values at which each kind of
# lobe appears or vanishes (a colour of 0 or 1, a weight, metallic or transmission of 0 or
# 1, a roughness of 0 (singular) or 1/2 (rough), an IOR of 1 or 1.5); the other slots
# (the tangent, the rotation) change no lobe's presence.
_PROBES = {cl.COLOR: (0.0, 1.0), cl.ROUGHNESS: (0.0, 0.5), cl.METALLIC: (0.0, 1.0),
           cl.IOR: (1.0, 1.5), cl.SPECULAR_LEVEL: (0.0, 0.5),
           cl.SPECULAR_TINT: (0.0, 1.0), cl.TRANSMISSION: (0.0, 1.0),
           cl.COAT_WEIGHT: (0.0, 1.0), cl.COAT_ROUGHNESS: (0.0, 0.5),
           cl.COAT_IOR: (1.0, 1.5), cl.COAT_TINT: (0.0, 1.0), cl.SHEEN_WEIGHT: (0.0, 1.0),
           cl.SHEEN_ROUGHNESS: (0.0, 0.5), cl.SHEEN_TINT: (0.0, 1.0),
           cl.ANISOTROPIC: (0.0, 1.0), cl.DIFFUSE_ROUGHNESS: (0.0, 0.5)}
_MAX_COMBINATIONS = 256


def program_lobe_masks(tab: closure.ClosureTable, programs) -> dict[str, np.ndarray]:
    """``closure.lobe_masks`` of ``tab`` with each programmed material's masks the union
    over what its program can produce, not its constant rows (whose programmed slots hold
    a socket's hidden default, e.g. a black Base Color under a texture): every
    combination of ``_PROBES`` values in the slots its TARGET_CLOSURE outputs write
    (colours as one; more than 256 combinations: all low, all high, and each slot high
    with the others low), the rows' constant weights kept (a TARGET_WEIGHT factor only
    scales a weight down). programs: one ShaderProgram or None per material. Returns
    (M,) bool arrays keyed by ``closure.LOBE_MASKS``."""
    out = closure.lobe_masks(tab)
    for m, prog in enumerate(programs or ()):
        if prog is None:
            continue
        f = int(tab.first[m])
        groups = {}  # (closure, first slot of the group) -> slots written
        for _, target, c, slot in prog.outputs.tolist():
            if target != pg.TARGET_CLOSURE:
                continue
            for start, (lo, _) in _PROBES.items():
                width = 3 if start in (cl.COLOR, cl.SPECULAR_TINT, cl.COAT_TINT,
                                       cl.SHEEN_TINT) else 1
                if start <= slot < start + width:
                    groups.setdefault((c, start), set()).add(slot)
        if not groups:
            continue
        keys = sorted(groups)
        if 2 ** len(keys) <= _MAX_COMBINATIONS:
            picks = [[(b >> i) & 1 for i in range(len(keys))] for b in range(2 ** len(keys))]
        else:
            picks = [[0] * len(keys), [1] * len(keys)] + [
                [int(i == j) for i in range(len(keys))] for j in range(len(keys))]
        for pick in picks:
            params = np.array(tab.params, copy=True)
            for (c, start), high in zip(keys, pick):
                for slot in groups[(c, start)]:
                    params[f + c, slot] = _PROBES[start][high]
            probe = tab._replace(params=params)
            for key, present in zip(closure.LOBE_MASKS, closure.lobe_presence(probe, m)):
                out[key][m] |= present
    return out


def prepare(scene: Scene, threads: int = 0, seed: int = 0) -> PreparedScene:
    """Build the PreparedScene of ``scene`` with ``threads`` workers (0 = every core);
    ``seed``: the render seed, which the media's ratio-tracking walks follow
    (``regions.Medium.seed``)."""
    mesh = scene.mesh
    workers = use_threads(threads)
    mats = bsdf.material_table(scene.materials)
    closures = closure.table(scene.materials)
    lobes = program_lobe_masks(closures, scene.materials.programs)
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
    hit_shader = HitShader(scene, closures, tri_vertices, tri_normals, tri_material,
                           geometry.scene_extent(lo, hi))
    emissive = EmissiveTriangles.from_mesh(mesh, scene.materials,
                                           hit_shader.textured_emitters())
    texels = SurfaceTextures(scene, np.ones_like(mats["diffuse"]))
    surfaces = SurfaceTextures(scene, mats["diffuse"])
    if np.any(hit_shader.alpha_programmed):
        for table in (texels, surfaces):
            table.use_program_alpha(hit_shader.alpha_programmed, hit_shader.alpha_at,
                                    light_path.shadow, light_path.with_length)
    emissive_index = np.full(mesh.triangle_count, -1, np.int32)
    emissive_index[emissive.triangle] = np.arange(emissive.count, dtype=np.int32)
    return PreparedScene(
        scene=scene, threads=workers, accel=Accelerator(tri_vertices, threads=workers),
        tri_vertices=tri_vertices, tri_normals=tri_normals,
        tri_material=tri_material, materials=mats, closures=closures,
        texels=texels,
        emissive_index=emissive_index, has_diffuse=has_diffuse,
        nondelta=has_diffuse | lobes["rough"], has_delta=lobes["delta"],
        sampled_only=lobes["rough"] & ~has_diffuse,
        glossy_on_diffuse=lobes["rough"] & has_diffuse,
        specular_material=specular_material, light_set=light_set,
        light_shows=np.any(light_set.radiance > 0, axis=1),
        emissive=emissive,
        world=np.asarray(scene.world.radiance, np.float64).reshape(3),
        surfaces=surfaces,
        extent=geometry.scene_extent(lo, hi), centre=centre,
        radius=radius * 1.01 if radius > 0 else 0.0,
        objects=object_spheres(tri_vertices, mesh.object_index, n_obj),
        specular_objects=specular_objects,
        diffuse_area=diffuse_area(tri_vertices, tri_material, has_diffuse),
        hit_shader=hit_shader, lobes=lobes,
        medium=regions.renderable(scene.media, geometry.scene_extent(lo, hi), workers,
                                  density_fields(scene, hit_shader), seed=seed))

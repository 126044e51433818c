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
  prepared scene is a context manager).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lights.light_set import EmissiveTriangles, LightSet
from .materials import bsdf, closure
from .materials.textures import SurfaceTextures
from .scene import geometry
from .scene.accel import Accelerator, use_threads
from .scene.bounds import Targets, bounding_sphere, object_spheres
from .scene.contract import Scene


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

    def close(self) -> None:
        """Release the Embree scene (idempotent)."""
        self.accel.close()

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
    lo, hi = scene.bounds()
    if mesh.vertices.size:
        glo = mesh.vertices.min(axis=0).astype(np.float64)
        ghi = mesh.vertices.max(axis=0).astype(np.float64)
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
    return PreparedScene(
        scene=scene, threads=workers, accel=Accelerator(tri_vertices, threads=workers),
        tri_vertices=tri_vertices, tri_normals=np.ascontiguousarray(mesh.normals, np.float32),
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
        diffuse_area=diffuse_area(tri_vertices, tri_material, has_diffuse))

"""The scene contract between Blender (or any other front end) and the renderer.

Everything is plain numpy: the exporter in ``photon_engine/export.py`` fills these
dataclasses from Blender's depsgraph, and the core tests build them by hand.

Conventions (the same as Blender's):
- World space is right-handed, Z up, lengths in metres.
- The camera looks along its local -Z with local +Y up (Blender's camera object).
- Light units match Cycles (see README, "Units"): point/spot/area ``power`` in watts,
  sun ``strength`` in W/m^2, emission and background as radiance in W/(m^2 sr).
- Images are (height, width, 3) float32 with row 0 at the TOP of the picture.

``Scene.validate()`` checks shapes, dtypes, finiteness (and magnitudes up to
MAX_MAGNITUDE) and ranges and raises
``SceneError`` naming the offending field and, where known, the object or material.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import closures
from .checks import MAX_MAGNITUDE, SceneError, check_array, label
from .images import ProgramImages
from .media import Media


# Light kinds, stored in Lights.kind (int32). Explicit values: they cross the boundary.
LIGHT_POINT = 0
LIGHT_SPOT = 1
LIGHT_SUN = 2
LIGHT_AREA = 3
LIGHT_KIND_NAMES = {LIGHT_POINT: "POINT", LIGHT_SPOT: "SPOT", LIGHT_SUN: "SUN", LIGHT_AREA: "AREA"}

# Area light shapes, stored in Lights.shape (int32). Square/rectangle and disk/ellipse
# differ only in whether size_y is tied to size_x, which the exporter resolves.
AREA_RECTANGLE = 0
AREA_ELLIPSE = 1

MIN_ABBE = 5.0
"""The smallest Abbe number V_d a dispersive material may have (0 = off). The most
dispersive transparent solids known are near 10 (rutile 9.8); below 5 the Cauchy fit's
IOR runs far outside any glass over 380-780 nm."""

CAMERA_PERSPECTIVE = 0
CAMERA_ORTHOGRAPHIC = 1


@dataclass(frozen=True)
class Mesh:
    """All renderable triangles of the scene, in world space.

    vertices: (V, 3) float32, metres.
    triangles: (T, 3) int32, indices into ``vertices``.
    normals: (T, 3, 3) float32, per-corner shading normals (unit length; smooth or flat
        as Blender computed them).
    uvs: (T, 3, 2) float32, per-corner texture coordinates (zeros where a mesh has none).
    material_index: (T,) int32, index into ``Materials``.
    object_index: (T,) int32, index into ``object_names`` (for error messages and debug).
    object_names: tuple of str, one per exported object instance.

    Optional, what shader programs read per object (None: identity transforms, texture
    space = the render frame's unit box, no origin shift):
    object_to_world: (O, 4, 4) float64, each object instance's world matrix (Blender's
        ``matrix_world``, true world coordinates, not the render frame).
    object_texspace: (O, 2, 3) float64, the mesh's texture space (Blender's
        ``texspace_location``, ``texspace_size``) in object space: Generated =
        (object position - location) / (2 size) + 0.5.
    origin: (3,) float64 metres, the render frame's origin in world coordinates
        (vertices = world positions - origin): programs read world positions.
    object_info: (O, 5) or (O, 6) float32, Object Info per object instance: the object's
        colour (RGB, Blender's ``Object.color``), Random in [0, 1] (Cycles' random_number
        of the instance's ``random_id``), Object Index (``pass_index``) and, in the sixth
        column, the colour's alpha (Object Info Alpha; 1 without it). None: zeros.
    attributes: (T, 3, A, 4) float32, the mesh attributes shader programs read (Attribute
        and Color Attribute nodes), RGBA at each triangle corner (interpolated per hit
        like the UVs), in the order of ``attribute_names`` (A str; "" is the render colour
        attribute). None: no attribute.
    tangents: (T, 3, G, 4) float32, the MikkTSpace tangents shader programs read (Normal
        Map in tangent space), per triangle corner and tangent map: the tangent (x, y, z)
        in world space (the object's linear transform applied, not normalised) and the
        bitangent sign w in {-1, 1} (0: the mesh has no such UV map; the Normal Map then
        leaves the normal as it is), in the order of ``tangent_maps`` (G UV map names;
        "" is the active render UV map). Interpolated per hit like the UVs, as Cycles
        interpolates its tangent attributes. None: no tangent map.
    uv_maps: (T, 3, U, 2) float32, the UV maps shader programs name (UV Map node, Normal
        Map), per triangle corner, in the order of ``uv_map_names`` (U str); a mesh
        without a map of that name has (0, 0) there, as Cycles. ``ShadingInputs.uv`` is
        [``uvs``, ``uv_maps``...]: a program's UV index 0 is the active render map, index
        1 + j the map ``uv_map_names[j]``. None: no named map.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    material_index: np.ndarray
    object_index: np.ndarray
    object_names: tuple = ()
    object_to_world: np.ndarray | None = None
    object_texspace: np.ndarray | None = None
    origin: np.ndarray | None = None
    object_info: np.ndarray | None = None
    attributes: np.ndarray | None = None
    attribute_names: tuple = ()
    tangents: np.ndarray | None = None
    tangent_maps: tuple = ()
    uv_maps: np.ndarray | None = None
    uv_map_names: tuple = ()

    @property
    def triangle_count(self) -> int:
        return int(self.triangles.shape[0])

    def triangle_vertices(self) -> np.ndarray:
        """(T, 3, 3) float32: the three corners of every triangle, metres."""
        return self.vertices[self.triangles]

    @staticmethod
    def empty() -> "Mesh":
        return Mesh(
            vertices=np.zeros((0, 3), np.float32),
            triangles=np.zeros((0, 3), np.int32),
            normals=np.zeros((0, 3, 3), np.float32),
            uvs=np.zeros((0, 3, 2), np.float32),
            material_index=np.zeros(0, np.int32),
            object_index=np.zeros(0, np.int32),
            object_names=(),
        )


@dataclass(frozen=True)
class Materials:
    """Materials as a mixture of lobes, one row per material (struct of arrays).

    Every BSDF the exporter understands maps onto these lobes:
    diffuse: (M, 3) float32, Lambert albedo in [0, 1].
    specular: (M, 3) float32 in [0, 1], tint of the reflection lobe (metal / Glossy BSDF); the
        lobe is a perfect mirror when roughness is 0, GGX otherwise.
    transmission: (M, 3) float32 in [0, 1], tint of the dielectric lobe (Glass BSDF, Principled
        transmission): Fresnel-weighted reflection and refraction with ``ior``.
    roughness: (M,) float32 in [0, 1], Blender's roughness (alpha = roughness^2).
    ior: (M,) float32 > 0, index of refraction of the dielectric lobe.
    emission: (M, 3) float32, emitted radiance, W/(m^2 sr) (colour x strength).
    names: tuple of str, material names for messages.

    Optional (None = no texture / opaque for every material, so older callers still work):
    diffuse_texture: (M,) int32, index into ``Scene.textures`` whose texel colour (linear
        RGB, at the hit's interpolated UV) MULTIPLIES the diffuse lobe; -1 = none. An
        Image Texture feeding Base Color replaces the base colour, so the exporter stores
        ``diffuse`` with the base colour factored out (the lobe's weight, e.g.
        (1 - metallic)(1 - transmission)) and the core multiplies by the texel.
    alpha: (M,) float32 in [0, 1], opacity (Principled Alpha): a hit is the surface with
        probability alpha and a straight pass-through (no refraction, no Fresnel, no
        bounce) with probability 1 - alpha.
    alpha_texture: (M,) int32, texture whose texel ALPHA channel multiplies ``alpha``; -1 = none.
    dispersion: (M,) float32, the Abbe number V_d of the material's transmission lobes
        (Glass, Refraction, Principled transmission; docs/dispersion.md): 0 = no dispersion,
        else >= ``MIN_ABBE``; their IOR is then the d-line (587.6 nm) value of a Cauchy fit.

    The closure table (core/scene/closures.py; None = derived from the lobes above by
    ``closure_table()``): material m is the weighted sum of closures
    [closure_first[m], closure_first[m] + closure_count[m]).
    closure_kind: (C,) int32, ``closures.CLOSURE_*``.
    closure_weight: (C, 3) float32 >= 0, the Mix / Add weight of each closure.
    closure_params: (C, closures.PARAM_COUNT) float32, the node's inputs by slot.
    closure_texture: (C,) int32, texture whose texel colour MULTIPLIES the COLOR slot (the
        exporter stores COLOR with the image factored out, usually 1); -1 = none.
    closure_first, closure_count: (M,) int32.

    programs: None, or a tuple of M ``core.shading.program.ShaderProgram`` or None: the
    material's compiled node graph (docs/shading.md), whose outputs replace closure
    parameters per hit (TARGET_CLOSURE: closure index within the material, slot) and
    scale closure weights per hit (TARGET_WEIGHT: a linked Mix Shader factor). A
    material without links has None and costs nothing.
    pass_index: (M,) float32, each material's pass index (Blender's ``pass_index``: Object
        Info's Material Index); None: 0.
    """

    diffuse: np.ndarray
    specular: np.ndarray
    transmission: np.ndarray
    roughness: np.ndarray
    ior: np.ndarray
    emission: np.ndarray
    names: tuple = ()
    diffuse_texture: np.ndarray | None = None
    alpha: np.ndarray | None = None
    alpha_texture: np.ndarray | None = None
    closure_kind: np.ndarray | None = None
    closure_weight: np.ndarray | None = None
    closure_params: np.ndarray | None = None
    closure_texture: np.ndarray | None = None
    closure_first: np.ndarray | None = None
    closure_count: np.ndarray | None = None
    programs: tuple | None = None
    dispersion: np.ndarray | None = None
    pass_index: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.diffuse.shape[0])

    def closure_table(self) -> dict[str, np.ndarray]:
        """The closure table (keys ``kind, weight, params, texture, first, count``, dtypes as
        documented above): the stored one, or, when ``closure_kind`` is None, the lobes as
        closures: Diffuse (weight = diffuse, texture = diffuse_texture), Glossy (weight =
        specular, GGX, the roughness) and smooth Glass (weight = transmission, the IOR), each
        with COLOR 1 and present only where its weight is non-zero."""
        if self.closure_kind is not None:
            return {"kind": np.asarray(self.closure_kind, np.int32),
                    "weight": np.asarray(self.closure_weight, np.float32).reshape(-1, 3),
                    "params": np.asarray(self.closure_params, np.float32)
                    .reshape(-1, closures.PARAM_COUNT),
                    "texture": np.asarray(self.closure_texture, np.int32),
                    "first": np.asarray(self.closure_first, np.int32),
                    "count": np.asarray(self.closure_count, np.int32)}
        kind, weight, params, texture, first, count = [], [], [], [], [], []
        tex = self.diffuse_texture_index()
        for m in range(self.count):
            first.append(len(kind))
            lobes = (
                (closures.CLOSURE_DIFFUSE, self.diffuse[m], {"roughness": 0.0}, int(tex[m])),
                (closures.CLOSURE_GLOSSY, self.specular[m],
                 {"roughness": float(self.roughness[m]),
                  "distribution": closures.DISTRIBUTION_GGX}, -1),
                (closures.CLOSURE_GLASS, self.transmission[m],
                 {"roughness": 0.0, "ior": float(self.ior[m]),
                  "distribution": closures.DISTRIBUTION_GGX}, -1),
            )
            for k, w, values, t in lobes:
                if np.any(np.asarray(w) > 0):
                    kind.append(k)
                    weight.append(np.asarray(w, np.float32))
                    params.append(closures.params(color=1.0, **values))
                    texture.append(t)
            count.append(len(kind) - first[-1])
        return {"kind": np.array(kind, np.int32),
                "weight": np.array(weight, np.float32).reshape(-1, 3),
                "params": np.array(params, np.float32).reshape(-1, closures.PARAM_COUNT),
                "texture": np.array(texture, np.int32),
                "first": np.array(first, np.int32), "count": np.array(count, np.int32)}

    def diffuse_texture_index(self) -> np.ndarray:
        """(M,) int32 texture of the diffuse lobe, -1 where none."""
        if self.diffuse_texture is None:
            return np.full(self.count, -1, np.int32)
        return np.asarray(self.diffuse_texture, np.int32)

    def alpha_texture_index(self) -> np.ndarray:
        """(M,) int32 texture whose alpha multiplies the opacity, -1 where none."""
        if self.alpha_texture is None:
            return np.full(self.count, -1, np.int32)
        return np.asarray(self.alpha_texture, np.int32)

    def abbe(self) -> np.ndarray:
        """(M,) float64 Abbe numbers (0 = no dispersion; all 0 where ``dispersion`` is None)."""
        if self.dispersion is None:
            return np.zeros(self.count)
        return np.asarray(self.dispersion, np.float64)

    def opacity(self) -> np.ndarray:
        """(M,) float64 constant opacity (1 where ``alpha`` is None)."""
        if self.alpha is None:
            return np.ones(self.count)
        return np.asarray(self.alpha, np.float64)

    @staticmethod
    def from_list(rows: list[dict]) -> "Materials":
        """Build from dicts with any of the keys above (missing lobes are zero).

        Defaults: ior 1.5, roughness 0, name "Material.<i>", diffuse_texture -1,
        alpha 1, alpha_texture -1, dispersion 0 (the optional fields are None when no row
        sets them).

        A row may instead give ``closures``: a list of dicts with ``kind`` (CLOSURE_*),
        ``weight`` (3,) (default 1), ``params`` (a (PARAM_COUNT,) row or a dict for
        ``closures.params``) and ``texture`` (default -1). When any row does, the closure
        table is stored, rows without ``closures`` contributing their lobes as closures.
        A row's ``program`` (a ShaderProgram, default None) is its entry of ``programs``
        (None when no row has one).
        """
        m = len(rows)

        def col(key, width, default):
            out = np.full((m, width) if width else (m,), default, np.float32)
            for i, r in enumerate(rows):
                if key in r:
                    out[i] = r[key]
            return out

        lobes = Materials(
            diffuse=col("diffuse", 3, 0.0),
            specular=col("specular", 3, 0.0),
            transmission=col("transmission", 3, 0.0),
            roughness=col("roughness", 0, 0.0),
            ior=col("ior", 0, 1.5),
            emission=col("emission", 3, 0.0),
            names=tuple(r.get("name", f"Material.{i}") for i, r in enumerate(rows)),
            diffuse_texture=(np.array([r.get("diffuse_texture", -1) for r in rows], np.int32)
                             .reshape(m) if any("diffuse_texture" in r for r in rows) else None),
            alpha=(col("alpha", 0, 1.0) if any("alpha" in r for r in rows) else None),
            alpha_texture=(np.array([r.get("alpha_texture", -1) for r in rows], np.int32)
                           .reshape(m) if any("alpha_texture" in r for r in rows) else None),
            dispersion=(col("dispersion", 0, 0.0) if any("dispersion" in r for r in rows)
                        else None),
            pass_index=(col("pass_index", 0, 0.0) if any("pass_index" in r for r in rows)
                        else None),
        )
        if any(r.get("program") is not None for r in rows):
            lobes = replace(lobes, programs=tuple(r.get("program") for r in rows))
        if not any("closures" in r for r in rows):
            return lobes
        derived = lobes.closure_table()
        kind, weight, params, texture, first, count = [], [], [], [], [], []
        for i, r in enumerate(rows):
            first.append(len(kind))
            if "closures" in r:
                for c in r["closures"]:
                    p = c.get("params", {})
                    kind.append(int(c["kind"]))
                    weight.append(np.broadcast_to(np.asarray(c.get("weight", 1.0), np.float32), (3,)))
                    params.append(closures.params(**p) if isinstance(p, dict)
                                  else np.asarray(p, np.float32))
                    texture.append(int(c.get("texture", -1)))
            else:
                lo = derived["first"][i]
                for j in range(lo, lo + derived["count"][i]):
                    kind.append(derived["kind"][j])
                    weight.append(derived["weight"][j])
                    params.append(derived["params"][j])
                    texture.append(derived["texture"][j])
            count.append(len(kind) - first[-1])
        return replace(
            lobes, closure_kind=np.array(kind, np.int32),
            closure_weight=np.array(weight, np.float32).reshape(-1, 3),
            closure_params=np.array(params, np.float32).reshape(-1, closures.PARAM_COUNT),
            closure_texture=np.array(texture, np.int32),
            closure_first=np.array(first, np.int32), closure_count=np.array(count, np.int32))


@dataclass(frozen=True)
class Textures:
    """All image textures of the scene, packed into one pixel array (struct of arrays).

    pixels: (P, 4) float32, linear RGBA (colour spaces already decoded by the exporter),
        every image one after the other, each row-major with row 0 at the BOTTOM of the
        image (Blender's ``Image.pixels`` order, so UV (0, 0) is pixel (0, 0)).
    offset: (K,) int64, first row of ``pixels`` of texture k.
    width, height: (K,) int32 >= 1, texels; texture k is pixels[offset[k]:offset[k] + w * h].
    names: tuple of str, image names for messages.
    Lookup (core/materials/textures.py): bilinear, pixel centres at ((i + 0.5) / w, (j + 0.5) / h),
    repeat wrapping (Blender's default "Repeat" extension).
    """

    pixels: np.ndarray
    offset: np.ndarray
    width: np.ndarray
    height: np.ndarray
    names: tuple = ()

    @property
    def count(self) -> int:
        return int(self.offset.shape[0])

    @staticmethod
    def empty() -> "Textures":
        return Textures(np.zeros((0, 4), np.float32), np.zeros(0, np.int64),
                        np.zeros(0, np.int32), np.zeros(0, np.int32), ())

    @staticmethod
    def from_images(images, names=()) -> "Textures":
        """Pack (H, W, 3 or 4) linear images (row 0 at the bottom) into one Textures;
        a missing alpha channel is 1."""
        parts, offset, width, height = [], [], [], []
        start = 0
        for img in images:
            a = np.asarray(img, np.float32)
            if a.ndim != 3 or a.shape[2] not in (3, 4):
                raise SceneError(f"texture image must be (H, W, 3|4), got {a.shape}")
            h, w = a.shape[:2]
            rgba = np.ones((h, w, 4), np.float32)
            rgba[..., :a.shape[2]] = a
            parts.append(rgba.reshape(-1, 4))
            offset.append(start)
            width.append(w)
            height.append(h)
            start += h * w
        pixels = np.concatenate(parts) if parts else np.zeros((0, 4), np.float32)
        names = tuple(names) or tuple(f"Texture.{i}" for i in range(len(offset)))
        return Textures(np.ascontiguousarray(pixels), np.array(offset, np.int64),
                        np.array(width, np.int32), np.array(height, np.int32), names)


@dataclass(frozen=True)
class Lights:
    """Analytic lights, one row per light (struct of arrays).

    kind: (L,) int32, LIGHT_POINT / LIGHT_SPOT / LIGHT_SUN / LIGHT_AREA.
    to_world: (L, 4, 4) float64, the light object's world matrix without scale
        (a light emits along its local -Z; area lights lie in their local XY plane).
    color: (L, 3) float32, linear RGB colour.
    power: (L,) float32. Watts for point, spot and area; W/m^2 (strength) for sun.
    radius: (L,) float32, metres; point and spot: the emitting sphere's radius (0 = point).
    angle: (L,) float32, radians; sun: the full angular diameter of the sun disc.
    spot_size: (L,) float32, radians; spot: full cone angle.
    spot_blend: (L,) float32 in [0, 1]; spot: smoothstep softness of the cone edge.
    shape: (L,) int32, AREA_RECTANGLE or AREA_ELLIPSE.
    size: (L, 2) float32, metres; area: full extents along local X and Y (with the
        object's scale already applied).
    visible_to_camera: (L,) bool, the light's surface is seen by camera rays.
    cast_shadow: (L,) bool.
    names: tuple of str.

    Optional (None means Blender's default for every light, so older callers still work):
    soft_falloff: (L,) bool, point/spot: Blender's "Soft Falloff" (default True). Cycles
        then models a radius > 0 as a disk facing the shading point instead of a sphere
        (``is_sphere = !use_soft_falloff``); far away both act as the point light.
    visible_to_diffuse, visible_to_glossy, visible_to_transmission: (L,) bool, the
        light's ray-visibility flags (default True): whether it lights diffuse / glossy
        lobes and is seen in mirror reflections / through refraction.
    """

    kind: np.ndarray
    to_world: np.ndarray
    color: np.ndarray
    power: np.ndarray
    radius: np.ndarray
    angle: np.ndarray
    spot_size: np.ndarray
    spot_blend: np.ndarray
    shape: np.ndarray
    size: np.ndarray
    visible_to_camera: np.ndarray
    cast_shadow: np.ndarray
    names: tuple = ()
    soft_falloff: np.ndarray | None = None
    visible_to_diffuse: np.ndarray | None = None
    visible_to_glossy: np.ndarray | None = None
    visible_to_transmission: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.kind.shape[0])

    def flag_mask(self, name: str) -> np.ndarray:
        """(L,) bool of an optional flag field, True for every light when it is None."""
        a = getattr(self, name)
        return np.ones(self.count, bool) if a is None else np.asarray(a, bool)

    def soft_falloff_mask(self) -> np.ndarray:
        return self.flag_mask("soft_falloff")

    @staticmethod
    def from_list(rows: list[dict]) -> "Lights":
        """Build from dicts; ``kind`` and ``to_world`` (or ``position``) are required.

        Defaults: colour white, power 0, radius 0, angle 0, spot_size pi/4, spot_blend 0.15,
        shape rectangle, size 1x1, visible_to_camera False, cast_shadow True,
        soft_falloff True, visible_to_diffuse / _glossy / _transmission True.
        A ``position`` (3,) without ``to_world`` gives a translation-only matrix, pointing
        down (-Z), which is Blender's default orientation.
        """
        n = len(rows)
        kind = np.array([r["kind"] for r in rows], np.int32).reshape(n)
        to_world = np.tile(np.eye(4), (n, 1, 1))
        for i, r in enumerate(rows):
            if "to_world" in r:
                to_world[i] = r["to_world"]
            elif "position" in r:
                to_world[i, :3, 3] = r["position"]

        def col(key, width, default, dtype=np.float32):
            out = np.full((n, width) if width else (n,), default, dtype)
            for i, r in enumerate(rows):
                if key in r:
                    out[i] = r[key]
            return out

        return Lights(
            kind=kind,
            to_world=to_world,
            color=col("color", 3, 1.0),
            power=col("power", 0, 0.0),
            radius=col("radius", 0, 0.0),
            angle=col("angle", 0, 0.0),
            spot_size=col("spot_size", 0, np.pi / 4),
            spot_blend=col("spot_blend", 0, 0.15),
            shape=col("shape", 0, AREA_RECTANGLE, np.int32),
            size=col("size", 2, 1.0),
            visible_to_camera=col("visible_to_camera", 0, False, bool),
            cast_shadow=col("cast_shadow", 0, True, bool),
            names=tuple(r.get("name", f"Light.{i}") for i, r in enumerate(rows)),
            soft_falloff=col("soft_falloff", 0, True, bool),
            visible_to_diffuse=col("visible_to_diffuse", 0, True, bool),
            visible_to_glossy=col("visible_to_glossy", 0, True, bool),
            visible_to_transmission=col("visible_to_transmission", 0, True, bool),
        )

    @staticmethod
    def empty() -> "Lights":
        return Lights.from_list([])


@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera.

    to_world: (4, 4) float64, camera-to-world matrix without scale (looks along local -Z).
    kind: CAMERA_PERSPECTIVE or CAMERA_ORTHOGRAPHIC.
    width, height: int, the output resolution in pixels (percentage already applied).
    film_size: (2,) float64, the image rectangle's full extents (x, y): for perspective
        on the plane at distance 1 in front of the camera (so tan of the half field of
        view is film_size / 2); for orthographic in metres.
    film_shift: (2,) float64, offset of the rectangle's centre in the same units
        (Blender's lens shift, already converted).
    clip_start, clip_end: float, metres: depths of the near and far clipping planes along
        the view axis (-Z). Cycles clips perspective rays at these planes too, so a ray at
        angle theta from the axis runs from clip_start / cos(theta) to clip_end / cos(theta)
        (kernel/camera/camera.h: ``nearclip * z_inv``).
    aperture_radius: float, metres: the thin lens's radius for depth of field (Cycles:
        focal length / (2 f-stop) for perspective cameras, 1 m / (2 f-stop) for
        orthographic ones); 0 is a pinhole (or parallel rays).
    focus_distance: float, metres along the view axis to the plane in focus.
    aperture_blades: int, 0 for a round aperture, else the polygon's corner count (>= 3).
    aperture_rotation: float, radians: the polygon's rotation.
    aperture_ratio: float: anamorphic distortion; the aperture's x extent is divided by it.
    region: None for the whole frame, or (x0, y0, x1, y1) int pixels of the frame with row 0
        at the TOP, x1 and y1 exclusive: only those pixels are rendered (Blender's Render
        Region), each exactly as in a render of the whole frame (camera.region_pixels).
    """

    to_world: np.ndarray
    width: int
    height: int
    film_size: np.ndarray
    film_shift: np.ndarray = field(default_factory=lambda: np.zeros(2))
    kind: int = CAMERA_PERSPECTIVE
    clip_start: float = 1e-3
    clip_end: float = 1e30
    name: str = "Camera"
    aperture_radius: float = 0.0
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    aperture_ratio: float = 1.0
    region: tuple | None = None


@dataclass(frozen=True)
class World:
    """Uniform environment: background radiance (3,) float32, W/(m^2 sr).

    visible_to_camera: the background is seen by camera rays (Blender's world
    ray-visibility "Camera" flag); it lights the scene either way.
    """

    radiance: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    visible_to_camera: bool = True


@dataclass(frozen=True)
class Scene:
    mesh: Mesh
    materials: Materials
    lights: Lights
    camera: Camera
    world: World = field(default_factory=World)
    textures: Textures = field(default_factory=Textures.empty)
    media: Media = field(default_factory=Media.empty)
    """The participating media (core/scene/media.py); empty: none, every ray in vacuum."""
    program_images: ProgramImages = field(default_factory=ProgramImages.empty)
    """The images the shader programs' Image Texture instructions sample
    (core/scene/images.py); empty: none."""

    def validate(self) -> "Scene":
        """Check every array; raise SceneError naming the field, object or material."""
        _validate_mesh(self.mesh, self.materials)
        _validate_textures(self.textures)
        _validate_materials(self.materials, self.textures.count)
        self.program_images.validate()
        if self.materials.programs is not None:
            _validate_program_images(self.materials, self.program_images.count)
        _validate_lights(self.lights)
        _validate_camera(self.camera)
        check_array("world.radiance", self.world.radiance, (3,), nonnegative=True)
        self.media.validate(len(self.mesh.object_names))
        if self.mesh.triangle_count:
            lo, hi = self.bounds()
            size = float(np.max(hi - lo))
            if size > 0 and not MIN_SCENE_SIZE <= size <= MAX_SCENE_SIZE:
                raise SceneError(
                    f"scene size {size:.3g} m (the bounding box of the geometry, lights and "
                    f"camera) is outside [{MIN_SCENE_SIZE:g}, {MAX_SCENE_SIZE:g}] m, the "
                    f"range float32 rendering holds; rescale the scene")
        return self

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) float64 (3,) of the geometry, the media's boundaries and the positional
        lights, metres.

        Falls back to the camera position when the scene has neither.
        """
        v = self.mesh.vertices
        pts = [np.stack([v.min(axis=0), v.max(axis=0)]).astype(np.float64) if v.size else v]
        local = self.lights.kind != LIGHT_SUN
        pts.append(self.lights.to_world[local, :3, 3])
        pts.append(self.camera.to_world[None, :3, 3])
        pts.append(self.media.boundary.reshape(-1, 3).astype(np.float64))
        allp = np.concatenate([p.reshape(-1, 3) for p in pts])
        return allp.min(axis=0), allp.max(axis=0)


MIN_SCENE_SIZE = 1e-6
MAX_SCENE_SIZE = 1e11
"""Scene sizes (largest side of Scene.bounds(), metres) the renderer holds. Measured on a
4.4 m box scaled: correct from 4.4e-7 to 4.4e12 m; at 4.4e-8 m the caustics come out 29 %
too bright, at 4.4e-12 m the radiance estimate finds k photons on one point, at 4.4e13 m
the image is black."""

class _TriangleObjects:
    """Object name of triangle i, looked up only when an error message needs it
    (a list over millions of triangles would cost seconds per render)."""

    def __init__(self, mesh: Mesh):
        self._mesh = mesh

    def __len__(self):
        return self._mesh.triangle_count

    def __getitem__(self, i):
        o = int(self._mesh.object_index[i])
        names = self._mesh.object_names
        return names[o] if 0 <= o < len(names) else None


def _validate_mesh(mesh: Mesh, materials: Materials) -> None:
    t = mesh.triangle_count
    check_array("mesh.vertices", mesh.vertices, (None, 3), dtype=np.float32)
    check_array("mesh.triangles", mesh.triangles, (None, 3), dtype=np.int32)
    check_array("mesh.material_index", mesh.material_index, (t,), dtype=np.int32)
    check_array("mesh.object_index", mesh.object_index, (t,), dtype=np.int32)
    tri_obj = _TriangleObjects(mesh)
    check_array("mesh.normals", mesh.normals, (t, 3, 3), dtype=np.float32, labels=tri_obj)
    check_array("mesh.uvs", mesh.uvs, (t, 3, 2), dtype=np.float32, labels=tri_obj)
    if t:
        v = mesh.vertices.shape[0]
        if mesh.triangles.min() < 0 or mesh.triangles.max() >= v:
            raise SceneError(f"mesh.triangles index out of range [0, {v}): "
                             f"{mesh.triangles.min()}..{mesh.triangles.max()}")
        if mesh.material_index.min() < 0 or mesh.material_index.max() >= materials.count:
            raise SceneError(f"mesh.material_index out of range [0, {materials.count}): "
                             f"{mesh.material_index.min()}..{mesh.material_index.max()}")
    n_obj = int(mesh.object_index.max()) + 1 if t else 0
    names = mesh.object_names if len(mesh.object_names) >= n_obj else None
    if mesh.object_to_world is not None:
        check_array("mesh.object_to_world", mesh.object_to_world, (None, 4, 4),
                     dtype=np.float64, labels=names)
    if mesh.object_texspace is not None:
        check_array("mesh.object_texspace", mesh.object_texspace, (None, 2, 3),
                     dtype=np.float64, labels=names)
    if mesh.attributes is not None:
        check_array("mesh.attributes", mesh.attributes,
                    (t, 3, len(mesh.attribute_names), 4), dtype=np.float32)
    if mesh.tangents is not None:
        check_array("mesh.tangents", mesh.tangents,
                    (t, 3, len(mesh.tangent_maps), 4), dtype=np.float32)
        sign = mesh.tangents[..., 3]
        if not np.all((sign == 0) | (sign == 1) | (sign == -1)):
            raise SceneError("mesh.tangents: the bitangent sign (last component) must be "
                             "-1, 1 or 0 (no tangent)")
    if mesh.uv_maps is not None:
        check_array("mesh.uv_maps", mesh.uv_maps, (t, 3, len(mesh.uv_map_names), 2),
                    dtype=np.float32)
    if mesh.object_info is not None:
        check_array("mesh.object_info", mesh.object_info, (None, None), dtype=np.float32,
                    labels=names)
        if mesh.object_info.shape[1] not in (5, 6):
            raise SceneError(f"mesh.object_info must have 5 or 6 columns, got "
                             f"{mesh.object_info.shape[1]}")
    for key in ("object_to_world", "object_texspace", "object_info"):
        a = getattr(mesh, key)
        if a is not None and a.shape[0] < n_obj:
            raise SceneError(f"mesh.{key} has {a.shape[0]} rows, fewer than the "
                             f"{n_obj} objects of mesh.object_index")
    if mesh.origin is not None:
        check_array("mesh.origin", mesh.origin, (3,), dtype=np.float64)


def _validate_textures(tx: Textures) -> None:
    k = tx.count
    names = tx.names if len(tx.names) == k else None
    check_array("textures.pixels", tx.pixels, (None, 4), dtype=np.float32, nonnegative=True)
    check_array("textures.offset", tx.offset, (k,), dtype=np.int64)
    check_array("textures.width", tx.width, (k,), dtype=np.int32)
    check_array("textures.height", tx.height, (k,), dtype=np.int32)
    for i in range(k):
        w, h, o = int(tx.width[i]), int(tx.height[i]), int(tx.offset[i])
        if w < 1 or h < 1:
            raise SceneError(f"textures.width/height{label(names, i)} must be >= 1, got {w}x{h}")
        if o < 0 or o + w * h > tx.pixels.shape[0]:
            raise SceneError(f"textures.offset{label(names, i)}: texels [{o}, {o + w * h}) "
                             f"outside textures.pixels (P = {tx.pixels.shape[0]})")


def _validate_materials(m: Materials, texture_count: int = 0) -> None:
    n = m.count
    names = m.names if len(m.names) == n else None
    for key in ("diffuse_texture", "alpha_texture"):
        a = getattr(m, key)
        if a is None:
            continue
        check_array(f"materials.{key}", a, (n,), dtype=np.int32, labels=names)
        if n and (a.min() < -1 or a.max() >= texture_count):
            i = int(np.argmax((a < -1) | (a >= texture_count)))
            raise SceneError(f"materials.{key}{label(names, i)} is {a[i]}, not -1 (none) or "
                             f"an index into the scene's {texture_count} textures")
    if m.closure_kind is not None:
        _validate_closures(m, texture_count, names)
    if m.programs is not None:
        _validate_programs(m, names)
    if m.alpha is not None:
        check_array("materials.alpha", m.alpha, (n,), dtype=np.float32, nonnegative=True,
                     labels=names, at_most=1.0)
    # Reflectances above 1 create energy (photon flux grows geometrically with the
    # bounces until it overflows); the exporter clamps them to 1 with a warning.
    for key in ("diffuse", "specular", "transmission"):
        check_array(f"materials.{key}", getattr(m, key), (n, 3), dtype=np.float32,
                     nonnegative=True, labels=names, at_most=1.0)
    check_array("materials.emission", m.emission, (n, 3), dtype=np.float32,
                 nonnegative=True, labels=names)
    check_array("materials.roughness", m.roughness, (n,), dtype=np.float32, nonnegative=True,
                 labels=names, at_most=1.0)
    check_array("materials.ior", m.ior, (n,), dtype=np.float32, labels=names)
    if n and np.any(m.ior <= 0):
        i = int(np.argmax(m.ior <= 0))
        raise SceneError(f"materials.ior{label(names, i)} must be > 0, got {m.ior[i]}")
    if m.pass_index is not None:
        check_array("materials.pass_index", m.pass_index, (n,), dtype=np.float32,
                    labels=names)
    if m.dispersion is not None:
        check_array("materials.dispersion", m.dispersion, (n,), dtype=np.float32,
                     labels=names)
        v = m.dispersion
        bad = ~((v == 0) | (v >= MIN_ABBE))
        if n and np.any(bad):
            i = int(np.argmax(bad))
            raise SceneError(f"materials.dispersion{label(names, i)}: Dispersion (Abbe number "
                             f"V_d) must be 0 (off) or >= {MIN_ABBE:g}, got {v[i]}")


def _validate_closures(m: Materials, texture_count: int, names) -> None:
    t = m.closure_table()
    c = t["kind"].shape[0]
    check_array("materials.closure_kind", m.closure_kind, (c,), dtype=np.int32)
    if c and not np.all(np.isin(t["kind"], list(closures.CLOSURE_KIND_NAMES))):
        j = int(np.argmax(~np.isin(t["kind"], list(closures.CLOSURE_KIND_NAMES))))
        raise SceneError(f"materials.closure_kind[{j}] is {t['kind'][j]}, not one of "
                         f"{closures.CLOSURE_KIND_NAMES}")
    check_array("materials.closure_weight", m.closure_weight, (c, 3), dtype=np.float32,
                 nonnegative=True)
    check_array("materials.closure_params", m.closure_params, (c, closures.PARAM_COUNT),
                 dtype=np.float32)
    check_array("materials.closure_texture", m.closure_texture, (c,), dtype=np.int32)
    if c and (t["texture"].min() < -1 or t["texture"].max() >= texture_count):
        j = int(np.argmax((t["texture"] < -1) | (t["texture"] >= texture_count)))
        raise SceneError(f"materials.closure_texture[{j}] is {t['texture'][j]}, not -1 (none) "
                         f"or an index into the scene's {texture_count} textures")
    for key in ("closure_first", "closure_count"):
        check_array(f"materials.{key}", getattr(m, key), (m.count,), dtype=np.int32,
                     labels=names)
    end = t["first"].astype(np.int64) + t["count"]
    if m.count and (t["first"].min() < 0 or t["count"].min() < 0 or end.max() > c):
        i = int(np.argmax((t["first"] < 0) | (t["count"] < 0) | (end > c)))
        raise SceneError(f"materials.closure_first/count{label(names, i)}: closures "
                         f"[{t['first'][i]}, {end[i]}) outside the table of {c}")


def _validate_programs(m: Materials, names) -> None:
    """Each program valid (its own validate()) and writing only closures its material has."""
    if len(m.programs) != m.count:
        raise SceneError(f"materials.programs has {len(m.programs)} entries, not one per "
                         f"material ({m.count})")
    count = m.closure_table()["count"]
    for i, prog in enumerate(m.programs):
        if prog is None:
            continue
        try:
            prog.validate()
        except ValueError as exc:
            raise SceneError(f"materials.programs{label(names, i)}: {exc}") from None
        for row in np.asarray(prog.outputs).reshape(-1, 4):
            # row[1] 0 / 5: core.shading.program.TARGET_CLOSURE / TARGET_WEIGHT (rank 2,
            # not importable here)
            if int(row[1]) in (0, 5) and not 0 <= int(row[2]) < int(count[i]):
                raise SceneError(f"materials.programs{label(names, i)}: an output writes "
                                 f"closure {int(row[2])}, but the material has "
                                 f"{int(count[i])} closures")


def _validate_program_images(m: Materials, count: int) -> None:
    """Every Image Texture instruction samples a slot of ``Scene.program_images`` (or -1,
    the missing image)."""
    names = m.names if len(m.names) == m.count else None
    for i, prog in enumerate(m.programs):
        if prog is None:
            continue
        ins = np.asarray(prog.instructions).reshape(-1, prog.instructions.shape[-1])
        # opcode 30: core.shading.program.OP_IMAGE (rank 2, not importable here)
        slots = ins[ins[:, 0] == 30, 1]
        if slots.size and (slots.max() >= count or slots.min() < -1):
            raise SceneError(f"materials.programs{label(names, i)}: an Image Texture samples "
                             f"image slot {int(slots.max())}, but program_images has {count}")


def _validate_lights(li: Lights) -> None:
    n = li.count
    names = li.names if len(li.names) == n else None
    check_array("lights.kind", li.kind, (n,), dtype=np.int32)
    if n and not np.all(np.isin(li.kind, list(LIGHT_KIND_NAMES))):
        i = int(np.argmax(~np.isin(li.kind, list(LIGHT_KIND_NAMES))))
        raise SceneError(f"lights.kind{label(names, i)} is {li.kind[i]}, not one of {LIGHT_KIND_NAMES}")
    check_array("lights.to_world", li.to_world, (n, 4, 4), labels=names)
    check_array("lights.color", li.color, (n, 3), nonnegative=True, labels=names)
    for key in ("power", "radius", "angle", "spot_size"):
        check_array(f"lights.{key}", getattr(li, key), (n,), nonnegative=True, labels=names)
    check_array("lights.spot_blend", li.spot_blend, (n,), nonnegative=True, labels=names,
                 at_most=1.0)
    check_array("lights.shape", li.shape, (n,), dtype=np.int32)
    check_array("lights.size", li.size, (n, 2), nonnegative=True, labels=names)
    check_array("lights.visible_to_camera", li.visible_to_camera, (n,), dtype=bool)
    check_array("lights.cast_shadow", li.cast_shadow, (n,), dtype=bool)
    for key in ("soft_falloff", "visible_to_diffuse", "visible_to_glossy", "visible_to_transmission"):
        if getattr(li, key) is not None:
            check_array(f"lights.{key}", getattr(li, key), (n,), dtype=bool)


def _validate_camera(c: Camera) -> None:
    check_array("camera.to_world", c.to_world, (4, 4), labels=[c.name] * 4)
    check_array("camera.film_size", np.asarray(c.film_size, np.float64), (2,))
    check_array("camera.film_shift", np.asarray(c.film_shift, np.float64), (2,))
    if int(c.width) < 1 or int(c.height) < 1:
        raise SceneError(f"camera '{c.name}' resolution must be at least 1x1, got {c.width}x{c.height}")
    if np.any(np.asarray(c.film_size) <= 0):
        raise SceneError(f"camera '{c.name}' film_size must be > 0, got {tuple(c.film_size)}")
    if not (0 <= c.clip_start < c.clip_end):
        raise SceneError(f"camera '{c.name}' needs 0 <= clip_start < clip_end, "
                         f"got {c.clip_start}, {c.clip_end}")
    if c.region is not None:
        r = tuple(c.region)
        ok = len(r) == 4 and all(isinstance(v, (int, np.integer)) for v in r)
        if not ok or not (0 <= r[0] < r[2] <= int(c.width) and 0 <= r[1] < r[3] <= int(c.height)):
            raise SceneError(f"camera '{c.name}' render region must be (x0, y0, x1, y1) pixels "
                             f"with 0 <= x0 < x1 <= {c.width} and 0 <= y0 < y1 <= {c.height}, "
                             f"got {c.region}")

"""Blender's evaluated depsgraph -> core.Scene, the only road from Blender to the renderer.

``export_scene(depsgraph)`` walks ``depsgraph.object_instances`` once: real objects and
instances alike (collection instances, geometry-nodes and particle instances), modifiers
already applied by the depsgraph. Curves, text, surfaces and metaballs arrive there as
evaluated mesh instances, so every mesh-like object is read the same way. Objects hidden
from the render (``hide_render``, excluded collections) are not in a render depsgraph at
all; objects with every ray-visibility flag off are skipped, as Cycles does.

Mesh data is read with ``foreach_get`` into numpy once per distinct evaluated mesh and
transformed for all of its instances at once (normals by the inverse transpose).
Images used by Image Texture nodes are read once per export (export_materials.ImageTable).
What is exported and how shaders map to lobes: docs/export.md.

Positions are exported relative to a render origin (export_camera.render_origin: the
camera's position), in float64 until the final float32 arrays, so a scene far from
Blender's world origin keeps its precision; ``ExportResult.origin`` says where it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.scene.contract import Lights, Materials, Mesh, Scene, World
from ..core.scene.media import Media
from ..core.shading import program as pg
from ..core.shading.hash import object_random_id
from .export_camera import camera_view, export_camera, relative_camera, relative_matrix, \
    render_origin
from .export_errors import ExportError, NoCameraError  # noqa: F401  (re-exported)
from .export_lights import light_row
from .export_materials import ImageTable, default_row, read_material, read_world, volume_only
from .export_images import ProgramImageTable
from .export_shader import INSTANCER_ATTRIBUTE, OBJECT_ATTRIBUTE, PARAMETRIC_ATTRIBUTE, \
    POINTINESS_ATTRIBUTE, AttributeNames, UVMapNames, rna_attribute
from .export_volumes import material_medium, world_medium
from .export_warnings import scene_warnings

_VISIBILITY_FLAGS = ("visible_camera", "visible_diffuse", "visible_glossy",
                     "visible_transmission", "visible_shadow")


@dataclass
class ExportResult:
    """scene: the validated core.Scene, in the render frame; warnings: messages for the user
    (one per problem); origin: (3,) float64 world position (metres) of the render frame's
    origin: world = scene coordinates + origin (rotation-free).
    """

    scene: Scene
    warnings: list[str] = field(default_factory=list)
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))


def export_scene(depsgraph, camera=None, origin=None) -> ExportResult:
    """Build the core scene from an evaluated depsgraph (render or viewport).

    ``camera``: a core Camera to render through instead of the scene camera (the 3D
    viewport's view, photon_engine/viewport.py). Raises NoCameraError without either and
    ExportError (a core SceneError) for data that cannot be rendered, e.g. a NaN in an
    object's transform. ``origin``: (3,) world position of the render frame's origin
    (default: the camera's position; zeros keep world coordinates).
    """
    warnings: list[str] = []
    if camera is None:
        camera = export_camera(depsgraph, warnings)  # fail fast, before reading geometry
    origin = render_origin(camera) if origin is None else np.asarray(origin, np.float64)
    camera = relative_camera(camera, origin)
    materials = _MaterialTable(warnings)
    materials.view = camera_view(depsgraph)  # the scene camera, also in the 3D viewport
    # the Attribute node's View Layer type: the view layer's property, then the scene's
    materials.attributes.layer = (getattr(depsgraph, "view_layer_eval", None),
                                  getattr(depsgraph, "scene_eval", None))
    geometry = _Geometry(warnings)
    light_rows = []
    flagged = set()
    volume_objects = set()
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == 'VOLUME' and inst.show_self and obj.name not in volume_objects:
            # bpy 5.2 exposes a grid's name and type but not its voxels (no openvdb module)
            volume_objects.add(obj.name)
            warnings.append(f"Volume object '{obj.name}': OpenVDB grids are not supported "
                            f"(Blender's Python API does not expose their voxels); not rendered")
        if obj.type not in ('MESH', 'LIGHT') or not inst.show_self:
            continue
        if not _ray_visible(inst, flagged, warnings):
            continue
        name = _instance_name(inst)
        if obj.type == 'LIGHT':
            row = light_row(obj, inst.matrix_world, name, warnings)
            if row is not None:
                row["to_world"] = relative_matrix(row["to_world"], origin)
                light_rows.append(row)
        else:
            geometry.add(obj, inst.matrix_world, name, materials, object_info(inst),
                         instance_ids(inst))

    mesh, mesh_media = geometry.build(origin, materials.left_out, materials.volumes,
                                      materials.attributes.names,
                                      materials.tangent_maps.names, materials.uv_maps.names)
    scene = Scene(
        mesh=mesh,
        materials=Materials.from_list(materials.rows),
        lights=Lights.from_list(light_rows),
        camera=camera,
        world=_export_world(depsgraph, warnings),
        textures=materials.images.textures(),
        program_images=materials.program_images.images(),
        media=_export_media(depsgraph, warnings, mesh_media),
    )
    scene.validate()
    warnings.extend(scene_warnings(depsgraph, scene))
    return ExportResult(scene=scene, warnings=warnings, origin=origin)


def object_info(inst) -> np.ndarray:
    """(6,) float32 Object Info of a depsgraph instance: colour RGB (``Object.color``),
    Random, Object Index (``pass_index``), the colour's alpha (Object Info Alpha). Random is Cycles' ``random_number``, computed
    as scene/object.cpp does in float32: (float)random_id * (1.0f / (float)0xFFFFFFFF),
    random_id as Cycles' Blender sync makes it (``core.shading.hash.object_random_id``:
    the object name's hash, or the instance's ``random_id``)."""
    obj = inst.object
    rid = np.uint32(object_random_id(obj.name, inst.random_id, inst.is_instance))
    rand = np.float32(rid) * (np.float32(1.0) / np.float32(0xFFFFFFFF))
    color = tuple(obj.color)
    return np.array([*color[:3], rand, float(obj.pass_index), color[3]], np.float32)


def instance_ids(inst) -> tuple[tuple, tuple]:
    """The IDs the Attribute node's Object and Instancer types look a property up in, in
    Cycles' order (lookup_instance_property): Object: the object, then its data;
    Instancer: the particle system's settings and the instancing parent (for an
    instance), then the object and its data."""
    obj = inst.object
    own = (obj, getattr(obj, "data", None))
    above = ()
    if inst.is_instance:
        psys = getattr(inst, "particle_system", None)
        above = (getattr(psys, "settings", None), inst.parent)
    return own, above + own


def _instance_name(inst) -> str:
    """"Parent/Object" for instances; a curve, text or metaball evaluated to a mesh
    arrives as an instance of itself and keeps its own name."""
    if inst.is_instance and inst.parent is not None and inst.parent.name != inst.object.name:
        return f"{inst.parent.name}/{inst.object.name}"
    return inst.object.name


def _ray_visible(inst, flagged, warnings) -> bool:
    """False when no ray can see the object (Cycles skips it); notes partial visibility."""
    objs = [inst.object] + ([inst.parent] if inst.is_instance and inst.parent is not None else [])
    flags = [all(getattr(o, f, True) for o in objs) for f in _VISIBILITY_FLAGS]
    if not any(flags):
        return False
    base = inst.object.name
    if inst.object.type == 'MESH' and not all(flags) and base not in flagged:
        flagged.add(base)
        off = [f.removeprefix("visible_") for f, on in zip(_VISIBILITY_FLAGS, flags) if not on]
        warnings.append(f"Object '{base}': ray visibility ({', '.join(off)} off) is not "
                        f"supported yet; rendering it as fully visible")
    return True


def _export_world(depsgraph, warnings) -> World:
    scene = depsgraph.scene
    world = scene.world
    radiance = read_world(world, warnings)
    visible = True
    if world is not None and hasattr(world, "cycles_visibility"):
        visible = bool(world.cycles_visibility.camera)
    # Transparent film: Cycles leaves the background out of the colour (alpha 0).
    visible = visible and not scene.render.film_transparent
    return World(radiance=np.asarray(radiance, np.float32), visible_to_camera=visible)


def _export_media(depsgraph, warnings, mesh_media) -> Media:
    """The scene's media (photon_engine/export_volumes.py): the World's Volume and
    ``mesh_media``, the rows of the media inside mesh objects (``_Geometry.build``)."""
    row = world_medium(depsgraph.scene.world, warnings)
    rows = ([row] if row is not None else []) + list(mesh_media)
    # Each heterogeneous material's density program once, shared by its objects' rows
    programs, index = [], {}
    for r in rows:
        prog = r.pop("density_program", None)
        if prog is not None:
            if id(prog) not in index:
                index[id(prog)] = len(programs)
                programs.append(prog)
            r["density_texture"] = index[id(prog)]
    return Media.from_list(rows, programs=tuple(programs))


class _MaterialTable:
    """The global material list, one row per distinct Blender material (None = default grey),
    and the images their Image Texture nodes use (each read once)."""

    def __init__(self, warnings):
        self.rows: list[dict] = []
        self._index: dict = {}
        self._warnings = warnings
        self.images = ImageTable(warnings)
        self.program_images = ProgramImageTable(warnings)
        self.attributes = AttributeNames()
        self.view = None
        """The render camera for the programs' Texture Coordinate Camera / Window."""
        self.tangent_maps = AttributeNames()
        """UV maps whose MikkTSpace tangents the programs read ("" = active render)."""
        self.uv_maps = UVMapNames()
        """UV maps the programs name (UV Map node; ``Mesh.uv_map_names``)."""
        self.left_out: set[int] = set()
        """Indices of volume-only materials: their faces are not surfaces (null
        interfaces) and only bound their medium."""
        self.volumes: dict[int, dict] = {}
        """Material index -> its Volume's medium row (export_volumes.material_medium)."""

    def index(self, mat) -> int:
        if mat is None:
            key = None
        else:
            mat = getattr(mat, "original", mat) or mat
            key = mat.as_pointer()
        if key not in self._index:
            volume = None if mat is None else material_medium(mat, self._warnings)
            if volume is not None:
                self.volumes[len(self.rows)] = volume
            if mat is not None and volume_only(mat):
                # Cycles renders it as a volume without a surface: its faces only bound
                # the medium.
                self.left_out.add(len(self.rows))
                row = default_row(mat.name)
            else:
                row = default_row() if mat is None else read_material(
                    mat, self._warnings, self.images, self.program_images, self.attributes,
                    view=self.view, tangent_maps=self.tangent_maps, uv_maps=self.uv_maps)
            self._index[key] = len(self.rows)
            self.rows.append(row)
        return self._index[key]

    def slots(self, obj) -> tuple:
        """Global material index per material slot of ``obj`` (at least one entry)."""
        mats = [slot.material for slot in obj.material_slots]
        if not mats:
            mats = list(getattr(obj.data, "materials", [])) or [None]
        return tuple(self.index(m) for m in mats)


@dataclass
class _LocalMesh:
    """One evaluated mesh in its object space (before any instance transform)."""

    positions: np.ndarray  # (V, 3) float64
    triangles: np.ndarray  # (T, 3) int32
    normals: np.ndarray  # (T, 3, 3) float32
    uvs: np.ndarray  # (T, 3, 2) float32
    material: np.ndarray  # (T,) int32, slot index
    corners: np.ndarray | None = None  # (T, 3) int32, the triangles' corner (loop) indices
    faces: np.ndarray | None = None    # (T,) int32, the triangles' faces (3.6+; else None)
    vertex_ids: np.ndarray | None = None  # (T, 3) int32, the mesh's own vertex indices
    attributes: np.ndarray | None = None  # (T, 3, A, 4) float32, read_attributes
    tangents: np.ndarray | None = None  # (T, 3, G, 4) float32, read_tangents
    uv_maps: np.ndarray | None = None  # (T, 3, U, 2) float32, read_uv_maps


def read_mesh(me) -> _LocalMesh | None:
    """Triangles, corner normals, active-render UVs and slot indices of a mesh, in object space.

    Zero-area triangles are dropped (they cannot be hit and have no normal). Returns None
    for a mesh without triangles. Reads attributes in bulk where Blender has them (4.x+);
    the per-item collections (``vertices``, ``loop_triangles`` fields) are many times slower.
    """
    nv, nl, nt = len(me.vertices), len(me.loops), len(me.loop_triangles)
    if nt == 0:
        return None
    co = _read(_attribute_data(me, "position"), "vector", nv * 3, np.float32,
               lambda out: me.vertices.foreach_get("co", out))
    corners = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", corners)
    corner_vert = _read(_attribute_data(me, ".corner_vert"), "value", nl, np.int32,
                        lambda out: me.loops.foreach_get("vertex_index", out))
    tri = corner_vert[corners].reshape(-1, 3)
    tri_face = None
    if hasattr(me, "loop_triangle_polygons"):  # 3.6+
        tri_face = np.empty(nt, np.int32)
        me.loop_triangle_polygons.foreach_get("value", tri_face)
        face_mat = _read(_attribute_data(me, "material_index"), "value", len(me.polygons), np.int32,
                         lambda out: out.fill(0))
        mat = face_mat[tri_face]
    else:
        mat = np.empty(nt, np.int32)
        me.loop_triangles.foreach_get("material_index", mat)
    normals = np.empty(nl * 3, np.float32)
    if hasattr(me, "corner_normals"):  # 4.1+
        me.corner_normals.foreach_get("vector", normals)
    else:
        me.calc_normals_split()
        me.loops.foreach_get("normal", normals)
    uv_layer = next((layer for layer in me.uv_layers if layer.active_render), None)
    if uv_layer is not None:
        all_uvs = _read(getattr(uv_layer, "uv", None), "vector", nl * 2, np.float32,
                        lambda out: uv_layer.data.foreach_get("uv", out))
        uvs = all_uvs.reshape(-1, 2)[corners].reshape(-1, 3, 2)
    else:
        uvs = np.zeros((nt, 3, 2), np.float32)

    positions = co.reshape(-1, 3)
    p = positions[tri]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    cross = np.cross(e1, e2)
    area2 = np.einsum("ij,ij->i", cross, cross)
    scale2 = np.einsum("ij,ij->i", e1, e1) + np.einsum("ij,ij->i", e2, e2)
    # |e1 x e2| <= 1e-6 |e|^2: collinear or repeated corners (float32 noise is ~1e-7).
    keep = area2 > 1e-12 * scale2 * scale2
    n = normals.reshape(-1, 3)[corners].reshape(-1, 3, 3)
    # Blender gives unit normals for valid faces; repair the odd broken one with the face's.
    length2 = np.einsum("tcj,tcj->tc", n, n)
    bad = ~(length2 > 0.25)  # also catches NaN
    if np.any(bad & keep[:, None]):
        face = cross / np.sqrt(np.maximum(area2, 1e-30))[:, None]
        n[bad] = np.broadcast_to(face[:, None, :], n.shape)[bad]
    corners = corners.reshape(-1, 3)
    if not np.all(keep):
        tri, n, uvs, mat = tri[keep], n[keep], uvs[keep], mat[keep]
        corners = corners[keep]
        tri_face = None if tri_face is None else tri_face[keep]
    return _LocalMesh(positions=positions.astype(np.float64), triangles=tri, normals=n,
                      uvs=uvs, material=mat, corners=corners, faces=tri_face,
                      vertex_ids=tri)


def read_attributes(me, names, local: _LocalMesh, where: str, warnings) -> np.ndarray:
    """(T, 3, A, 4) float32: the mesh attributes ``names`` at the corners of ``local``'s
    triangles, as the Attribute / Color Attribute nodes read them (RGBA): a colour
    attribute (float or byte; Blender gives both in scene linear) as it is, a vector
    (x, y, z, 1), a 2D vector (x, y, 0, 1), a float (f, f, f, 1). Point, corner and face
    domains. The name "" is the mesh's render colour attribute (Cycles' default). A name
    the mesh lacks, or of another type or domain, is 0 (as Cycles) and reported once
    with ``where`` (the object)."""
    nt = local.triangles.shape[0]
    out = np.zeros((nt, 3, len(names), 4), np.float32)
    for a, name in enumerate(names):
        if name.startswith((OBJECT_ATTRIBUTE, INSTANCER_ATTRIBUTE)):
            continue  # a per-object value, written by _Geometry.build
        if name == PARAMETRIC_ATTRIBUTE:  # the Geometry node's Parametric, per corner
            out[:, :, a] = np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 0, 1]], np.float32)
            continue
        if name == POINTINESS_ATTRIBUTE:  # the Geometry node's Pointiness, per vertex
            f = pointiness(me)
            out[:, :, a, :3] = f[local.vertex_ids][..., None]
            out[:, :, a, 3] = 1.0
            continue
        key = name
        if not name:
            colors = getattr(me, "color_attributes", None)
            idx = getattr(colors, "render_color_index", -1) if colors is not None else -1
            key = colors[idx].name if colors is not None and 0 <= idx < len(colors) else None
        att = me.attributes.get(key) if key is not None else None
        if att is None:
            msg = (f"{where}: attribute '{name or '(render colour)'}' not found; "
                   f"0 is used, as Cycles")
            if msg not in warnings:
                warnings.append(msg)
            continue
        kind = {"FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color", 4),
                "FLOAT_VECTOR": ("vector", 3), "FLOAT2": ("vector", 2),
                "FLOAT": ("value", 1)}.get(att.data_type)
        dom = {"CORNER": local.corners, "POINT": local.vertex_ids,
               "FACE": None if local.faces is None else
               np.repeat(local.faces[:, None], 3, axis=1)}.get(att.domain)
        if kind is None or dom is None:
            msg = (f"{where}: attribute '{key}' ({att.data_type} on {att.domain}) is not "
                   f"supported; 0 is used")
            if msg not in warnings:
                warnings.append(msg)
            continue
        field, width = kind
        buf = np.empty(len(att.data) * width, np.float32)
        att.data.foreach_get(field, buf)
        vals = buf.reshape(-1, width)
        rgba = np.zeros((vals.shape[0], 4), np.float32)
        rgba[:, 3] = 1.0
        if width == 1:
            rgba[:, :3] = vals
        else:
            rgba[:, :width] = vals
        out[:, :, a] = rgba[dom]
    return out


def pointiness(me) -> np.ndarray:
    """(V,) float32: Cycles' Pointiness of each vertex of mesh ``me`` (blender/mesh.cpp
    attr_create_pointiness): vertices at the same position welded; per welded vertex the
    normal the mean of their normals, then acos(N . mean of the unit edge vectors from it)
    / pi over its distinct edges, then blurred once: (own + the sum over the edge
    neighbours) / (1 + their count). 0.5 on a flat region, more on a convex corner."""
    nv = len(me.vertices)
    if nv == 0:
        return np.zeros(0, np.float32)
    co = np.empty(nv * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    nrm = np.empty(nv * 3, np.float32)
    source = getattr(me, "vertex_normals", None)
    if source is not None and len(source) == nv:
        source.foreach_get("vector", nrm)
    else:
        me.vertices.foreach_get("normal", nrm)
    nrm = nrm.reshape(-1, 3).astype(np.float64)
    _, weld = np.unique(co, axis=0, return_inverse=True)
    weld = weld.ravel()
    k = int(weld.max()) + 1
    acc = np.zeros((k, 3))
    np.add.at(acc, weld, nrm)
    n = acc / np.maximum(np.linalg.norm(acc, axis=1), 1e-30)[:, None]
    pos = np.zeros((k, 3))
    pos[weld] = co
    ed = np.empty(len(me.edges) * 2, np.int32)
    me.edges.foreach_get("vertices", ed)
    e = np.sort(weld[ed.reshape(-1, 2)], axis=1)
    e = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
    d = pos[e[:, 1]] - pos[e[:, 0]]
    d /= np.maximum(np.linalg.norm(d, axis=1), 1e-30)[:, None]
    edge_sum = np.zeros((k, 3))
    np.add.at(edge_sum, e[:, 0], d)
    np.add.at(edge_sum, e[:, 1], -d)
    count = np.zeros(k)
    np.add.at(count, e.ravel(), 1.0)
    mean = edge_sum / np.maximum(count, 1.0)[:, None]
    raw = np.where(count > 0, np.arccos(np.clip(np.einsum("ij,ij->i", n, mean), -1.0, 1.0))
                   / np.pi, 0.0)
    blur = raw.copy()
    np.add.at(blur, e[:, 0], raw[e[:, 1]])
    np.add.at(blur, e[:, 1], raw[e[:, 0]])
    blur /= count + 1.0
    return blur[weld].astype(np.float32)


def read_tangents(me, names, local: _LocalMesh, where: str, warnings) -> np.ndarray:
    """(T, 3, G, 4) float32: the MikkTSpace tangents (object space) and bitangent signs
    of the UV maps ``names`` ("" = the active render one) at the corners of ``local``'s
    triangles, as Blender computes them for Cycles (``Mesh.calc_tangents`` on the
    evaluated mesh, its corner normals). A UV map the mesh lacks, or a mesh Blender cannot
    compute tangents for (faces of more than 4 corners), gives sign 0 (the Normal Map
    leaves the normal as it is, as Cycles does without the tangent attribute), reported
    once with ``where``."""
    nt = local.triangles.shape[0]
    out = np.zeros((nt, 3, len(names), 4), np.float32)
    nl = len(me.loops)
    for g, name in enumerate(names):
        layer = (next((lay for lay in me.uv_layers if lay.active_render), None) if not name
                 else me.uv_layers.get(name))
        if layer is None:
            msg = (f"{where}: UV map '{name or '(active render)'}' for a Normal Map not "
                   f"found; the normal is left as it is, as Cycles")
            if msg not in warnings:
                warnings.append(msg)
            continue
        try:
            me.calc_tangents(uvmap=layer.name)
        except RuntimeError as exc:
            msg = (f"{where}: no tangents for UV map '{layer.name}' ({exc}); the Normal "
                   f"Map leaves the normal as it is")
            if msg not in warnings:
                warnings.append(msg)
            continue
        tangent = np.empty(nl * 3, np.float32)
        sign = np.empty(nl, np.float32)
        me.loops.foreach_get("tangent", tangent)
        me.loops.foreach_get("bitangent_sign", sign)
        me.free_tangents()
        corners = local.corners
        out[:, :, g, :3] = tangent.reshape(-1, 3)[corners]
        out[:, :, g, 3] = np.where(sign.reshape(-1)[corners] < 0, -1.0, 1.0)
    return out


def read_uv_maps(me, names, local: _LocalMesh, where: str, uv_maps: UVMapNames,
                 warnings, materials=None) -> np.ndarray:
    """(T, 3, U, 2) float32: the UV maps ``names`` at the corners of ``local``'s triangles
    (``Mesh.uv_maps``). A name the mesh lacks is (0, 0), as Cycles (its attribute lookup
    fails and the node reads 0), reported once per material and name for each material
    among ``materials`` (the object's material names; None: any) that reads it
    (``uv_maps.readers``), with ``where`` (the object)."""
    nt = local.triangles.shape[0]
    out = np.zeros((nt, 3, len(names), 2), np.float32)
    nl = len(me.loops)
    for j, name in enumerate(names):
        layer = me.uv_layers.get(name)
        if layer is None:
            for material in uv_maps.readers.get(name, ()):
                if materials is not None and material not in materials:
                    continue
                msg = (f"Material '{material}': UV map '{name}' not found on {where}; "
                       f"(0, 0) is used, as Cycles")
                if not any(w.startswith(f"Material '{material}': UV map '{name}' not found")
                           for w in warnings):
                    warnings.append(msg)
            continue
        data = _read(getattr(layer, "uv", None), "vector", nl * 2, np.float32,
                     lambda buf: layer.data.foreach_get("uv", buf))
        out[:, :, j] = data.reshape(-1, 2)[local.corners]
    return out


def _attribute_data(me, name):
    attribute = me.attributes.get(name)
    return None if attribute is None else attribute.data


def _read(items, attr, size, dtype, fallback):
    """(size,) array from the collection ``items`` by ``foreach_get``, or filled by
    ``fallback(out)`` when it is missing or has another length."""
    out = np.empty(size, dtype)
    if items is not None and len(items) > 0 and size % len(items) == 0 \
            and size // len(items) in (1, 2, 3):
        items.foreach_get(attr, out)
    else:
        fallback(out)
    return out


class _Geometry:
    """Collects mesh instances, then transforms each distinct mesh for all its instances."""

    def __init__(self, warnings):
        self._warnings = warnings
        self._meshes: dict[int, _LocalMesh | None] = {}
        self._batches: dict[tuple, list] = {}
        self.names: list[str] = []
        self.matrices: list[np.ndarray] = []   # per object: matrix_world (shader programs)
        self.texspaces: list[np.ndarray] = []  # per object: texture space location, size
        self.info: list[np.ndarray] = []       # per object: object_info rows
        self.object_attributes: list[dict] = []  # per object: Object / Instancer values

    def add(self, obj, matrix, name, materials: _MaterialTable, info=None,
            ids=((), ())) -> None:
        """One instance of ``obj``; info its ``object_info`` row (None: zeros); ids the IDs
        its Object and Instancer attributes are looked up in (``instance_ids``)."""
        m = np.array(matrix, np.float64)
        if not np.all(np.isfinite(m)):
            raise ExportError(f"object '{name}' has a non-finite transform (NaN or infinity "
                              f"in its matrix); fix its location, rotation or scale")
        slots = materials.slots(obj)  # first: its programs name the attributes they read
        names = tuple(materials.attributes.names)
        tangent_maps = tuple(materials.tangent_maps.names)
        uv_names = tuple(materials.uv_maps.names)
        key = (obj.data.as_pointer(), names, tangent_maps, uv_names)
        if key not in self._meshes:
            local = read_mesh(obj.data)
            if local is not None:
                local.attributes = read_attributes(obj.data, names, local,
                                                   f"Object '{name}'", self._warnings)
                if tangent_maps:
                    local.tangents = read_tangents(obj.data, tangent_maps, local,
                                                   f"Object '{name}'", self._warnings)
                if uv_names:
                    local.uv_maps = read_uv_maps(obj.data, uv_names, local,
                                                 f"object '{name}'", materials.uv_maps,
                                                 self._warnings,
                                                 {materials.rows[i]["name"] for i in slots})
            self._meshes[key] = local
        if self._meshes[key] is None:
            return
        det = np.linalg.det(m[:3, :3])
        if not abs(det) > 0:
            self._warnings.append(f"Object '{name}': zero scale on an axis; skipped")
            return
        self.names.append(name)
        self.matrices.append(m)
        values = {}  # the Attribute node's Object / Instancer values of this instance
        read = set()  # the attribute indices its own materials' programs read
        for i in slots:
            prog = materials.rows[i].get("program") if i < len(materials.rows) else None
            if prog is not None:
                ins = prog.instructions
                attr = (ins[:, 0] == pg.OP_INPUT) & np.isin(
                    ins[:, 1], (pg.SOURCE_ATTRIBUTE_COLOR, pg.SOURCE_ATTRIBUTE_ALPHA))
                read.update(ins[attr, 2].tolist())
        for j, att in enumerate(names):
            for prefix, where in ((OBJECT_ATTRIBUTE, ids[0]), (INSTANCER_ATTRIBUTE, ids[1])):
                if att.startswith(prefix) and j in read:
                    rgba = rna_attribute(where, att[len(prefix):])
                    if rgba is not None:
                        values[att] = rgba
                    else:
                        msg = (f"Object '{name}': property '{att[len(prefix):]}' of an "
                               f"Attribute node ({prefix[1:-1]}) not found; 0 is used, as "
                               f"Cycles")
                        if msg not in self._warnings:
                            self._warnings.append(msg)
        self.object_attributes.append(values)
        self.info.append(np.array([0, 0, 0, 0, 0, 1], np.float32) if info is None else info)
        me = obj.data
        self.texspaces.append(np.array([tuple(getattr(me, "texspace_location", (0, 0, 0))),
                                        tuple(getattr(me, "texspace_size", (1, 1, 1)))],
                                       np.float64))
        self._batches.setdefault((key, slots), []).append((m, len(self.names) - 1))

    def build(self, origin, left_out=frozenset(), volumes=None,
              attribute_names=(), tangent_maps=(), uv_map_names=()) -> tuple[Mesh, list[dict]]:
        """The mesh in the render frame: world positions - ``origin`` (3,), in float64
        until the float32 cast; faces of the materials in ``left_out`` are dropped;
        ``attribute_names`` the shader programs' attributes (``Mesh.attributes``),
        ``tangent_maps`` the UV maps of their tangents (``Mesh.tangents``),
        ``uv_map_names`` the UV maps they name (``Mesh.uv_maps``). And the
        media inside the objects: one ``Media.from_list`` row per object and material of
        ``volumes`` (material index -> medium row), bounded by that object's faces of the
        material ("Smoke in Sphere")."""
        if not self._batches:
            return Mesh.empty(), []
        n_attributes = len(attribute_names)
        n_tangents = len(tangent_maps)
        n_uv = len(uv_map_names)
        parts = []
        base = 0
        for (key, slots), instances in self._batches.items():
            local = self._meshes[key]
            part = _transform(local, np.stack([m for m, _ in instances]),
                              np.array([i for _, i in instances], np.int32), slots, base,
                              n_attributes, n_tangents, n_uv)
            base += part[0].shape[0]
            parts.append(part)
        verts, tris, normals, uvs, mats, objs, attrs, tans, uv_maps = (
            np.concatenate(col) for col in zip(*parts))
        for a, att in enumerate(attribute_names):  # per-object values at every corner
            if att.startswith((OBJECT_ATTRIBUTE, INSTANCER_ATTRIBUTE)):
                table = np.zeros((len(self.names), 4), np.float32)
                for i, values in enumerate(self.object_attributes):
                    table[i] = values.get(att, table[i])
                attrs[:, :, a] = table[objs][:, None, :]
        verts -= np.asarray(origin, np.float64)
        media = []
        for mat_index, row in sorted((volumes or {}).items()):
            on = mats == mat_index
            for obj in np.unique(objs[on]):
                faces = on & (objs == obj)
                name = f"{row['name']} in {self.names[obj]}"
                open_edges = _open_edges(tris[faces])
                if open_edges:
                    self._warnings.append(
                        f"Medium '{name}': the faces of material \"{row['name']}\" on object "
                        f"'{self.names[obj]}' are not a closed mesh ({open_edges} open edges); "
                        f"a ray that crosses it once stays in the medium for the rest of its "
                        f"way, as in Cycles")
                boundary = verts[tris[faces]].astype(np.float32)
                own = {k: v for k, v in row.items() if k != "homogeneous_part"}
                media.append({**own, "bounds": int(obj), "name": name, "boundary": boundary})
                if "homogeneous_part" in row:  # the rest of an Add / Mix beside a varying density
                    media.append({**row["homogeneous_part"], "bounds": int(obj),
                                  "name": f"{name} (homogeneous part)", "boundary": boundary})
        if left_out:  # faces of volume-only materials on objects with other slots too
            keep = ~np.isin(mats, list(left_out))
            tris, normals, uvs = tris[keep], normals[keep], uvs[keep]
            mats, objs, attrs, tans = mats[keep], objs[keep], attrs[keep], tans[keep]
            uv_maps = uv_maps[keep]
        f32, i32 = np.float32, np.int32
        return Mesh(vertices=verts.astype(f32), triangles=tris.astype(i32, copy=False),
                    normals=normals.astype(f32, copy=False), uvs=uvs.astype(f32, copy=False),
                    material_index=mats.astype(i32, copy=False),
                    object_index=objs.astype(i32, copy=False), object_names=tuple(self.names),
                    object_to_world=np.stack(self.matrices).astype(np.float64),
                    object_texspace=np.stack(self.texspaces),
                    object_info=np.stack(self.info).astype(np.float32),
                    attributes=attrs.astype(f32, copy=False) if n_attributes else None,
                    attribute_names=tuple(attribute_names),
                    tangents=tans.astype(f32, copy=False) if n_tangents else None,
                    tangent_maps=tuple(tangent_maps),
                    uv_maps=uv_maps.astype(f32, copy=False) if n_uv else None,
                    uv_map_names=tuple(uv_map_names),
                    origin=np.asarray(origin, np.float64).reshape(3)), media


def _open_edges(tris) -> int:
    """How many edges of the triangles (T, 3) vertex indices belong to an odd number of
    them (0 for a closed mesh: every edge has a triangle on each side)."""
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int(np.count_nonzero(counts % 2))


def _transform(local: _LocalMesh, matrices, object_ids, slots, base, n_attributes=0,
               n_tangents=0, n_uv=0):
    """World-space arrays for K instances of one mesh: (V*K, 3) vertices, (T*K, ...) rest."""
    k = matrices.shape[0]
    nv, nt = local.positions.shape[0], local.triangles.shape[0]
    lin, trans = matrices[:, :3, :3], matrices[:, :3, 3]
    # (N, 3) @ (K, 3, 3) broadcasts to (K, N, 3): one matrix product per instance.
    verts = local.positions @ np.transpose(lin, (0, 2, 1)) + trans[:, None, :]
    normal_matrix = np.linalg.inv(lin).astype(np.float32)  # inverse transpose, transposed
    normals = (local.normals.reshape(-1, 3) @ normal_matrix).reshape(k, nt, 3, 3)
    normals /= np.sqrt(np.einsum("ktcj,ktcj->ktc", normals, normals))[..., None]
    tris = local.triangles[None] + (base + nv * np.arange(k))[:, None, None]
    uvs = np.broadcast_to(local.uvs, (k, nt, 3, 2)).copy()
    # a mesh read before a later material named more attributes: those are 0 on it
    # (its own materials do not read them)
    own = local.attributes if local.attributes is not None else \
        np.zeros((nt, 3, 0, 4), np.float32)
    attrs = np.zeros((k, nt, 3, n_attributes, 4), np.float32)
    attrs[:, :, :, :own.shape[2]] = own[:, :, :n_attributes]
    # Tangents are directions: the linear part takes them to the world (Cycles applies
    # the object transform to its tangent attribute the same way); a mirror also flips
    # the bitangent sign, so that sign * N x T stays the image of the object's bitangent.
    tans = np.zeros((k, nt, 3, n_tangents, 4), np.float32)
    if local.tangents is not None and n_tangents:
        own_t = local.tangents[:, :, :n_tangents]
        g = own_t.shape[2]
        tans[:, :, :, :g, :3] = np.einsum("kij,tcgj->ktcgi", lin, own_t[..., :3])
        tans[:, :, :, :g, 3] = own_t[None, ..., 3] * np.where(
            np.linalg.det(lin) < 0, -1.0, 1.0)[:, None, None, None]
    # likewise UV maps named after this mesh was read: (0, 0) on it
    own_uv = local.uv_maps if local.uv_maps is not None else \
        np.zeros((nt, 3, 0, 2), np.float32)
    uv_maps = np.zeros((k, nt, 3, n_uv, 2), np.float32)
    uv_maps[:, :, :, :own_uv.shape[2]] = own_uv[:, :, :n_uv]
    # A mirroring transform flips the winding; swap two corners to keep the face
    # orientation (and so the geometric normal) on the side of the shading normals.
    flip = np.linalg.det(lin) < 0
    if np.any(flip):
        for arr in (tris, normals, uvs, attrs, tans, uv_maps):
            arr[flip, :, 1], arr[flip, :, 2] = arr[flip, :, 2].copy(), arr[flip, :, 1].copy()
    lut = np.asarray(slots, np.int32)
    mats = np.tile(lut[np.clip(local.material, 0, len(lut) - 1)], k)
    objs = np.repeat(object_ids, nt)
    return (verts.reshape(-1, 3), tris.reshape(-1, 3), normals.reshape(-1, 3, 3),
            uvs.reshape(-1, 3, 2), mats, objs, attrs.reshape(k * nt, 3, n_attributes, 4),
            tans.reshape(k * nt, 3, n_tangents, 4), uv_maps.reshape(k * nt, 3, n_uv, 2))

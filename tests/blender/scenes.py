"""Small scene builders and render helpers for the Blender tests.

Import as ``from tests.blender import scenes`` (pytest's importlib mode registers the
``tests`` namespace). Every builder works on ``bpy.context.scene`` after ``reset()``.
Units are Blender's: metres, watts for point/spot/area lights, W/m^2 for the sun.
Images come back as numpy (H, W, C) float32 with row 0 at the TOP, like core's passes.
"""

from __future__ import annotations

import pathlib
import tempfile

import bpy
import numpy as np
from mathutils import Vector


def photon_map():
    """The extension package ``photon_map`` (the repo root), registered once per process."""
    from tests.conftest import load_extension_package

    package = load_extension_package()
    if not hasattr(bpy.types.Scene, "photon_map"):
        package.register()
    return package


def reset():
    """An empty factory scene (no objects, no world), Cycles-neutral render settings."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def set_resolution(width: int, height: int, percentage: int = 100):
    r = bpy.context.scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, percentage


def add_camera(location=(0.0, -4.0, 1.0), look_at=(0.0, 0.0, 0.0), lens=50.0,
               name="Camera", ortho_scale=None):
    """A camera at ``location`` aimed at ``look_at``; made the scene camera.

    ortho_scale: when given, the camera is orthographic with that width in metres.
    """
    data = bpy.data.cameras.new(name)
    data.lens = lens
    if ortho_scale is not None:
        data.type = 'ORTHO'
        data.ortho_scale = ortho_scale
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    direction = Vector(look_at) - Vector(location)
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    bpy.context.scene.camera = obj
    return obj


def ensure_node_tree(idblock):
    """The node tree of a material or world, made to be used (photon_engine/compat.py keeps
    the Blender-version rules: ``use_nodes`` before 5.0, always from 5.0)."""
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.compat import ensure_node_tree as ensure

    return ensure(idblock)


def world_volume(name, idname, **inputs):
    """A new World ``name`` on the scene whose active output's Volume is one ``idname``
    node with ``inputs`` (socket name -> default value); the World's other nodes (its
    Background) kept. Returns (world, tree, node, output)."""
    world = bpy.data.worlds.new(name)
    bpy.context.scene.world = world
    tree = ensure_node_tree(world)
    node = tree.nodes.new(idname)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_WORLD')
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return world, tree, node, output


def eevee_id() -> str:
    """EEVEE's engine id in this Blender (photon_engine/compat.py)."""
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.compat import EEVEE

    return EEVEE


def diffuse_material(name="Diffuse", color=(0.8, 0.8, 0.8)):
    """A node material: Diffuse BSDF of albedo ``color`` (linear RGB) -> Material Output."""
    mat = bpy.data.materials.new(name)  # 5.0: always node-based (use_nodes is deprecated)
    if mat.node_tree is None:  # older Blender
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfDiffuse')
    bsdf.inputs['Color'].default_value = (*color, 1.0)
    out = nodes.new('ShaderNodeOutputMaterial')
    mat.node_tree.links.new(bsdf.outputs['BSDF'], out.inputs['Surface'])
    return mat


def principled_material(name="Principled", **inputs):
    """A new material as Blender makes it (a default Principled BSDF -> Material Output),
    with the named inputs set: keyword = socket name with spaces as underscores, e.g.
    ``principled_material("Copper", Base_Color=(0.95, 0.64, 0.54), Metallic=1.0,
    Roughness=0.35)``; colours are linear RGB (alpha 1 added)."""
    mat = bpy.data.materials.new(name)
    tree = ensure_node_tree(mat)
    bsdf = next(n for n in tree.nodes if n.bl_idname == 'ShaderNodeBsdfPrincipled')
    for key, value in inputs.items():
        socket = bsdf.inputs[key.replace("_", " ")]
        if socket.type == 'RGBA':
            value = (*value, 1.0)
        socket.default_value = value
    return mat


def add_plane(size=2.0, location=(0.0, 0.0, 0.0), material=None, name="Plane", rotation=(0.0, 0.0, 0.0)):
    """A square of side ``size`` metres (normal +Z before ``rotation``, radians)."""
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    obj = bpy.context.active_object
    obj.name = name
    if material is not None:
        obj.data.materials.append(material)
    return obj


def add_sphere(radius=0.5, location=(0.0, 0.0, 0.0), material=None, name="Sphere", segments=32):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=location,
                                         segments=segments, ring_count=segments // 2)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    if material is not None:
        obj.data.materials.append(material)
    return obj


def add_light(kind='POINT', location=(0.0, 0.0, 2.0), power=100.0, color=(1.0, 1.0, 1.0),
              rotation=(0.0, 0.0, 0.0), name=None, **attrs):
    """A light of ``kind`` POINT/SPOT/SUN/AREA.

    power: watts (point, spot, area) or W/m^2 (sun, stored as ``energy`` too).
    attrs: extra light-data attributes, e.g. shadow_soft_size=0.1, size=0.5, shape='DISK'.
    """
    data = bpy.data.lights.new(name or kind.title(), kind)
    data.energy = power
    data.color = color
    for key, value in attrs.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name or kind.title(), data)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = rotation
    return obj


def use_photon_map(scene=None, **settings):
    """Select the Photon Map engine (registering it if needed) and set ``scene.photon_map`` values.

    Adaptive sampling is off unless ``adaptive_threshold`` is given: the tests compare the
    physics with every pixel at ``samples`` (adaptive sampling stops a pixel whose samples
    have not met a rare bright path: docs/photon_rendering.md, "Adaptive sampling"), and
    its own tests set it."""
    settings.setdefault("adaptive_threshold", 0.0)
    photon_map()
    scene = scene or bpy.context.scene
    scene.render.engine = 'PHOTON_MAP'
    if scene.render.engine != 'PHOTON_MAP':
        raise RuntimeError("Photon Map engine is not registered")
    for key, value in settings.items():
        setattr(scene.photon_map, key, value)
    return scene


def plane_and_point_light(width=32, height=24, power=100.0, albedo=0.8):
    """The smallest lit scene: a 4 m plane, a point light 1 m above it, a camera looking down.

    Returns the scene (render engine untouched).
    """
    scene = reset()
    set_resolution(width, height)
    add_plane(size=4.0, material=diffuse_material("Grey", (albedo, albedo, albedo)))
    add_light('POINT', location=(0.0, 0.0, 1.0), power=power, shadow_soft_size=0.0)
    add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), lens=35.0)
    return scene


def read_multilayer_exr(path) -> dict[str, np.ndarray]:
    """Passes of a Blender multilayer EXR: {"Combined": (H, W, 4), "Emission": (H, W, 3), ...}.

    Blender 5.0 writes one EXR *part* per pass ("ViewLayer.Combined", ...), so every part
    is read, not only the first. Keys drop the view-layer prefix; channels are ordered
    RGBA / XYZ as Blender names them. Row 0 is the top of the picture (EXR order).
    """
    import OpenEXR

    order = {c: i for i, c in enumerate("RGBAXYZ")}
    grouped: dict[str, dict[str, np.ndarray]] = {}
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                pass_name, _, chan = name.rpartition(".")
                pass_name = pass_name.split(".", 1)[-1] if "." in pass_name else pass_name
                grouped.setdefault(pass_name, {})[chan] = np.asarray(channel.pixels)
    return {name: np.stack([chans[c] for c in sorted(chans, key=lambda c: order.get(c, 99))], axis=-1)
            for name, chans in grouped.items()}


def render_passes(scene=None) -> dict[str, np.ndarray]:
    """``bpy.ops.render.render()``, then every pass of the Render Result as numpy arrays.

    Blender does not expose Render Result pixels to Python, so the result is saved as a
    32-bit multilayer EXR in a temporary folder and read back (the scene's own output
    settings are left untouched). Raises RuntimeError("Error: ...") when the engine
    reports an error, as ``bpy.ops.render.render`` does.
    """
    scene = scene or bpy.context.scene
    bpy.ops.render.render()
    return saved_render_result(scene)


def saved_render_result(scene=None) -> dict[str, np.ndarray]:
    """The current Render Result, every pass, via a temporary multilayer EXR."""
    scene = scene or bpy.context.scene
    image = bpy.data.images["Render Result"]
    settings = scene.render.image_settings
    has_media_type = hasattr(settings, "media_type")  # 5.0+: set before file_format
    saved = (getattr(settings, "media_type", None), settings.file_format, settings.color_depth)
    try:
        if has_media_type:
            settings.media_type = 'MULTI_LAYER_IMAGE'
        settings.file_format = 'OPEN_EXR_MULTILAYER'
        settings.color_depth = '32'
        with tempfile.TemporaryDirectory() as folder:
            path = pathlib.Path(folder) / "render.exr"
            image.save_render(filepath=str(path), scene=scene)
            return read_multilayer_exr(path)
    finally:
        if has_media_type:
            settings.media_type = saved[0]
        settings.file_format = saved[1]
        settings.color_depth = saved[2]

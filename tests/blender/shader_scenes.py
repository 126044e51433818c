"""Cycles as the reference for the shader nodes: planes whose Emission colour is driven by
a node graph, side by side in one orthographic view, rendered by Cycles in this bpy
process; and the same graphs compiled (photon_engine/export_shader.py) and run by the
core interpreter at the pixel centres' surface points, computed here from the camera.

Cycles is set to sample at the pixel centre: a box filter 0.01 pixel wide, no bounces,
no denoising; the Emission radiance is the colour (strength 1) in the linear EXR.
"""

from __future__ import annotations

import numpy as np

import bpy
from mathutils import Euler

from tests.blender import scenes
from tests.conftest import load_extension_package

photon_map = load_extension_package()
from photon_map.core.shading import program as pg  # noqa: E402
from photon_map.core.shading.inputs import ShadingInputs  # noqa: E402
from photon_map.core.shading.interpreter import evaluate  # noqa: E402
from photon_map.photon_engine.export_shader import compile_sockets  # noqa: E402
from photon_map.photon_engine.export_images import ProgramImageTable  # noqa: E402
from photon_map.photon_engine.export import object_info, read_attributes, read_mesh, \
    read_tangents, read_uv_maps  # noqa: E402
from photon_map.core.shading import light_path  # noqa: E402
from photon_map.photon_engine.export_shader import AttributeNames, UVMapNames  # noqa: E402
from photon_map.photon_engine.export_camera import camera_view  # noqa: E402

CELL = 2.0      # metres per plane (Blender's default plane)
PIXELS = 32     # pixels per plane side
OFF_CENTRE = 0.2
"""How far from the pixel centre (pixels) Cycles was measured to place an occasional
sample even with a FILTER-wide filter (about 0.15: 8 of 2048 pixels at 4 samples)."""
FILTER = 0.01   # Cycles' Gaussian filter width in pixels: samples land at the pixel centre


def emission_material(name, build):
    """A material Emission (strength 1) -> Material Output; ``build(tree, color_socket)``
    links a node graph into the Emission's Color."""
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    em = tree.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    tree.links.new(em.outputs[0], out.inputs["Surface"])
    build(tree, em.inputs["Color"])
    return mat


def layout(specs):
    """A fresh scene with one 2 m plane per (name, build) of ``specs`` (its material by
    ``emission_material``) on a square grid, row by row from the top left, and an
    orthographic camera above looking down at all of them.
    Returns (scene, [plane objects], grid side)."""
    scene = scenes.reset()
    materials = [emission_material(name, build) for name, build in specs]
    g = int(np.ceil(np.sqrt(len(materials))))
    planes = []
    for k, mat in enumerate(materials):
        row, col = divmod(k, g)
        loc = ((col - (g - 1) / 2) * CELL, ((g - 1) / 2 - row) * CELL, 0.0)
        planes.append(scenes.add_plane(size=CELL, location=loc, material=mat,
                                       name=f"Plane{k}"))
    cam_data = bpy.data.cameras.new("Ortho")
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = g * CELL
    cam = bpy.data.objects.new("Ortho", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, 0.0, 10.0)
    scene.camera = cam
    scenes.set_resolution(g * PIXELS, g * PIXELS)
    return scene, planes, g


def render_cycles(scene, samples=4) -> np.ndarray:
    """(H, W, 3) float32 linear radiance, row 0 at the top."""
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = samples
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.max_bounces = 0
    c.pixel_filter_type = 'GAUSSIAN'  # Cycles' box filter is always 1 pixel wide
    c.filter_width = FILTER
    scene.view_settings.view_transform = 'Standard'
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float32)


def plane_attributes(plane, obj, names) -> np.ndarray:
    """(A, N, 4): the exporter's corner attributes ``names`` of ``plane`` at the object-space
    points ``obj`` (N, 3) of its z = 0 face, interpolated over the triangle holding each
    point (barycentric, as the renderer interpolates per hit)."""
    local = read_mesh(plane.data)
    return _interpolate(local, read_attributes(plane.data, list(names), local, plane.name,
                                               []), obj)


def plane_uv_maps(plane, obj, names, warnings=None) -> np.ndarray:
    """(U, N, 2): the exporter's UV maps ``names`` (``export.read_uv_maps``) of ``plane``
    at the object-space points ``obj`` (N, 3), interpolated as ``plane_attributes``."""
    local = read_mesh(plane.data)
    maps = read_uv_maps(plane.data, list(names), local, plane.name, UVMapNames(names),
                        [] if warnings is None else warnings)
    return _interpolate(local, maps, obj)


def _interpolate(local, corners, obj) -> np.ndarray:
    """(A, N, C): corner values (T, 3, A, C) at the points obj (N, 3) of the z = 0 face."""
    names = range(corners.shape[2])
    out = np.zeros((corners.shape[2], len(obj), corners.shape[3]), np.float32)
    p = local.positions[local.triangles][..., :2]  # (T, 3, 2)
    for t in range(p.shape[0]):
        e1, e2 = p[t, 1] - p[t, 0], p[t, 2] - p[t, 0]
        m = np.linalg.inv(np.array([e1, e2]).T)
        uv = (obj[:, :2] - p[t, 0]) @ m.T
        w = 1.0 - uv[:, 0] - uv[:, 1]
        inside = (uv >= -1e-9).all(1) & (w >= -1e-9)
        for a in range(len(names)):
            c = corners[t, :, a]
            out[a, inside] = (w[inside, None] * c[0] + uv[inside, :1] * c[1]
                              + uv[inside, 1:] * c[2])
    return out


def plane_tangents(plane, obj, names) -> np.ndarray:
    """(G, N, 4): the exporter's MikkTSpace tangents of the UV maps ``names`` of ``plane``
    at the object-space points ``obj`` (N, 3), interpolated as ``plane_attributes`` and
    taken to the world by the plane's linear part (as ``export`` does)."""
    local = read_mesh(plane.data)
    tan = _interpolate(local, read_tangents(plane.data, list(names), local, plane.name, []),
                       obj)
    tan[..., :3] = tan[..., :3] @ np.array(plane.matrix_world, np.float64)[:3, :3].T
    return tan


def plane_inputs(plane, g, offset=(0.0, 0.0), attributes=(), uv_maps=(),
                 tangent_maps=()) -> ShadingInputs:
    """The surface points of ``plane``'s pixels (PIXELS x PIXELS, row 0 at the top),
    shifted by ``offset`` pixels: world position, normal +Z, incoming +Z, generated and
    object coordinates, the active render UV map interpolated (an affine fit of the
    plane's corners) then the named ``uv_maps`` as the exporter reads them, the
    exporter's Object Info of the plane's depsgraph instance, the mesh attributes
    ``attributes`` (names) as the exporter reads them, the tangents of ``tangent_maps``,
    the object's normal transform, and the Light Path context of the camera's rays (the
    orthographic camera straight above: Ray Length its height above the plane less the
    near clip distance, as both renderers start camera rays at the near plane)."""
    px = CELL / PIXELS
    lx, ly, _ = plane.location
    i = np.arange(PIXELS)
    x = lx - CELL / 2 + (i + 0.5 + offset[0]) * px
    y = ly + CELL / 2 - (i + 0.5 + offset[1]) * px
    X, Y = np.meshgrid(x, y)
    P = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    M = np.array(plane.matrix_world, np.float64)  # a plane may be rotated with its mesh
    obj = (P - M[:3, 3]) @ np.linalg.inv(M[:3, :3]).T  # counter-rotated (turn_mesh)
    mesh = plane.data
    tl, ts = np.array(mesh.texspace_location), np.array(mesh.texspace_size)
    gen = np.where(ts != 0, (obj - tl) / np.where(ts != 0, 2 * ts, 1) + 0.5, 0.5)
    co = np.array([mesh.vertices[lp.vertex_index].co[:] for lp in mesh.loops])
    uv_layer = next(u for u in mesh.uv_layers if u.active_render).data
    uvs = np.array([d.uv[:] for d in uv_layer])
    A = np.linalg.lstsq(np.c_[co, np.ones(len(co))], uvs, rcond=None)[0]
    uv = np.c_[obj, np.ones(len(obj))] @ A
    up = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    onrm = up @ M[:3, :3]  # Cycles' object_inverse_normal_transform: M^T n
    onrm /= np.linalg.norm(onrm, axis=1)[:, None]
    cam = bpy.context.scene.camera
    length = cam.location.z - float(plane.location.z) - cam.data.clip_start
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for inst in depsgraph.object_instances:  # an instance is valid only in its step
        if inst.object.name == plane.name:
            info = object_info(inst)
            break
    return ShadingInputs.build(P, up, incoming=up, generated=gen, object_coords=obj,
                               object_normal=onrm,
                               object_location=np.tile(plane.location, (len(P), 1)),
                               object_color=np.tile(info[:3], (len(P), 1)),
                               object_random=np.full(len(P), info[3]),
                               object_index=np.full(len(P), info[4]),
                               object_alpha=np.full(len(P), info[5]),
                               material_index=np.full(len(P), float(
                                   plane.data.materials[0].pass_index)),
                               uv=np.concatenate([uv[None].astype(np.float32),
                                                  plane_uv_maps(plane, obj, uv_maps)]),
                               attributes=plane_attributes(plane, obj, attributes),
                               tangents=plane_tangents(plane, obj, tangent_maps),
                               normal_to_world=np.broadcast_to(
                                   np.linalg.inv(M[:3, :3]).T, (len(P), 3, 3)),
                               light_path=light_path.camera([length])[0])


def turn_mesh(plane, rotation):
    """Rotate ``plane`` by the Euler angles ``rotation`` (radians) and its mesh by the
    inverse: the same surface in the world, seen from another side in object space (its
    object-space normal is R^-1 +Z)."""
    r = Euler(rotation).to_matrix().to_4x4()
    plane.data.transform(r.inverted())
    plane.data.update()
    plane.rotation_euler = rotation
    bpy.context.view_layer.update()


def compile_planes(planes):
    """[(plane, ShaderCompile of its Emission colour, the ProgramImages its Image
    Textures sample, the attribute names it reads, the UV maps it names, the UV maps
    whose tangents it reads)], and every
    warning (the image table's and the exporter's UV map reader's too)."""
    out, warnings = [], []
    view = camera_view(bpy.context.evaluated_depsgraph_get())
    for plane in planes:
        mat = plane.data.materials[0]
        em = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeEmission")
        table = ProgramImageTable(warnings)
        names, uv_maps, tangent_maps = AttributeNames(), UVMapNames(), AttributeNames()
        result = compile_sockets(mat, [(em.inputs["Color"], pg.TARGET_EMISSION, 0, 0)],
                                 uv_maps=uv_maps, images=table, attributes=names,
                                 view=view, tangent_maps=tangent_maps)
        warnings += result.warnings
        if uv_maps.names:
            local = read_mesh(plane.data)
            read_uv_maps(plane.data, uv_maps.names, local, f"object '{plane.name}'",
                         uv_maps, warnings)
        out.append((plane, result, table.images(), names.names, uv_maps.names,
                    tangent_maps.names))
    return out, warnings


def photon_map_image(planes, g, offset=(0.0, 0.0), compiled=None):
    """(H, W, 3) float32: each plane's compiled Emission colour at its pixels (shifted
    by ``offset`` pixels), and the compiler's warnings."""
    if compiled is None:
        compiled, warnings = compile_planes(planes)
    else:
        warnings = []
    img = np.zeros((g * PIXELS, g * PIXELS, 3), np.float32)
    for k, (plane, result, images, names, uv_maps, tangent_maps) in enumerate(compiled):
        if result.program is None:
            values = np.tile(np.array(result.constant[0], np.float32), (PIXELS * PIXELS, 1))
        else:
            values = evaluate(result.program, plane_inputs(plane, g, offset, names, uv_maps,
                                                            tangent_maps), images)
        row, col = divmod(k, g)
        img[row * PIXELS:(row + 1) * PIXELS, col * PIXELS:(col + 1) * PIXELS] = \
            values.reshape(PIXELS, PIXELS, 3)
    return img, warnings


def compare(specs, samples=4, jump=2e-2, setup=None):
    """Render the planes of ``specs`` ([(material name, build)], see ``layout``) by
    Cycles and Photon Map. Returns a dict: ``cycles``, ``ours`` (H, W, 3); ``error``
    (H, W): the worst channel's |difference| beyond our own value's variation within the
    filter's footprint (+-FILTER/2 pixel), over max(1, |cycles|); ``edge`` (H, W) bool where
    that variation exceeds ``jump`` (a discontinuity inside the footprint); ``loose_error``
    like ``error`` beyond the variation within +-OFF_CENTRE pixel; ``warnings``. Each
    variation is the largest change of our value over a 5 x 5 grid of offsets.
    ``setup(planes)``, if given, runs after the layout (object properties)."""
    scene, planes, g = layout(specs)
    if setup is not None:
        setup(planes)
    cycles = render_cycles(scene, samples)
    compiled, warnings = compile_planes(planes)
    ours, _ = photon_map_image(planes, g, compiled=compiled)
    scale = np.maximum(1.0, np.abs(cycles))
    out = {"cycles": cycles, "ours": ours, "warnings": warnings, "grid": g}
    for name, reach in (("error", FILTER / 2), ("loose_error", OFF_CENTRE)):
        steps = (-reach, -reach / 2, 0.0, reach / 2, reach)  # a 5 x 5 grid: thin features
        around = np.stack([photon_map_image(planes, g, (dx, dy), compiled)[0]
                           for dx in steps for dy in steps if dx or dy])
        spread = np.abs(around - ours).max(0)
        out[name] = (np.maximum(np.abs(cycles - ours) - spread, 0.0) / scale).max(-1)
        if name == "error":
            # a jump inside the footprint, or the exact centre on a lattice boundary (a
            # checker corner: our float64 point is on it, Cycles' float32 one is not)
            isolated = np.abs(ours - np.median(around, 0))
            out["edge"] = (np.maximum(spread, isolated) / scale).max(-1) > jump
    return out


def per_plane(result, fn):
    """[fn(error block, edge block, loose error block)] for each plane of a compare()
    result."""
    g = result["grid"]
    out = []
    for row in range(g):
        for col in range(g):
            s = np.s_[row * PIXELS:(row + 1) * PIXELS, col * PIXELS:(col + 1) * PIXELS]
            out.append(fn(result["error"][s], result["edge"][s], result["loose_error"][s]))
    return out

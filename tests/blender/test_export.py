"""photon_engine/export.py against Blender itself: tiny scenes exported through a render
depsgraph (a probe RenderEngine calls ``export_scene`` inside ``bpy.ops.render.render``,
exactly where the real engine does), checked against bpy's own answers (mathutils
transforms, ``world_to_camera_view``) or against hand-computed values.
"""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Vector  # noqa: E402

from tests.blender import export_probe, scenes  # noqa: E402
from tests.conftest import load_extension_package  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

photon_map = load_extension_package()
from photon_map.core.scene import closures as cl  # noqa: E402
from photon_map.core.scene import contract as core_scene  # noqa: E402
from photon_map.photon_engine.compat import ensure_node_tree  # noqa: E402
from photon_map.photon_engine.export import ExportError, NoCameraError, export_scene  # noqa: E402


ORIGIN = np.zeros(3)  # world coordinates, to check against bpy's own (test_render_origin)


def export(scene=None):
    """Export ``scene`` through a real render depsgraph with the world origin (ORIGIN);
    returns the ExportResult."""
    return export_probe.export(scene, origin=ORIGIN)


def basic_scene(width=32, height=24):
    scene = scenes.reset()
    scenes.set_resolution(width, height)
    scenes.add_camera(location=(0.0, -6.0, 2.0))
    return scene


def world_vertices_oracle(obj):
    """World positions of the evaluated mesh, computed by mathutils (not numpy)."""
    ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mw = ev.matrix_world
    return np.array([tuple(mw @ v.co) for v in ev.data.vertices])


def triangle_corners(mesh, names=None):
    """(T, 3, 3) world corners of the exported triangles, optionally of some objects only."""
    tri = mesh.triangle_vertices().astype(np.float64)
    if names is None:
        return tri
    ids = [i for i, n in enumerate(mesh.object_names) if n in names]
    return tri[np.isin(mesh.object_index, ids)]


# Geometry ---------------------------------------------------------------------------------

def test_transformed_modified_mesh_matches_blender_positions():
    basic_scene()
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    cube = bpy.context.active_object
    cube.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    cube.modifiers["Subdivision"].render_levels = 1
    cube.modifiers.new("Array", 'ARRAY').count = 2
    cube.location = (0.3, -0.2, 1.5)
    cube.rotation_euler = (0.3, 0.5, 1.1)
    cube.scale = (2.0, 1.0, 0.5)
    mesh = export().scene.mesh
    # A cube's 6 quads subdivide into 24, i.e. 48 triangles, twice for the array.
    assert mesh.triangle_count == 96
    exported = mesh.vertices.astype(np.float64)
    oracle = world_vertices_oracle(cube)
    assert exported.shape == oracle.shape
    # Same point set: every oracle vertex has an exported twin (float32 precision).
    d = np.linalg.norm(exported[:, None, :] - oracle[None, :, :], axis=2)
    assert d.min(axis=0).max() < 1e-5 and d.min(axis=1).max() < 1e-5


def test_collection_instances_are_exported_with_their_transform():
    basic_scene()
    coll = bpy.data.collections.new("Props")
    bpy.context.scene.collection.children.link(coll)
    mesh = bpy.data.meshes.new("Tri")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    tri = bpy.data.objects.new("Tri", mesh)
    coll.objects.link(tri)
    for i, x in enumerate((5.0, 10.0)):
        empty = bpy.data.objects.new(f"Inst{i}", None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = coll
        empty.location = (x, 0.0, 0.0)
        empty.scale = (2.0, 2.0, 2.0)
        bpy.context.scene.collection.objects.link(empty)
    out = export().scene.mesh
    assert out.triangle_count == 3
    corners = np.sort(out.triangle_vertices()[:, 0, 0])
    np.testing.assert_allclose(corners, [0.0, 5.0, 10.0], atol=1e-6)
    # The instances are scaled by 2: legs of length 2.
    legs = out.triangle_vertices()[:, 1] - out.triangle_vertices()[:, 0]
    np.testing.assert_allclose(np.sort(np.linalg.norm(legs, axis=1)), [1.0, 2.0, 2.0], atol=1e-6)


def _instance_on_points_tree(count):
    tree = bpy.data.node_groups.new("Scatter", 'GeometryNodeTree')
    tree.interface.new_socket(name="Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = tree.nodes, tree.links
    line = nodes.new('GeometryNodeMeshLine')
    line.inputs["Count"].default_value = count
    line.inputs["Offset"].default_value = (1.0, 0.0, 0.0)
    cube = nodes.new('GeometryNodeMeshCube')
    inst = nodes.new('GeometryNodeInstanceOnPoints')
    out = nodes.new('NodeGroupOutput')
    links.new(line.outputs["Mesh"], inst.inputs["Points"])
    links.new(cube.outputs["Mesh"], inst.inputs["Instance"])
    links.new(inst.outputs["Instances"], out.inputs["Geometry"])
    return tree


def test_geometry_nodes_instances_are_counted():
    basic_scene()
    host = scenes.add_plane(size=1.0, name="Host")
    host.modifiers.new("Scatter", 'NODES').node_group = _instance_on_points_tree(5)
    out = export().scene.mesh
    assert out.triangle_count == 5 * 12  # five cubes, the host plane replaced by the tree
    # Mesh Line spaces the points 1 m apart along +X: five distinct cube centres.
    centres = out.triangle_vertices().reshape(5, 12 * 3, 3).mean(axis=1)
    np.testing.assert_allclose(np.sort(centres[:, 0]), np.arange(5.0), atol=1e-5)


def test_particle_instances_are_exported():
    basic_scene()
    scenes.add_plane(size=2.0, name="Emitter")
    emitter = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=0.1, location=(0.0, 0.0, -10.0))
    cube = bpy.context.active_object
    cube.name = "Grain"
    emitter.modifiers.new("Particles", 'PARTICLE_SYSTEM')
    settings = emitter.particle_systems[0].settings
    settings.type = 'HAIR'
    settings.count = 7
    settings.render_type = 'OBJECT'
    settings.instance_object = cube
    out = export().scene.mesh
    names = np.array(out.object_names)
    tris_per_instance = np.bincount(out.object_index, minlength=len(names))
    grains = names == "Emitter/Grain"
    assert np.count_nonzero(grains) == 7 and np.all(tris_per_instance[grains] == 12)
    # The emitter (shown by default) and the original cube are there too.
    assert tris_per_instance[list(names).index("Emitter")] == 2
    assert tris_per_instance[list(names).index("Grain")] == 12


def test_curves_text_and_metaballs_are_exported_as_meshes():
    basic_scene()
    bpy.ops.object.text_add(location=(3.0, 0.0, 0.0))
    bpy.ops.curve.primitive_bezier_circle_add(location=(-3.0, 0.0, 0.0))
    bpy.context.active_object.data.bevel_depth = 0.1
    bpy.ops.object.metaball_add(location=(0.0, 3.0, 0.0))
    bpy.ops.curve.primitive_bezier_curve_add(location=(0.0, -3.0, 0.0))  # no bevel: no faces
    mesh = export().scene.mesh
    counts = {name: int(np.count_nonzero(mesh.object_index == i))
              for i, name in enumerate(mesh.object_names)}
    assert set(counts) == {"Text", "BézierCircle", "Mball"}
    assert all(n > 50 for n in counts.values())


def test_hidden_objects_are_left_out():
    basic_scene()
    visible = scenes.add_plane(name="Visible")
    scenes.add_plane(name="NoRender", location=(0, 0, 1)).hide_render = True
    viewport_hidden = scenes.add_plane(name="ViewportHidden", location=(0, 0, 2))
    viewport_hidden.hide_viewport = True  # still rendered, as in Cycles
    invisible = scenes.add_plane(name="NoRays", location=(0, 0, 3))
    for flag in ("visible_camera", "visible_diffuse", "visible_glossy",
                 "visible_transmission", "visible_shadow"):
        setattr(invisible, flag, False)
    hidden_coll = bpy.data.collections.new("HiddenColl")
    bpy.context.scene.collection.children.link(hidden_coll)
    hidden_coll.hide_render = True
    in_hidden = scenes.add_plane(name="InHiddenColl", location=(0, 0, 4))
    for c in in_hidden.users_collection:
        c.objects.unlink(in_hidden)
    hidden_coll.objects.link(in_hidden)
    assert visible.visible_camera
    result = export()
    assert set(result.scene.mesh.object_names) == {"Visible", "ViewportHidden"}
    assert result.scene.mesh.triangle_count == 4


def test_zero_area_triangles_are_dropped():
    basic_scene()
    mesh = bpy.data.meshes.new("Degenerate")
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]
    mesh.from_pydata(verts, [], [(0, 1, 2), (3, 4, 5), (0, 1, 3)])  # two collinear
    obj = bpy.data.objects.new("Degenerate", mesh)
    bpy.context.scene.collection.objects.link(obj)
    out = export().scene.mesh
    assert out.triangle_count == 1
    assert np.all(np.isfinite(out.normals))


def test_normals_and_uvs():
    basic_scene()
    sphere = scenes.add_sphere(radius=0.5, location=(1.0, 2.0, 3.0), segments=16, name="Ball")
    sphere.scale = (1.0, 1.0, -1.0)  # mirrored: winding must be flipped back
    plane = scenes.add_plane(size=2.0, location=(0.0, 0.0, -2.0), name="Floor")
    nouv = scenes.add_plane(size=2.0, location=(0.0, 0.0, -4.0), name="NoUV")
    nouv.data.uv_layers.remove(nouv.data.uv_layers[0])
    mesh = export().scene.mesh
    t = mesh.triangle_count
    assert mesh.normals.shape == (t, 3, 3) and mesh.uvs.shape == (t, 3, 2)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=2), 1.0, atol=1e-5)
    ball = np.isin(mesh.object_index, [mesh.object_names.index("Ball")])
    corners = mesh.triangle_vertices()[ball].astype(np.float64)
    # Smooth normals of a sphere point away from its centre ...
    outward = np.einsum("tcj,tcj->tc", mesh.normals[ball], corners - (1.0, 2.0, 3.0))
    assert np.all(outward > 0)
    # ... and the winding (geometric normal) agrees with them despite the mirroring.
    geo = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.all(np.einsum("tj,tj->t", geo, mesh.normals[ball].mean(axis=1)) > 0)
    floor = mesh.object_index == mesh.object_names.index("Floor")
    uv = mesh.uvs[floor]
    xy = mesh.triangle_vertices()[floor][..., :2]
    # Blender's plane maps x, y in [-1, 1] to u, v in [0, 1].
    np.testing.assert_allclose(uv, (xy + 1.0) / 2.0, atol=1e-6)
    np.testing.assert_array_equal(mesh.uvs[mesh.object_index == mesh.object_names.index("NoUV")], 0.0)


def test_nan_transform_is_a_clear_error():
    basic_scene()
    scenes.add_plane(name="Broken").location = (float("nan"), 0.0, 0.0)
    with pytest.raises(ExportError, match="Broken.*non-finite"):
        export()


def test_no_camera_is_a_clear_error():
    # Blender refuses F12 without a camera; the CLI and viewport paths reach the exporter.
    scenes.reset()
    scenes.add_plane()
    with pytest.raises(NoCameraError, match="no active camera"):
        export_scene(bpy.context.evaluated_depsgraph_get())


# Materials --------------------------------------------------------------------------------

def node_material(name, idname, **inputs):
    mat = bpy.data.materials.new(name)
    nodes = ensure_node_tree(mat).nodes
    nodes.clear()
    node = nodes.new(idname)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    out = nodes.new('ShaderNodeOutputMaterial')
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat, node


def export_materials(*mats):
    """Export one plane per material (made after ``basic_scene()``); rows in that order."""
    for i, mat in enumerate(mats):
        scenes.add_plane(size=1.0, location=(2.0 * i, 0.0, 0.0), material=mat, name=f"P{i}")
    result = export()
    m = result.scene.materials
    mesh = result.scene.mesh
    rows = []
    for i in range(len(mats)):
        idx = mesh.material_index[mesh.object_index == mesh.object_names.index(f"P{i}")]
        assert np.all(idx == idx[0])
        t = m.closure_table()
        first, count = t["first"][idx[0]], t["count"][idx[0]]
        rows.append({k: getattr(m, k)[idx[0]] for k in
                     ("diffuse", "specular", "transmission", "emission", "roughness", "ior")}
                    | {"name": m.names[idx[0]],
                       "program": None if m.programs is None else m.programs[idx[0]],
                       "closures": [{"params": p} for p in t["params"][first:first + count]]})
    return rows, result.warnings


def test_shader_nodes_map_to_lobes():
    basic_scene()
    principled, _ = node_material(
        "Principled", 'ShaderNodeBsdfPrincipled', **{
            "Base Color": (0.5, 0.4, 0.2, 1.0), "Metallic": 0.25, "Roughness": 0.3,
            "Transmission Weight": 0.4, "IOR": 1.33, "Emission Color": (1.0, 0.5, 0.0, 1.0),
            "Emission Strength": 3.0})
    diffuse, _ = node_material("Diffuse", 'ShaderNodeBsdfDiffuse', Color=(0.1, 0.2, 0.3, 1.0))
    glossy, _ = node_material("Glossy", 'ShaderNodeBsdfGlossy', Color=(0.9, 0.8, 0.7, 1.0), Roughness=0.0)
    glass, _ = node_material("Glass", 'ShaderNodeBsdfGlass', Color=(1.0, 0.9, 1.0, 1.0), IOR=1.5, Roughness=0.1)
    emission, _ = node_material("Lamp", 'ShaderNodeEmission', Color=(1.0, 0.5, 0.25, 1.0), Strength=4.0)
    rows, warnings = export_materials(principled, diffuse, glossy, glass, emission)
    assert warnings == []
    p, d, g, gl, e = rows
    base = np.array([0.5, 0.4, 0.2])
    np.testing.assert_allclose(p["diffuse"], base * 0.75 * 0.6, rtol=1e-6)
    np.testing.assert_allclose(p["specular"], base * 0.25, rtol=1e-6)
    np.testing.assert_allclose(p["transmission"], base * 0.75 * 0.4, rtol=1e-6)
    np.testing.assert_allclose(p["emission"], [3.0, 1.5, 0.0], rtol=1e-6)
    assert p["roughness"] == pytest.approx(0.3) and p["ior"] == pytest.approx(1.33)
    np.testing.assert_allclose(d["diffuse"], [0.1, 0.2, 0.3], rtol=1e-6)
    assert not d["specular"].any() and not d["transmission"].any() and not d["emission"].any()
    np.testing.assert_allclose(g["specular"], [0.9, 0.8, 0.7], rtol=1e-6)
    assert g["roughness"] == 0.0 and not g["diffuse"].any()
    np.testing.assert_allclose(gl["transmission"], [1.0, 0.9, 1.0], rtol=1e-6)
    assert gl["ior"] == pytest.approx(1.5) and gl["roughness"] == pytest.approx(0.1)
    np.testing.assert_allclose(e["emission"], [4.0, 2.0, 1.0], rtol=1e-6)
    assert not e["diffuse"].any()
    assert [r["name"] for r in rows] == ["Principled", "Diffuse", "Glossy", "Glass", "Lamp"]


def test_mix_and_add_shaders():
    basic_scene()
    mat = bpy.data.materials.new("Mixed")
    ensure_node_tree(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    diff = nodes.new('ShaderNodeBsdfDiffuse')
    diff.inputs["Color"].default_value = (0.8, 0.0, 0.0, 1.0)
    gloss = nodes.new('ShaderNodeBsdfGlossy')
    gloss.inputs["Color"].default_value = (0.0, 0.0, 1.0, 1.0)
    gloss.inputs["Roughness"].default_value = 0.2
    mix = nodes.new('ShaderNodeMixShader')
    mix.inputs["Fac"].default_value = 0.25
    emit = nodes.new('ShaderNodeEmission')
    emit.inputs["Strength"].default_value = 2.0
    add = nodes.new('ShaderNodeAddShader')
    out = nodes.new('ShaderNodeOutputMaterial')
    links.new(diff.outputs[0], mix.inputs[1])
    links.new(gloss.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], add.inputs[0])
    links.new(emit.outputs[0], add.inputs[1])
    links.new(add.outputs[0], out.inputs["Surface"])
    (row,), warnings = export_materials(mat)
    assert warnings == []
    np.testing.assert_allclose(row["diffuse"], [0.6, 0.0, 0.0], rtol=1e-6)
    np.testing.assert_allclose(row["specular"], [0.0, 0.0, 0.25], rtol=1e-6)
    np.testing.assert_allclose(row["emission"], [2.0, 2.0, 2.0], rtol=1e-6)
    assert row["roughness"] == pytest.approx(0.2)


def test_unreadable_tree_gives_one_warning_and_grey():
    basic_scene()
    toon, _ = node_material("Cartoon", 'ShaderNodeBsdfToon', Color=(1.0, 0.0, 0.0, 1.0))
    (row,), warnings = export_materials(toon)
    assert len(warnings) == 1 and "Cartoon" in warnings[0] and "Toon" in warnings[0]
    np.testing.assert_allclose(row["diffuse"], [0.8, 0.8, 0.8], rtol=1e-6)
    assert not row["specular"].any() and not row["emission"].any()


def test_linked_input_becomes_a_shader_program():
    # A Checker into Color: the closure's COLOR comes from the material's program at each
    # hit (issue 14); the row keeps the socket value as its constant.
    basic_scene()
    mat, bsdf = node_material("Textured", 'ShaderNodeBsdfDiffuse', Color=(0.2, 0.4, 0.6, 1.0))
    tex = mat.node_tree.nodes.new('ShaderNodeTexChecker')
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    (row,), warnings = export_materials(mat)
    assert warnings == []
    np.testing.assert_allclose(row["diffuse"], [0.2, 0.4, 0.6], rtol=1e-6)
    prog = row["program"]
    assert prog is not None
    assert sorted(prog.outputs[:, 3].tolist()) == [0, 1, 2]  # the COLOR slots of closure 0
    assert set(prog.outputs[:, 1].tolist()) == {0} and set(prog.outputs[:, 2].tolist()) == {0}


def test_linked_input_from_an_unsupported_node_takes_its_output_default_with_a_warning():
    # docs/shading.md: an unsupported node is reported by material and node name and its
    # output takes the socket's default value (Wireframe's Fac: 0), folded into the closure.
    basic_scene()
    mat, bsdf = node_material("Wired", 'ShaderNodeBsdfDiffuse', Color=(0.2, 0.4, 0.6, 1.0))
    wire = mat.node_tree.nodes.new('ShaderNodeWireframe')
    mat.node_tree.links.new(wire.outputs[0], bsdf.inputs["Color"])
    (row,), warnings = export_materials(mat)
    assert len(warnings) == 1 and "Wired" in warnings[0] and "Wireframe" in warnings[0]
    assert row["program"] is None
    np.testing.assert_array_equal(row["closures"][0]["params"][cl.COLOR:cl.COLOR + 3], 0.0)


def test_empty_slot_and_slot_indices():
    basic_scene()
    red = scenes.diffuse_material("Red", (0.8, 0.1, 0.1))
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.active_object
    cube.data.materials.append(None)  # slot 0 empty -> default grey
    cube.data.materials.append(red)
    cube.data.polygons.foreach_set("material_index", [0, 1, 1, 0, 1, 0])
    result = export()
    m, mesh = result.scene.materials, result.scene.mesh
    idx = mesh.material_index.reshape(6, 2)[:, 0]  # two triangles per quad, in order
    diffuse = m.diffuse[idx]
    np.testing.assert_allclose(diffuse[[0, 3, 5]], 0.8, rtol=1e-6)
    np.testing.assert_allclose(diffuse[[1, 2, 4]], [[0.8, 0.1, 0.1]] * 3, rtol=1e-6)
    assert m.count == 2  # deduplicated


# Lights -----------------------------------------------------------------------------------

def test_lights_of_every_kind():
    basic_scene()
    point = scenes.add_light('POINT', location=(1, 2, 3), power=100.0, color=(1.0, 0.5, 0.25),
                             shadow_soft_size=0.2, use_soft_falloff=False, name="Point")
    point.visible_glossy = False
    # Light exposure (2^exposure x power) is newer than 4.2: there, 100 W directly.
    exposure = {"exposure": 1.0} if "exposure" in bpy.types.Light.bl_rna.properties else {}
    spot = scenes.add_light('SPOT', location=(0, 0, 4), power=50.0 if exposure else 100.0,
                            spot_size=0.8, spot_blend=0.3, shadow_soft_size=0.0, name="Spot",
                            **exposure)
    spot.scale = (3.0, 3.0, 3.0)
    scenes.add_light('SUN', power=3.0, angle=0.1, rotation=(0.5, 0.0, 0.0), name="Sun",
                     use_shadow=False)
    square = scenes.add_light('AREA', location=(0, 0, 2), power=20.0, shape='SQUARE', size=0.5,
                              name="Square")
    square.scale = (2.0, 3.0, 1.0)
    square.visible_camera = True
    scenes.add_light('AREA', power=20.0, shape='RECTANGLE', size=0.5, size_y=0.25, name="Rect")
    scenes.add_light('AREA', power=20.0, shape='DISK', size=0.4, name="Disk")
    # "Normalize" (power per unit area when off) is newer than 4.2 too.
    normalize = "normalize" in bpy.types.Light.bl_rna.properties
    scenes.add_light('AREA', power=20.0, shape='ELLIPSE', size=0.4, size_y=0.1, name="Ellipse",
                     **({"normalize": False} if normalize else {}))
    result = export()
    li = result.scene.lights
    assert result.warnings == []
    row = {name: i for i, name in enumerate(li.names)}
    k = core_scene
    assert [li.kind[row[n]] for n in ("Point", "Spot", "Sun", "Square", "Rect", "Disk", "Ellipse")] == \
        [k.LIGHT_POINT, k.LIGHT_SPOT, k.LIGHT_SUN] + [k.LIGHT_AREA] * 4
    p = row["Point"]
    assert li.power[p] == pytest.approx(100.0) and li.radius[p] == pytest.approx(0.2)
    np.testing.assert_allclose(li.color[p], [1.0, 0.5, 0.25])
    np.testing.assert_allclose(li.to_world[p][:3, 3], [1, 2, 3])
    s = row["Spot"]
    assert li.power[s] == pytest.approx(100.0)  # exposure 1 doubles the power
    assert li.spot_size[s] == pytest.approx(0.8) and li.spot_blend[s] == pytest.approx(0.3)
    np.testing.assert_allclose(li.to_world[s][:3, :3], np.eye(3), atol=1e-7)  # scale removed
    sun = row["Sun"]
    assert li.power[sun] == pytest.approx(3.0) and li.angle[sun] == pytest.approx(0.1)
    assert not li.cast_shadow[sun] and li.cast_shadow[p]
    # The sun is rotated by 0.5 rad about X: it shines along its local -Z.
    np.testing.assert_allclose(-li.to_world[sun][:3, 2], [0.0, math.sin(0.5), -math.cos(0.5)], atol=1e-6)
    sq = row["Square"]
    np.testing.assert_allclose(li.size[sq], [1.0, 1.5])  # size x object scale
    assert li.shape[sq] == k.AREA_RECTANGLE and li.visible_to_camera[sq]
    assert not li.visible_to_camera[p]  # Blender 5: lights are invisible to the camera
    assert not li.visible_to_glossy[p] and li.visible_to_glossy[sq]
    assert li.visible_to_diffuse[p] and li.visible_to_transmission[p]
    assert not li.soft_falloff[p] and li.soft_falloff[s]
    np.testing.assert_allclose(li.size[row["Rect"]], [0.5, 0.25])
    np.testing.assert_allclose(li.size[row["Disk"]], [0.4, 0.4])
    assert li.shape[row["Disk"]] == k.AREA_ELLIPSE and li.shape[row["Ellipse"]] == k.AREA_ELLIPSE
    # Normalize off: 20 W per square metre of an ellipse with axes 0.4 x 0.1.
    area = math.pi / 4 * 0.4 * 0.1 if normalize else 1.0
    assert li.power[row["Ellipse"]] == pytest.approx(20.0 * area, rel=1e-5)


# Camera -----------------------------------------------------------------------------------

CAMERA_CASES = [
    # (resolution, percentage, pixel aspect, sensor fit, ortho, shift)
    ((64, 48), 100, (1, 1), 'AUTO', False, (0.0, 0.0)),
    ((48, 64), 100, (1, 1), 'AUTO', False, (0.1, -0.2)),
    ((64, 48), 50, (1, 1), 'VERTICAL', False, (0.0, 0.3)),
    ((48, 64), 100, (1, 1), 'HORIZONTAL', False, (0.2, 0.0)),
    ((64, 48), 100, (1, 2), 'AUTO', False, (0.0, 0.0)),
    ((40, 60), 100, (3, 1), 'AUTO', False, (0.1, 0.1)),
    ((64, 48), 100, (1, 1), 'AUTO', True, (0.25, 0.0)),
    ((48, 64), 100, (2, 1), 'VERTICAL', True, (0.0, -0.1)),
]


@pytest.mark.parametrize("res, pct, aspect, fit, ortho, shift", CAMERA_CASES)
def test_camera_rays_hit_the_pixels_blender_projects_to(res, pct, aspect, fit, ortho, shift):
    scene = scenes.reset()
    scenes.set_resolution(*res, percentage=pct)
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = aspect
    cam_obj = scenes.add_camera(location=(1.0, -5.0, 2.0), look_at=(0.0, 0.0, 0.5), lens=35.0,
                                ortho_scale=3.0 if ortho else None)
    cam_obj.scale = (1.5, 1.5, 1.5)  # must not change the picture
    cam = cam_obj.data
    cam.sensor_fit, cam.sensor_width, cam.sensor_height = fit, 32.0, 20.0
    cam.shift_x, cam.shift_y = shift
    c = export().scene.camera
    assert (c.width, c.height) == (res[0] * pct // 100, res[1] * pct // 100)
    assert c.kind == (core_scene.CAMERA_ORTHOGRAPHIC if ortho else core_scene.CAMERA_PERSPECTIVE)
    # Rays through pixel centres (the contract's definition), projected back by Blender.
    cols, rows = np.meshgrid([0, c.width // 3, c.width - 1], [0, c.height // 2, c.height - 1])
    fx = (cols.ravel() + 0.5) / c.width
    fy = (rows.ravel() + 0.5) / c.height
    x = (fx - 0.5) * c.film_size[0] + c.film_shift[0]
    y = (0.5 - fy) * c.film_size[1] + c.film_shift[1]
    m = c.to_world
    np.testing.assert_allclose(np.linalg.norm(m[:3, :3], axis=0), 1.0)
    if ortho:
        points = m[:3, 3] + x[:, None] * m[:3, 0] + y[:, None] * m[:3, 1] - 4.0 * m[:3, 2]
    else:
        d = x[:, None] * m[:3, 0] + y[:, None] * m[:3, 1] - m[:3, 2]
        points = m[:3, 3] + 4.0 * d
    for p, u, v in zip(points, fx, fy):
        proj = world_to_camera_view(scene, cam_obj, Vector(p))
        assert proj.x == pytest.approx(u, abs=1e-6) and proj.y == pytest.approx(1.0 - v, abs=1e-6)
    assert c.clip_start == pytest.approx(cam.clip_start) and c.clip_end == pytest.approx(cam.clip_end)


# World ------------------------------------------------------------------------------------

def test_world_background():
    scene = basic_scene()
    assert export().scene.world.radiance.tolist() == [0.0, 0.0, 0.0]  # no world: black
    scene.world = bpy.data.worlds.new("Default")
    bg = ensure_node_tree(scene.world).nodes["Background"]
    default = np.array(bg.inputs["Color"].default_value[:3]) * bg.inputs["Strength"].default_value
    w = export().scene.world
    # Blender 5's new world is a 0.05 grey background, visible to the camera.
    np.testing.assert_allclose(w.radiance, default, rtol=1e-6)
    np.testing.assert_allclose(w.radiance, 0.05, atol=0.002)
    assert w.visible_to_camera
    bg.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    scene.world.cycles_visibility.camera = False
    w = export().scene.world
    np.testing.assert_allclose(w.radiance, [0.2, 0.4, 0.6], rtol=1e-6)
    assert not w.visible_to_camera


def test_unreadable_world_falls_back_to_its_colour():
    scene = basic_scene()
    scene.world = bpy.data.worlds.new("Odd")
    ensure_node_tree(scene.world)
    scene.world.color = (0.3, 0.2, 0.1)
    nodes = scene.world.node_tree.nodes
    holdout = nodes.new('ShaderNodeHoldout')
    scene.world.node_tree.links.new(holdout.outputs[0], nodes["World Output"].inputs["Surface"])
    result = export()
    assert len(result.warnings) == 1 and "Odd" in result.warnings[0]
    np.testing.assert_allclose(result.scene.world.radiance, [0.3, 0.2, 0.1], rtol=1e-6)

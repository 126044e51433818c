"""The Attribute node's Object, Instancer and View Layer types against Cycles through
emission: planes whose Emission colour is a property of the object (a custom property on
the object, on its mesh only, on both: the object's wins; an RNA path, Object.color; a
missing one: 0), of the instancer (a plane that is no instance falls back to the object),
or of the view layer / scene, through the whole exporter and renderer (the values cross
the contract as per-object mesh attributes). And Geometry Pointiness on a bumpy grid."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes, shader_scenes as ss  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.blender.test_shader_nodes import link, node  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]


def attribute(kind, name, output="Color"):
    def build(tree, color):
        n = node(tree, "ShaderNodeAttribute", attribute_name=name, attribute_type=kind)
        if output == "Color":
            link(tree, n.outputs["Color"], color)
        else:
            comb = node(tree, "ShaderNodeCombineColor")
            for i in range(3):
                link(tree, n.outputs[output], comb.inputs[i])
            link(tree, comb.outputs[0], color)
    return build


SPECS = [("obj", attribute("OBJECT", "tint")), ("data", attribute("OBJECT", "tint")),
         ("both", attribute("OBJECT", "tint", "Fac")), ("rna", attribute("OBJECT", "color")),
         ("missing", attribute("OBJECT", "nothing")),
         ("instancer", attribute("INSTANCER", "tint", "Alpha")),
         ("layer", attribute("VIEW_LAYER", "glow")),
         ("scene", attribute("VIEW_LAYER", "glow2", "Fac")),
         ("int", attribute("OBJECT", "level"))]

EXPECTED = [(0.2, 0.5, 0.9), (0.3, 0.3, 0.3), (0.7,) * 3, (0.1, 0.6, 0.3), (0.0,) * 3,
            (0.25,) * 3, (0.4, 0.2, 0.1), (0.25,) * 3, (2.0,) * 3]
"""Each plane's colour, written out: obj["tint"] a 3-array; the mesh's 0.3; the object's
0.7 over the mesh's 0.1 (Fac = the mean); Object.color; 0; the instancer's (the object's)
alpha 0.25 of a 4-array; the view layer's 3-array; the scene's 0.25; an int 2."""


def setup(planes):
    p = planes
    p[0]["tint"] = (0.2, 0.5, 0.9)
    p[1].data["tint"] = 0.3
    p[2]["tint"], p[2].data["tint"] = 0.7, 0.1
    p[3].color = (0.1, 0.6, 0.3, 1.0)
    p[5]["tint"] = (0.9, 0.9, 0.9, 0.25)
    p[8]["level"] = 2
    bpy.context.view_layer["glow"] = (0.4, 0.2, 0.1)
    bpy.context.scene["glow2"] = 0.25


def test_object_instancer_and_view_layer_attributes_match_cycles():
    scene, planes, g = ss.layout(SPECS)
    setup(planes)
    cycles = ss.render_cycles(scene)
    exported = export(scene)
    assert [w for w in exported.warnings if "not found" in w] == [
        "Object 'Plane4': property 'nothing' of an Attribute node (object) not found; 0 is "
        "used, as Cycles"], exported.warnings
    scenes.use_photon_map(scene, samples=1, global_photons=1000, caustic_photons=100,
                          final_gather_rays=1)
    ours = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    n = ss.PIXELS
    for k, want in enumerate(EXPECTED):
        row, col = divmod(k, g)
        s = np.s_[row * n + 4:(row + 1) * n - 4, col * n + 4:(col + 1) * n - 4]
        a, b = ours[s].reshape(-1, 3), cycles[s].reshape(-1, 3)
        err = np.abs(a - b).max() / max(1.0, np.abs(b).max())
        print(f"{SPECS[k][0]}: ours {a.mean(0).round(5)}, Cycles {b.mean(0).round(5)}, worst "
              f"pixel {err:.2e}")
        np.testing.assert_allclose(b, np.broadcast_to(want, b.shape), atol=1e-3)
        assert err < 1e-3, SPECS[k][0]


def bumpy_grid(material, n=8, size=2.0, height=0.15):
    """An n x n quad grid of side ``size`` whose inner vertices are raised at random by up
    to ``height`` (pointiness then varies from vertex to vertex)."""
    rng = np.random.default_rng(3)
    xs = np.linspace(-size / 2, size / 2, n + 1)
    verts = [(x, y, 0.0) for y in xs for x in xs]
    z = rng.uniform(-height, height, (n + 1, n + 1))
    z[[0, -1], :] = 0.0
    z[:, [0, -1]] = 0.0
    verts = [(x, y, float(z[j, i])) for j, y in enumerate(xs) for i, x in enumerate(xs)]
    faces = [(j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
              (j + 1) * (n + 1) + i) for j in range(n) for i in range(n)]
    me = bpy.data.meshes.new("Bumpy")
    me.from_pydata(verts, [], faces)
    me.update()
    me.materials.append(material)
    obj = bpy.data.objects.new("Bumpy", me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_geometry_pointiness_matches_cycles():
    """Emission = Pointiness on a bumpy grid seen from above: Cycles' per-vertex curvature
    (export.pointiness), interpolated over each triangle."""
    def pointy(tree, color):
        geo = node(tree, "ShaderNodeNewGeometry")
        comb = node(tree, "ShaderNodeCombineColor")
        for i in range(3):
            link(tree, geo.outputs["Pointiness"], comb.inputs[i])
        link(tree, comb.outputs[0], color)
    scene, planes, g = ss.layout([("Pointiness", pointy)])
    material = planes[0].data.materials[0]
    bpy.data.objects.remove(planes[0])
    bumpy_grid(material)
    ss.render_cycles(scene)  # Cycles' settings; then its box filter, as ours (a pixel)
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.samples = 256
    cycles = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    exported = export(scene)
    assert not [w for w in exported.warnings if "Pointiness" in w], exported.warnings
    # 256 samples per pixel in both: each pixel's mean over its area
    scenes.use_photon_map(scene, samples=256, global_photons=1000, caustic_photons=100,
                          final_gather_rays=1)
    ours = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    a, b = ours[2:-2, 2:-2], cycles[2:-2, 2:-2]
    err = np.abs(a - b).max(-1) / np.maximum(np.abs(b).max(-1), 1e-3)
    print(f"pointiness: range {b.min():.4f} to {b.max():.4f}; relative error 99th "
          f"percentile {np.percentile(err, 99):.2e}, max {err.max():.2e}")
    assert b.max() - b.min() > 0.05
    assert np.percentile(err, 99) < 1e-3


def test_an_instancer_attribute_reads_the_collection_instance_parent():
    """A plane in a collection instanced by two empties (each covering half the view):
    Instancer "tint" reads each empty's property, not the plane's own, in both
    renderers."""
    scene, planes, g = ss.layout([("instanced", attribute("INSTANCER", "tint"))])
    plane = planes[0]
    scene.collection.objects.unlink(plane)
    plane["tint"] = (0.9, 0.1, 0.1)  # the fallback: not read by an instance
    inner = bpy.data.collections.new("Inner")
    inner.objects.link(plane)
    tints = [(0.2, 0.7, 0.4), (0.5, 0.3, 0.8)]
    for k, tint in enumerate(tints):
        empty = bpy.data.objects.new(f"Empty{k}", None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = inner
        empty.location = (-0.5 + k, 0.0, 0.0)
        empty.scale = (0.5, 1.0, 1.0)
        empty["tint"] = tint
        scene.collection.objects.link(empty)
    cycles = ss.render_cycles(scene)
    exported = export(scene)
    assert not [w for w in exported.warnings if "not found" in w], exported.warnings
    scenes.use_photon_map(scene, samples=1, global_photons=1000, caustic_photons=100,
                          final_gather_rays=1)
    ours = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    h, w, _ = ours.shape
    for k, tint in enumerate(tints):
        s = np.s_[3:h - 3, 3 + k * w // 2:(k + 1) * w // 2 - 3]
        a, b = ours[s].reshape(-1, 3), cycles[s].reshape(-1, 3)
        print(f"instance {k}: ours {a.mean(0).round(5)}, Cycles {b.mean(0).round(5)}")
        np.testing.assert_allclose(b, np.broadcast_to(tint, b.shape), atol=1e-3)
        np.testing.assert_allclose(a, b, atol=1e-6)

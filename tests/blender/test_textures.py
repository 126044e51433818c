"""Image textures and Principled alpha through Blender: a textured plane under a sun seen
from above (texel's linear colour x E cos / pi, with the sRGB decode computed here), the
Non-Color case, Cycles in the same process, an alpha-0.25 plane over a lit floor, and
what the exporter reports (unsupported nodes by material and node, missing images,
images shared by several materials read once)."""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.conftest import load_extension_package  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

photon_map = load_extension_package()

RES = 32
SUN = 3.0                      # W/m^2
TILT = math.radians(30.0)      # the sun's angle from the vertical


def srgb_decode(c):
    """IEC 61966-2-1, written out here independently of core/materials/textures.py."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def block_image(name, colorspace="sRGB"):
    """A 16 x 16 byte image of 4 x 4 uniform blocks of 4 x 4 texels, random colours; returns
    (image, block colours (4, 4, 3) as Blender stores them (bytes / 255), row 0 bottom)."""
    rng = np.random.default_rng(7)
    blocks = rng.uniform(0.05, 0.95, (4, 4, 3))
    px = np.ones((16, 16, 4), np.float32)
    px[..., :3] = np.repeat(np.repeat(blocks, 4, axis=0), 4, axis=1)
    img = bpy.data.images.new(name, 16, 16)
    img.colorspace_settings.name = colorspace
    img.pixels.foreach_set(px.ravel())
    stored = np.empty(16 * 16 * 4, np.float32)
    img.pixels.foreach_get(stored)
    stored = stored.reshape(16, 16, 4)[::4, ::4, :3].astype(np.float64)
    return img, stored


def textured_material(name, image, shader='ShaderNodeBsdfPrincipled', socket="Base Color",
                      interpolation='Closest', reroute=True):
    mat = bpy.data.materials.new(name)
    scenes.ensure_node_tree(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new(shader)
    if shader == 'ShaderNodeBsdfPrincipled':
        # No dielectric specular layer: the plane is Lambert, so its light is analytic.
        bsdf.inputs["Specular IOR Level"].default_value = 0.0
    tex = nodes.new('ShaderNodeTexImage')
    tex.image = image
    tex.interpolation = interpolation
    out = nodes.new('ShaderNodeOutputMaterial')
    if reroute:
        r = nodes.new('NodeReroute')
        links.new(tex.outputs["Color"], r.inputs[0])
        links.new(r.outputs[0], bsdf.inputs[socket])
    else:
        links.new(tex.outputs["Color"], bsdf.inputs[socket])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def sun_plane_scene(make_material):
    """A 2.2 m plane under a tilted sun, an orthographic camera above seeing its middle
    2 m, which its UVs map to exactly one period of the image (so the plane's own edges
    stay out of the picture). The material is built by make_material() after the scene is
    reset (a reset removes every datablock)."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    plane = scenes.add_plane(size=2.2, material=make_material(), name="Floor")
    uv = plane.data.uv_layers.active.data
    co = np.empty(2 * len(uv), np.float32)
    uv.foreach_get("uv", co)
    uv.foreach_set("uv", ((co - 0.5) * 1.1 + 0.5).astype(np.float32))
    sun = scenes.add_light('SUN', power=SUN, rotation=(TILT, 0.0, 0.0))
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    return scene


def render_photon_map(scene, samples=4, **settings):
    scenes.use_photon_map(scene, samples=samples, global_photons=20_000, caustic_photons=1000,
                          final_gather_rays=8, **settings)
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)


def block_interiors(image):
    """(4, 4, K, 3): the pixels of each texture block away from its border texels, block
    row 0 at the BOTTOM of the picture (texture order). 8 x 8 pixels per block here."""
    out = np.empty((4, 4, 16, 3))
    for j in range(4):
        for i in range(4):
            r0 = RES - 8 * (j + 1)  # image row 0 is the top
            out[j, i] = image[r0 + 2:r0 + 6, 8 * i + 2:8 * i + 6].reshape(-1, 3)
    return out


@pytest.mark.parametrize("colorspace", ["sRGB", "Non-Color"])
def test_textured_plane_under_a_sun_is_texel_times_irradiance_over_pi(colorspace):
    made = {}

    def material():
        made["image"], made["stored"] = block_image(f"Blocks {colorspace}", colorspace)
        return textured_material("Textured", made["image"])

    scene = sun_plane_scene(material)
    stored = made["stored"]
    img = render_photon_map(scene)
    linear = srgb_decode(stored) if colorspace == "sRGB" else stored
    want = linear * SUN * math.cos(TILT) / math.pi
    got = block_interiors(img)
    rel = np.abs(got - want[:, :, None, :]) / want[:, :, None, :]
    print(f"\n{colorspace}: worst pixel {100 * rel.max():.3f} % off texel x E cos / pi")
    assert rel.max() < 0.02


def test_textured_diffuse_plane_matches_cycles():
    """Mean over the plane against Cycles with Closest interpolation: bilinear filtering of
    linear values keeps a periodic image's mean, so the means agree. (Cycles' Linear
    interpolation of an 8-bit sRGB image filters the ENCODED bytes and decodes after, which
    darkens high-contrast texel borders; Photon Map filters decoded values, docs/export.md.)"""
    scene = sun_plane_scene(lambda: textured_material(
        "Textured Diffuse", block_image("Blocks Cycles")[0], shader='ShaderNodeBsdfDiffuse',
        socket="Color", interpolation='Closest', reroute=False))
    pm = render_photon_map(scene)
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device, c.samples, c.use_denoising, c.use_adaptive_sampling = 'CPU', 16, False, False
    c.diffuse_bounces = 0
    scene.render.filter_size = 0.01
    scene.view_settings.view_transform = 'Standard'
    cy = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    ratio = pm.mean(axis=(0, 1)) / cy.mean(axis=(0, 1))
    print(f"\nPM / Cycles mean over the plane per channel: {np.round(ratio, 4)}")
    np.testing.assert_allclose(ratio, 1.0, atol=0.015)


def test_alpha_quarter_plane_over_a_lit_floor_is_the_blend():
    """Sun straight down (E = 2): the floor beside the plane is 0.8 E / pi; seen through
    the alpha-0.25 plane it is 0.25 x plane (albedo x E / pi) + 0.75 x floor lit through
    the plane (0.75 E x 0.8 / pi)."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    mat = bpy.data.materials.new("Cut-out")
    scenes.ensure_node_tree(mat)
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0.9, 0.3, 0.1, 1.0)
    bsdf.inputs["Alpha"].default_value = 0.25
    bsdf.inputs["Specular IOR Level"].default_value = 0.0  # Lambert: the blend is analytic
    scenes.add_plane(size=1.0, location=(0.0, 0.0, 0.5), material=mat, name="Leaf")
    sun = scenes.add_light('SUN', power=2.0)
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    img = render_photon_map(scene, samples=64, indirect_mode='off', caustics=False)
    e = 2.0 / math.pi
    over = img[12:20, 12:20].mean(axis=(0, 1))  # the plane covers pixels 8..23
    beside = img[:, :4].mean(axis=(0, 1))
    want = 0.25 * np.array([0.9, 0.3, 0.1]) * e + 0.75 * 0.75 * 0.8 * e
    print(f"\nthrough alpha 0.25: {over} (want {want}), pixel std {img[12:20, 12:20].std(axis=(0, 1))}; "
          f"floor {beside} (want {0.8 * e})")
    np.testing.assert_allclose(over, want, rtol=0.02)
    np.testing.assert_allclose(beside, 0.8 * e, rtol=0.01)


def test_image_alpha_into_principled_alpha_cuts_out():
    """A 16 x 16 image, alpha 0 on its left half and 1 on its right, feeds both Base Color
    and Alpha of a plane over a lit floor (sun straight down, E = 2): the floor shows,
    fully lit, on the left; the plane's texel colour on the right."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    img = bpy.data.images.new("Mask", 16, 16, alpha=True)
    img.colorspace_settings.name = "Non-Color"
    px = np.ones((16, 16, 4), np.float32)
    px[..., :3] = (0.9, 0.3, 0.1)
    px[:, :8, 3] = 0.0
    img.pixels.foreach_set(px.ravel())
    img.pixels.foreach_get(px.ravel())  # as stored (bytes / 255)
    colour = px.reshape(16, 16, 4)[0, 15, :3].astype(np.float64)
    mat = textured_material("Stencil", img, reroute=False)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    links.new(nodes["Image Texture"].outputs["Alpha"], nodes["Principled BSDF"].inputs["Alpha"])
    scenes.add_plane(size=2.0, location=(0.0, 0.0, 0.5), material=mat, name="Stencil")
    sun = scenes.add_light('SUN', power=2.0)
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    im = render_photon_map(scene, samples=4, indirect_mode='off', caustics=False)
    e = 2.0 / math.pi
    # Columns 0..15 see x < 0 (alpha 0), 16..31 x > 0; bilinear blends around x = 0 and,
    # by repeat wrapping, at the image's edges x = +-1: keep away from both.
    np.testing.assert_allclose(im[:, 4:12].mean(axis=(0, 1)), 0.8 * e, rtol=1e-4)
    np.testing.assert_allclose(im[:, 20:28].mean(axis=(0, 1)), colour * e, rtol=1e-4)


def test_exporter_reports_unsupported_nodes_missing_images_and_reads_images_once():
    scene = scenes.reset()
    scenes.set_resolution(8, 8)
    scenes.add_camera(location=(0.0, -6.0, 2.0))
    shared, _ = block_image("Shared")
    a = textured_material("Bark", shared)
    b = textured_material("Moss", shared, shader='ShaderNodeBsdfDiffuse', socket="Color")
    leaf = bpy.data.materials.new("Leaf")
    scenes.ensure_node_tree(leaf)
    noise = leaf.node_tree.nodes.new('ShaderNodeTexNoise')  # supported: a shader program
    wire = leaf.node_tree.nodes.new('ShaderNodeWireframe')  # not supported: reported
    principled = leaf.node_tree.nodes.get("Principled BSDF")
    leaf.node_tree.links.new(noise.outputs[1], principled.inputs["Base Color"])
    leaf.node_tree.links.new(wire.outputs[0], principled.inputs["Roughness"])
    missing = textured_material("Ghost", None)
    lost = bpy.data.images.new("Lost", 4, 4)
    lost.source, lost.filepath = 'FILE', "//no/such/lost.png"
    lost_a, lost_b = textured_material("Lost A", lost), textured_material("Lost B", lost)
    for i, mat in enumerate((a, b, leaf, missing, lost_a, lost_b)):
        scenes.add_plane(size=1.0, location=(2.0 * i, 0.0, 0.0), material=mat, name=f"P{i}")
    result = export(scene)
    tx = result.scene.textures
    assert tx.count == 1 and tx.names == ("Shared",)
    m = result.scene.materials
    names = list(m.names)
    assert m.diffuse_texture[names.index("Bark")] == 0
    assert m.diffuse_texture[names.index("Moss")] == 0
    assert m.diffuse_texture[names.index("Ghost")] == -1
    np.testing.assert_allclose(m.diffuse[names.index("Ghost")], 0.8, rtol=1e-6)
    assert m.programs[names.index("Leaf")] is not None
    assert not any("Noise" in w for w in result.warnings), result.warnings
    wire_msgs = [w for w in result.warnings if "Wireframe" in w]
    assert len(wire_msgs) == 1, result.warnings
    assert wire_msgs[0].startswith("Material 'Leaf': node 'Wireframe' (ShaderNodeWireframe) "
                                   "is not supported")
    ghost = [w for w in result.warnings if "Ghost" in w]
    assert len(ghost) == 1 and 'node "Image Texture"' in ghost[0] and "no image" in ghost[0]
    assert not any("Bark" in w or "Moss" in w for w in result.warnings), result.warnings
    for name in ("Lost A", "Lost B"):
        msgs = [w for w in result.warnings if w.startswith(f'Material "{name}"')]
        assert len(msgs) == 1 and 'image "Lost" has no pixels' in msgs[0], result.warnings
        assert m.diffuse_texture[names.index(name)] == -1


def test_transparent_mix_over_a_floor_matches_cycles():
    """Mix Shader (Factor 0.25) of Transparent BSDF and a Diffuse BSDF on a plane over a lit
    floor, sun straight down: the mean over the plane's pixels against Cycles (direct
    light, transparent shadows) within 2 %."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    mat = bpy.data.materials.new("Veil")
    scenes.ensure_node_tree(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    clear = nodes.new('ShaderNodeBsdfTransparent')
    diff = nodes.new('ShaderNodeBsdfDiffuse')
    diff.inputs["Color"].default_value = (0.9, 0.3, 0.1, 1.0)
    mix = nodes.new('ShaderNodeMixShader')
    mix.inputs["Fac"].default_value = 0.25
    out = nodes.new('ShaderNodeOutputMaterial')
    links.new(clear.outputs[0], mix.inputs[1])
    links.new(diff.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=1.0, location=(0.0, 0.0, 0.5), material=mat, name="Veil")
    sun = scenes.add_light('SUN', power=2.0)
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    pm = render_photon_map(scene, samples=64, indirect_mode='off', caustics=False)
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device, c.samples, c.use_denoising, c.use_adaptive_sampling = 'CPU', 64, False, False
    c.diffuse_bounces = 0
    scene.render.filter_size = 0.01
    scene.view_settings.view_transform = 'Standard'
    cy = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    a, b = pm[10:22, 10:22].mean(axis=(0, 1)), cy[10:22, 10:22].mean(axis=(0, 1))
    print(f"\nthrough a 0.25 Transparent mix: PM {a}, Cycles {b}, ratio {np.round(a / b, 4)}")
    np.testing.assert_allclose(a, b, rtol=0.02)

"""Per-pass switches: the multilayer EXR Blender writes holds exactly the passes switched
on, with their channels, and Combined is the sum of the light passes (and stays the same
when some are switched off)."""

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = [pytest.mark.blender, pytest.mark.api]

LIGHT = {"emission": "Emission", "environment": "Environment", "direct": "Direct",
         "specular": "Specular", "caustics": "Caustics", "indirect": "Indirect"}
SETTINGS = dict(samples=2, global_photons=4000, caustic_photons=4000, final_gather_rays=8,
                seed=3)


@pytest.fixture(scope="module")
def every_term():
    """Every light term shows: a lit grey plane, a glass sphere on it (specular, caustics),
    a red emissive cube (emission, colour bleeding), a blue world seen at the top."""
    scenes.photon_map()
    scene = scenes.reset()
    scenes.set_resolution(24, 16)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Grey", (0.7, 0.7, 0.7)))
    glass = bpy.data.materials.new("Glass")
    scenes.ensure_node_tree(glass)
    nodes = scenes.ensure_node_tree(glass).nodes
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfGlass')
    out = nodes.new('ShaderNodeOutputMaterial')
    glass.node_tree.links.new(bsdf.outputs[0], out.inputs['Surface'])
    scenes.add_sphere(radius=0.4, location=(0.0, 0.0, 0.4), material=glass, segments=16)
    red = bpy.data.materials.new("Red")
    scenes.ensure_node_tree(red)
    nodes = red.node_tree.nodes
    nodes.clear()
    emit = nodes.new('ShaderNodeEmission')
    emit.inputs['Color'].default_value = (1.0, 0.1, 0.1, 1.0)
    emit.inputs['Strength'].default_value = 2.0
    out = nodes.new('ShaderNodeOutputMaterial')
    red.node_tree.links.new(emit.outputs[0], out.inputs['Surface'])
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(1.0, 0.5, 0.25))
    bpy.context.active_object.data.materials.append(red)
    scenes.add_light('POINT', location=(0.3, -0.3, 2.0), power=300.0, shadow_soft_size=0.0)
    world = bpy.data.worlds.new("World")
    scenes.ensure_node_tree(world)
    background = world.node_tree.nodes["Background"]
    background.inputs['Color'].default_value = (0.1, 0.2, 0.6, 1.0)
    scene.world = world
    scenes.add_camera(location=(0.0, -4.0, 2.0), look_at=(0.0, 0.0, 0.5), lens=28.0)
    scenes.use_photon_map(scene, **SETTINGS)
    return scene


def render_exr(scene, path, **switches):
    """Render through Blender with an output path, as F12 + save or ``blender -b -f``."""
    from photon_map.photon_engine.cli import set_format

    for key, value in switches.items():
        setattr(scene.photon_map, key, value)
    set_format(scene.render.image_settings, "OPEN_EXR_MULTILAYER")
    scene.render.filepath = str(path)
    try:
        bpy.ops.render.render(write_still=True)
    finally:
        for key in switches:
            scene.photon_map.property_unset(key)
    return scenes.read_multilayer_exr(path)


@pytest.fixture(scope="module")
def all_on(every_term, tmp_path_factory):
    return render_exr(every_term, tmp_path_factory.mktemp("passes") / "all.exr")


def test_all_passes_on_sum_to_combined(all_on):
    assert set(all_on) == {"Combined", *LIGHT.values()}
    assert all_on["Combined"].shape == (16, 24, 4)
    for name in LIGHT.values():
        assert all_on[name].shape == (16, 24, 3), name
        assert all_on[name].max() > 0, name  # every term shows in this scene
    total = sum(all_on[n].astype(np.float64) for n in LIGHT.values())
    np.testing.assert_allclose(all_on["Combined"][..., :3], total, rtol=1e-6, atol=1e-7)


def test_switched_off_passes_are_absent_and_combined_keeps_them(every_term, all_on, tmp_path):
    passes = render_exr(every_term, tmp_path / "some.exr", pass_direct=False,
                        pass_caustics=False, pass_environment=False)
    assert set(passes) == {"Combined", "Emission", "Specular", "Indirect"}
    np.testing.assert_allclose(passes["Combined"], all_on["Combined"], rtol=1e-6, atol=1e-7)
    for name in ("Emission", "Specular", "Indirect"):
        np.testing.assert_array_equal(passes[name], all_on[name])


def test_only_combined_and_the_debug_pass(every_term, all_on, tmp_path):
    off = {f"pass_{name}": False for name in LIGHT}
    passes = render_exr(every_term, tmp_path / "debug.exr", photon_debug_pass=True, **off)
    assert set(passes) == {"Combined", "Photons"}
    assert passes["Photons"].shape == (16, 24, 4) and passes["Photons"][..., 3].max() > 0
    np.testing.assert_allclose(passes["Combined"], all_on["Combined"], rtol=1e-6, atol=1e-7)


def test_update_render_passes_registers_the_switched_on_passes_only(every_term):
    from photon_map.photon_engine.render import register_passes

    class Recorder:
        def __init__(self):
            self.passes = []

        def register_pass(self, scene, layer, name, channels, chan_id, kind):
            self.passes.append((name, channels, chan_id))

    props = every_term.photon_map
    layer = every_term.view_layers[0]
    rec = Recorder()
    register_passes(rec, every_term, layer)
    assert rec.passes == [("Combined", 4, "RGBA")] + [(n, 3, "RGB") for n in LIGHT.values()]
    props.pass_specular = props.pass_emission = False
    props.photon_debug_pass = True
    try:
        rec = Recorder()
        register_passes(rec, every_term, layer)
        assert [p[0] for p in rec.passes] == ["Combined", "Environment", "Direct", "Caustics",
                                              "Indirect", "Photons"]
        assert rec.passes[-1] == ("Photons", 4, "RGBA")
        props.integrator = 'progressive'
        rec = Recorder()
        register_passes(rec, every_term, layer)
        assert rec.passes == [("Combined", 4, "RGBA")]
    finally:
        for key in ("pass_specular", "pass_emission", "photon_debug_pass", "integrator"):
            props.property_unset(key)


def compositor(scene, pass_name):
    """A Blender 5.0 compositor: Render Layers' ``pass_name`` output -> the group's Image."""
    tree = bpy.data.node_groups.new("Passes", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.scene = scene
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(layers.outputs[pass_name], out.inputs["Image"])
    return tree, layers


@pytest.mark.skipif("compositing_node_group" not in bpy.types.Scene.bl_rna.properties,
                    reason="Blender < 5.0 keeps the compositor in scene.node_tree")
def test_the_compositor_gets_the_switched_on_passes(every_term, all_on, tmp_path):
    """What a compositing artist sees: the Render Layers node offers exactly the passes
    switched on, and a pass wired to the output is what the saved image holds."""
    from photon_map.photon_engine.cli import set_format

    import OpenEXR

    tree, layers = compositor(every_term, "Caustics")
    every_term.compositing_node_group = tree
    settings = every_term.render.image_settings
    saved = (settings.media_type, settings.file_format, settings.color_depth,
             every_term.render.filepath, every_term.render.use_compositing)
    try:
        enabled = {o.name for o in layers.outputs if o.enabled}
        assert enabled == {"Image", "Alpha", *LIGHT.values()}
        every_term.photon_map.pass_direct = False
        every_term.view_layers[0].update()
        enabled = {o.name for o in layers.outputs if o.enabled}
        assert enabled == {"Image", "Alpha", *LIGHT.values()} - {"Direct"}
        # A single-layer EXR holds the composite: here the Caustics pass alone.
        set_format(settings, "OPEN_EXR")
        every_term.render.use_compositing = True
        every_term.render.filepath = str(tmp_path / "composite.exr")
        bpy.ops.render.render(write_still=True)
        with OpenEXR.File(str(tmp_path / "composite.exr"), separate_channels=True) as exr:
            channels = exr.parts[0].channels
            image = np.stack([np.asarray(channels[c].pixels) for c in "RGB"], axis=-1)
        assert image.max() > 0
        np.testing.assert_allclose(image, all_on["Caustics"], rtol=1e-6, atol=1e-7)
    finally:
        every_term.photon_map.property_unset("pass_direct")
        every_term.compositing_node_group = None
        bpy.data.node_groups.remove(tree)
        (settings.media_type, settings.file_format, settings.color_depth,
         every_term.render.filepath, every_term.render.use_compositing) = saved

"""Registration: the engine, its settings and its panels, as Blender sees them."""

import dataclasses
import subprocess
import sys
import types

import bpy
import pytest

from tests.blender import scenes
from tests.conftest import ROOT

pytestmark = [pytest.mark.blender, pytest.mark.api]


@pytest.fixture
def pm():
    package = scenes.photon_map()
    scenes.reset()
    return package


def test_engine_is_listed_and_selectable(pm):
    engines = {getattr(cls, "bl_idname", None): cls for cls in bpy.types.RenderEngine.__subclasses__()}
    assert engines["PHOTON_MAP"].bl_label == "Photon Map"
    assert "PHOTON_MAP" in _engine_ids()
    scene = bpy.context.scene
    scene.render.engine = 'PHOTON_MAP'
    assert scene.render.engine == 'PHOTON_MAP'


def _engine_ids():
    """The engines Blender offers in Render Properties (a dynamic enum: probe by setting)."""
    render = bpy.context.scene.render
    before, offered = render.engine, []
    for engine in ('PHOTON_MAP', 'CYCLES', scenes.eevee_id()):
        try:
            render.engine = engine
        except TypeError:
            continue
        offered.append(engine)
    render.engine = before
    return offered


def test_engine_survives_factory_reset(pm):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.engine = 'PHOTON_MAP'
    assert bpy.context.scene.render.engine == 'PHOTON_MAP'


def test_settings_defaults_match_core(pm):
    from photon_map.core.settings import CORE_ONLY, RenderSettings
    from photon_map.photon_engine.properties import setting_names, to_core_settings

    props = bpy.context.scene.photon_map
    core_defaults = RenderSettings()
    for field in dataclasses.fields(RenderSettings):
        if field.name not in CORE_ONLY:
            want = getattr(core_defaults, field.name)
            if isinstance(want, float):  # Blender stores float32
                want = pytest.approx(want, rel=1e-7)
            assert getattr(props, field.name) == want, field.name
    assert to_core_settings(props) == core_defaults
    assert set(setting_names()) == {f.name for f in dataclasses.fields(RenderSettings)
                                    if f.name not in CORE_ONLY}


def test_settings_are_described(pm):
    from photon_map.photon_engine.properties import setting_names

    rna = bpy.context.scene.photon_map.bl_rna.properties
    for name in setting_names():
        prop = rna[name]
        assert prop.name and prop.name != name, name
        assert prop.description and not prop.description.endswith("."), name


def test_translator_carries_every_value(pm):
    from photon_map.photon_engine.properties import to_core_settings

    props = bpy.context.scene.photon_map
    props.samples, props.max_specular_depth, props.light_samples = 3, 5, 2
    props.seed, props.threads, props.volume_light_samples = 77, 1, 9
    props.global_photons, props.caustic_photons, props.photon_max_bounces = 1234, 567, 3
    props.global_k, props.caustic_k, props.final_gather_rays = 11, 13, 17
    props.global_radius, props.caustic_radius = 0.25, 0.125
    props.filter, props.indirect_mode = 'gaussian', 'preview'
    props.caustics, props.projection_map = False, False
    core = to_core_settings(props)
    assert (core.samples, core.max_specular_depth, core.light_samples, core.seed, core.threads) == (
        3, 5, 2, 77, 1)
    assert core.volume_light_samples == 9
    assert (core.global_photons, core.caustic_photons, core.photon_max_bounces) == (1234, 567, 3)
    assert (core.global_k, core.caustic_k, core.final_gather_rays) == (11, 13, 17)
    assert (core.global_radius, core.caustic_radius) == (0.25, 0.125)
    assert (core.filter, core.indirect_mode, core.caustics, core.projection_map) == (
        'gaussian', 'preview', False, False)
    props.pass_direct, props.pass_indirect, props.integrator = False, False, 'progressive'
    props.pass_volume_direct = False
    props.progressive_passes, props.photons_per_pass, props.time_budget = 9, 321, 2.5
    core = to_core_settings(props)
    assert core.passes() == ("emission", "environment", "specular", "caustics",
                             "volume_indirect")
    assert (core.integrator, core.progressive_passes, core.photons_per_pass,
            core.time_budget) == ('progressive', 9, 321, 2.5)


def test_enum_items_are_the_core_choices(pm):
    """Every core choice is offered, under the core's own string, and nothing else."""
    from photon_map.core.settings import FILTERS, INDIRECT_MODES, MAX_RADIUS, RenderSettings
    from photon_map.core.settings import SettingsError
    from photon_map.photon_engine import properties

    rna = bpy.context.scene.photon_map.bl_rna.properties
    for name, choices in (("filter", FILTERS), ("indirect_mode", INDIRECT_MODES)):
        assert tuple(item.identifier for item in rna[name].enum_items) == choices, name
        with pytest.raises(SettingsError, match=name):
            RenderSettings().with_values(**{name: "bogus"})
    assert [i[3] for i in properties.INDIRECT_MODE_ITEMS] == [0, 1, 2]
    assert "Preview" in rna["indirect_mode"].enum_items["preview"].name
    assert properties.MAX_RADIUS == MAX_RADIUS
    from photon_map.core import settings as core_settings

    assert tuple(i.identifier for i in rna["integrator"].enum_items) == core_settings.INTEGRATORS
    assert [i[3] for i in properties.INTEGRATOR_ITEMS] == [0, 1]
    assert (properties.MAX_PROGRESSIVE_PASSES, properties.MAX_PHOTONS_PER_PASS,
            properties.MAX_TIME_BUDGET) == (core_settings.MAX_PROGRESSIVE_PASSES,
                                            core_settings.MAX_PHOTONS_PER_PASS,
                                            core_settings.MAX_TIME_BUDGET)


def test_property_limits_are_the_core_limits(pm):
    """Blender clamps to the hard limits; each must be a value the core accepts, and one
    step beyond it a value the core refuses, so the UI can neither store a value the
    renderer rejects nor hide one it accepts."""
    from photon_map.core.settings import RenderSettings, SettingsError
    from photon_map.photon_engine.properties import setting_names

    rna = bpy.context.scene.photon_map.bl_rna.properties
    for name in setting_names():
        if rna[name].type not in ('INT', 'FLOAT'):
            continue  # booleans and enums: test_enum_items_are_the_core_choices
        lo, hi = rna[name].hard_min, rna[name].hard_max
        RenderSettings().with_values(**{name: lo})
        RenderSettings().with_values(**{name: hi})
        for outside in (lo - 1, hi + 1):
            with pytest.raises(SettingsError, match=name):
                RenderSettings().with_values(**{name: outside})


def _context(engine, **data):
    return types.SimpleNamespace(engine=engine, **data)


def test_own_panels_poll_only_for_photon_map(pm):
    from photon_map.photon_engine import ui

    mat = scenes.diffuse_material()
    obj = scenes.add_plane(material=mat)
    for panel in ui.classes:
        assert panel.__name__.startswith("PHOTON_MAP_")
        assert panel.poll(_context('PHOTON_MAP', scene=bpy.context.scene, object=obj,
                                   material=mat))
        assert not panel.poll(_context('CYCLES', scene=bpy.context.scene, object=obj,
                                       material=mat))
        assert not panel.poll(_context(scenes.eevee_id(), scene=bpy.context.scene, object=obj,
                                       material=mat))


LIGHT_PANELS = ("DATA_PT_context_light", "DATA_PT_EEVEE_light", "DATA_PT_spot")
MATERIAL_PANELS = ("EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface")
WORLD_PANELS = ("WORLD_PT_context_world", "EEVEE_WORLD_PT_surface")
CAMERA_PANELS = ("DATA_PT_context_camera", "DATA_PT_lens", "DATA_PT_camera")


def test_light_material_world_camera_panels_show_with_photon_map(pm):
    spot = scenes.add_light('SPOT')
    mat = scenes.diffuse_material()
    plane = scenes.add_plane(material=mat)
    world = bpy.data.worlds.new("World")
    scenes.ensure_node_tree(world)
    camera = scenes.add_camera()
    contexts = {
        LIGHT_PANELS: dict(light=spot.data, object=spot),
        MATERIAL_PANELS: dict(material=mat, object=plane),
        WORLD_PANELS: dict(world=world, scene=bpy.context.scene),
        CAMERA_PANELS: dict(camera=camera.data, object=camera),
    }
    for names, data in contexts.items():
        for name in names:
            panel = getattr(bpy.types, name)
            assert panel.poll(_context('PHOTON_MAP', **data)), name
            # The change must not leak to engines that hide these panels on purpose.
            assert panel.poll(_context(scenes.eevee_id(), **data)), name
    # DATA_PT_light shows only the type outside EEVEE; the full EEVEE panel replaces it.
    assert not bpy.types.DATA_PT_light.poll(_context('PHOTON_MAP', light=spot.data))
    assert not bpy.types.DATA_PT_EEVEE_light.poll(_context('CYCLES', light=spot.data))
    assert not bpy.types.EEVEE_MATERIAL_PT_surface.poll(_context('CYCLES', material=mat))


def test_unregister_restores_blender(pm):
    from photon_map.photon_engine import ui

    opened = ui.compatible_panels()
    assert opened and all('PHOTON_MAP' in p.COMPAT_ENGINES for p in opened)
    pm.unregister()
    try:
        assert not hasattr(bpy.types.Scene, "photon_map")
        assert "PHOTON_MAP" not in _engine_ids()
        assert not any('PHOTON_MAP' in p.COMPAT_ENGINES for p in opened)
        assert not hasattr(bpy.types, "PHOTON_MAP_RENDER_PT_sampling")
    finally:
        pm.register()
    from photon_map.core.settings import RenderSettings

    assert bpy.context.scene.photon_map.samples == RenderSettings.samples


def test_package_imports_without_bpy():
    """pytest and the CLI import the root and photon_engine before Blender exists."""
    code = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('photon_map', {str(ROOT / '__init__.py')!r},"
        f" submodule_search_locations=[{str(ROOT)!r}])\n"
        "m = importlib.util.module_from_spec(spec); sys.modules['photon_map'] = m\n"
        "spec.loader.exec_module(m)\n"
        "import photon_engine\n"
        "assert m.bl_info['blender'] == (4, 2, 0) and m.bl_info['category'] == 'Render'\n"
        "assert 'bpy' not in sys.modules and 'numba' not in sys.modules, sorted(sys.modules)\n"
        "print('ok')\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


class RecordingLayout:
    """Stands in for a UILayout: records prop() calls, checks the property exists."""

    def __init__(self, drawn):
        self.drawn = drawn

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, name
        self.drawn.append((data, name))

    def column(self, **_):
        return self

    row = column


def test_panels_draw_every_setting(pm):
    from photon_map.photon_engine import ui
    from photon_map.photon_engine.properties import UI_ONLY, VIEWPORT_ONLY, setting_names

    scene = bpy.context.scene
    light = scenes.add_light('POINT')
    mat = scenes.diffuse_material()
    drawn = []
    for panel in ui.classes:
        context = _context('PHOTON_MAP', scene=scene, object=light, material=mat)
        panel.draw(types.SimpleNamespace(layout=RecordingLayout(drawn)), context)
    assert (mat.photon_map, "dispersion") in drawn  # the Material panel's one setting
    shown = {name for data, name in drawn if data == scene.photon_map}
    assert shown == set(setting_names()) | set(VIEWPORT_ONLY) | set(UI_ONLY)
    assert {"visible_camera", "visible_diffuse", "visible_glossy"} <= {n for _, n in drawn}

"""The Quality dial: presets write their values, hand edits turn it to Custom, a .blend
keeps the choice, and the defaults are the default preset everywhere."""

import bpy
import pytest

from tests.blender import scenes

pytestmark = [pytest.mark.blender, pytest.mark.api]


@pytest.fixture
def props():
    scenes.photon_map()
    return scenes.reset().photon_map


def _governed(props):
    from photon_map.core.presets import PRESET_FIELDS

    return {name: getattr(props, name) for name in PRESET_FIELDS}


def _assert_values(props, values):
    for name, value in values.items():
        assert getattr(props, name) == pytest.approx(value), name


def test_defaults_are_the_default_preset_in_blender_and_in_core(props):
    from photon_map.core.presets import DEFAULT_QUALITY, PRESETS
    from photon_map.core.settings import RenderSettings
    from photon_map.photon_engine.properties import to_core_settings

    assert props.quality == DEFAULT_QUALITY
    _assert_values(props, PRESETS[DEFAULT_QUALITY])
    core = RenderSettings()
    for name, value in PRESETS[DEFAULT_QUALITY].items():
        assert getattr(core, name) == value, name
    assert to_core_settings(props) == core


def test_choosing_a_preset_writes_its_values(props):
    from photon_map.core.presets import PRESETS, QUALITIES, preset_settings
    from photon_map.photon_engine.properties import to_core_settings

    props.seed = 5  # not governed: kept by every preset
    for name in ("final",) + QUALITIES:
        props.quality = name
        assert props.quality == name  # writing the values did not flip it to Custom
        _assert_values(props, PRESETS[name])
        assert props.seed == 5
        assert to_core_settings(props) == preset_settings(name, to_core_settings(props))
    # Custom writes nothing: the values stay those of the last preset.
    before = _governed(props)
    props.quality = 'custom'
    assert _governed(props) == before


def test_editing_a_governed_setting_by_hand_selects_custom(props):
    from photon_map.core.presets import PRESET_FIELDS, PRESETS

    props.quality = 'final'
    props.samples = 7
    assert props.quality == 'custom' and props.samples == 7
    _assert_values(props, {k: v for k, v in PRESETS["final"].items() if k != "samples"})
    # Every governed setting does it; the others do not.
    for name in PRESET_FIELDS:
        props.quality = 'final'
        rna = props.bl_rna.properties[name]
        if rna.type == 'ENUM':
            other = next(i.identifier for i in rna.enum_items if i.identifier != getattr(props, name))
        elif rna.type == 'FLOAT':
            other = getattr(props, name) + 0.5
        else:
            other = getattr(props, name) + 1
        setattr(props, name, other)
        assert props.quality == 'custom', name
    props.quality = 'draft'
    props.seed, props.threads, props.max_specular_depth = 3, 1, 4
    assert props.quality == 'draft'


def test_a_blend_file_keeps_the_choice_and_its_values(props, tmp_path):
    from photon_map.core.presets import PRESETS

    props.quality = 'final'
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "final.blend"))
    props.samples = 9  # -> custom
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "custom.blend"))

    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "final.blend"))
    reopened = bpy.context.scene.photon_map
    assert reopened.quality == 'final'
    _assert_values(reopened, PRESETS["final"])
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "custom.blend"))
    reopened = bpy.context.scene.photon_map
    assert reopened.quality == 'custom' and reopened.samples == 9


def test_tooltips_state_each_presets_cost(props):
    from photon_map.core.presets import PRESETS, QUALITIES

    items = props.bl_rna.properties["quality"].enum_items
    assert [i.identifier for i in items] == list(QUALITIES) + ['custom']
    for name in QUALITIES:
        text = items[name].description
        assert f"{PRESETS[name]['samples']} samples" in text, text
        assert f"k {PRESETS[name]['global_k']}" in text, text

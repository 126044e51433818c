"""Quality presets (core/presets.py): the interface and its invariants. The measured error
and time of each preset are checked in tests/blender/test_presets.py."""

from dataclasses import asdict

import pytest

from core.presets import DEFAULT_QUALITY, PRESET_FIELDS, PRESETS, QUALITIES, preset_settings
from core.settings import RenderSettings, SettingsError


def test_default_settings_are_the_default_preset():
    defaults = asdict(RenderSettings())
    assert {k: defaults[k] for k in PRESET_FIELDS} == PRESETS[DEFAULT_QUALITY]
    assert preset_settings(DEFAULT_QUALITY) == RenderSettings()


def test_every_preset_sets_the_same_valid_fields():
    assert set(PRESETS) == set(QUALITIES)
    for name in QUALITIES:
        assert tuple(PRESETS[name]) == PRESET_FIELDS, name
        st = preset_settings(name)  # validated: every value is in range
        assert {k: getattr(st, k) for k in PRESET_FIELDS} == PRESETS[name]


def test_presets_cost_more_from_draft_to_converged():
    """Each step up spends at least as much on every budget and more on some."""
    budgets = ("samples", "global_photons", "caustic_photons", "final_gather_rays")
    for lo, hi in zip(QUALITIES, QUALITIES[1:]):
        a, b = PRESETS[lo], PRESETS[hi]
        assert all(a[k] <= b[k] for k in budgets), (lo, hi)
        assert any(a[k] < b[k] for k in budgets), (lo, hi)


def test_preset_keeps_the_settings_it_does_not_govern():
    base = RenderSettings(seed=7, threads=1, max_specular_depth=3, filter="gaussian")
    st = preset_settings("draft", base)
    assert (st.seed, st.threads, st.max_specular_depth, st.filter) == (7, 1, 3, "gaussian")
    assert preset_settings("custom", base) == base


def test_unknown_preset_is_named():
    with pytest.raises(SettingsError, match="'ultra'"):
        preset_settings("ultra")

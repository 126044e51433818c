"""Quality presets: one dial that sets the photon counts, k, radii, final-gather rays and
camera samples together.

``PRESETS[name]`` holds RenderSettings field values; ``preset_settings(name, base)``
applies one to a base RenderSettings. "custom" means hand-set values (no preset applied).
The values are chosen from measurements (benchmarks/tradeoff.py; README "Speed for
accuracy"), and the default settings of RenderSettings are the DEFAULT_QUALITY preset
(tests/core/test_presets.py checks both).
"""

from __future__ import annotations

from .settings import RenderSettings, SettingsError

QUALITIES = ("draft", "preview", "final", "converged")
"""Preset names from fastest to most accurate; "custom" (hand-set values) is not a preset."""

DEFAULT_QUALITY = "preview"
"""The preset RenderSettings' defaults equal (new Blender scenes start on it)."""

PRESETS: dict[str, dict] = {
    "draft": dict(samples=16, adaptive_threshold=0.1, global_photons=50_000,
                  caustic_photons=50_000, global_k=30, caustic_k=30, global_radius=0.0,
                  caustic_radius=0.0, final_gather_rays=64, indirect_mode="final_gather"),
    "preview": dict(samples=64, adaptive_threshold=0.1, global_photons=200_000,
                    caustic_photons=100_000, global_k=50, caustic_k=50, global_radius=0.0,
                    caustic_radius=0.0, final_gather_rays=256, indirect_mode="final_gather"),
    "final": dict(samples=256, adaptive_threshold=0.05, global_photons=500_000,
                  caustic_photons=500_000, global_k=100, caustic_k=100, global_radius=0.0,
                  caustic_radius=0.0, final_gather_rays=1024, indirect_mode="final_gather"),
    "converged": dict(samples=512, adaptive_threshold=0.025, global_photons=1_000_000,
                      caustic_photons=1_000_000, global_k=150, caustic_k=150,
                      global_radius=0.0, caustic_radius=0.0, final_gather_rays=2048,
                      indirect_mode="final_gather"),
}
"""name -> the RenderSettings values the preset sets (every preset sets the same keys)."""

PRESET_FIELDS = tuple(PRESETS[DEFAULT_QUALITY])
"""The settings a preset governs; every other setting keeps its hand-set value."""


def preset_settings(name: str, base: RenderSettings | None = None) -> RenderSettings:
    """``base`` (default RenderSettings()) with preset ``name``'s values; "custom" returns
    base unchanged. Raises SettingsError naming an unknown preset."""
    base = base or RenderSettings()
    if name == "custom":
        return base.validated()
    if name not in PRESETS:
        raise SettingsError(f'unknown quality preset {name!r}; one of '
                            f'{", ".join(QUALITIES)} or custom')
    return base.with_values(**PRESETS[name])

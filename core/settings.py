"""Render settings: the one parameter object the core accepts.

The Blender side translates ``scene.photon_map`` into this (photon_engine/properties.py,
``to_core_settings``); the CLI's ``--set KEY=VALUE`` and the tests build it directly.
Defaults live here and only here.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace


class SettingsError(ValueError):
    """A setting out of range; the message names the setting and the value."""


@dataclass(frozen=True)
class RenderSettings:
    samples: int = 16
    """Camera samples per pixel (jittered within the pixel)."""
    max_specular_depth: int = 8
    """Maximum number of mirror/glass bounces followed from the camera."""
    seed: int = 0
    """Random seed: the same settings and seed give the same image."""
    light_samples: int = 1
    """Shadow rays per light per camera sample at each diffuse hit."""
    threads: int = 0
    """Worker threads for ray tracing and shading; 0 = all cores."""

    def validated(self) -> "RenderSettings":
        checks = {
            "samples": (1, 1 << 20),
            "max_specular_depth": (0, 1024),
            "seed": (0, 2**31 - 1),
            "light_samples": (1, 1024),
            "threads": (0, 1024),
        }
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or not (lo <= v <= hi):
                raise SettingsError(f'"{name}" must be an integer in [{lo}, {hi}], got {v!r}')
        return self

    def with_values(self, **values) -> "RenderSettings":
        """A copy with some settings changed; unknown names raise SettingsError."""
        known = {f.name: f for f in fields(self)}
        for k in values:
            if k not in known:
                raise SettingsError(f'unknown setting "{k}"; known: {", ".join(sorted(known))}')
        return replace(self, **values).validated()

    def with_strings(self, pairs: dict[str, str]) -> "RenderSettings":
        """Like with_values, parsing each string with the field's type (CLI ``--set``)."""
        known = {f.name: f for f in fields(self)}
        parsed = {}
        for k, text in pairs.items():
            if k not in known:
                raise SettingsError(f'unknown setting "{k}"; known: {", ".join(sorted(known))}')
            typ = type(getattr(self, k))
            try:
                if typ is bool:
                    parsed[k] = text.lower() in ("1", "true", "yes", "on")
                else:
                    parsed[k] = typ(text)
            except ValueError:
                raise SettingsError(f'setting "{k}" expects {typ.__name__}, got {text!r}') from None
        return self.with_values(**parsed)

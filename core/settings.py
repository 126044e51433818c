"""Render settings: the one parameter object the core accepts.

The Blender side translates ``scene.photon_map`` into this (photon_engine/properties.py,
``to_core_settings``); the CLI's ``--set KEY=VALUE`` and the tests build it directly.
Defaults live here and only here.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from .passes import LIGHT_PASSES


class SettingsError(ValueError):
    """A setting out of range; the message names the setting and the value."""


INDIRECT_MODES = ("final_gather", "preview", "off")
"""``indirect_mode`` values: final gathering, direct visualisation of the global map, none."""

FILTERS = ("none", "cone", "gaussian")
"""``filter`` values: the radiance-estimate kernel (core/photons/estimate.py)."""

MAX_RADIUS = 1e9
"""Largest explicit gather radius, metres (a bound that keeps the value finite)."""

OVERLAY_MAPS = ("global", "caustic", "both")
"""``overlay_map`` values: the photon map(s) the debug pass shows (core/integrators/debug_overlay.py)."""

MAX_DOT_RADIUS_PX = 32.0
"""Largest ``overlay_dot_radius``, pixels (debug_overlay.MAX_DOT_RADIUS_PX)."""

INTEGRATORS = ("photon_map", "progressive")
PROGRESSIVE_DIRECT = ("shadow_rays", "photons")
CORE_ONLY = ("progressive_alpha", "progressive_radius", "progressive_direct",
             "progressive_block")
"""Settings of the core with no Blender property: the progressive integrator's algorithm
constants and merge block, for checks and experiments (tests, benchmarks); renders from
Blender use the defaults."""
"""``integrator`` values: photon maps + final gathering (core/integrators/photon_mapping.py,
a fixed budget) or stochastic progressive photon mapping (core/integrators/sppm.py,
converges with passes)."""

MAX_PROGRESSIVE_PASSES = 1 << 20
"""Largest ``progressive_passes``."""
MAX_PHOTONS_PER_PASS = 1 << 26
"""Largest ``photons_per_pass``."""
MAX_TIME_BUDGET = 1e7
"""Largest ``time_budget``, seconds (about 116 days: a bound that keeps it finite)."""


@dataclass(frozen=True)
class RenderSettings:
    samples: int = 64
    """Camera samples per pixel (jittered within the pixel); with adaptive sampling the
    most a pixel takes."""
    adaptive_threshold: float = 0.1
    """Adaptive sampling's noise threshold (core/integrators/adaptive.py): a pixel stops
    taking samples once its relative standard error is below it; 0 = off (every pixel
    takes ``samples``)."""
    adaptive_min_samples: int = 0
    """Samples every pixel takes before adaptive sampling judges its noise; 0 = automatic
    (a quarter of ``samples``, at least 4)."""
    max_specular_depth: int = 8
    """Maximum number of mirror/glass bounces followed from the camera."""
    seed: int = 0
    """Random seed: the same settings and seed give the same image."""
    light_samples: int = 1
    """Shadow rays per light per camera sample at each diffuse hit."""
    volume_light_samples: int = 0
    """Single-scattering samples (an equiangular distance and a shadow ray) per light per
    camera sample along each stretch of a camera ray through a medium; per pass in
    progressive mode. Only scenes with a medium read it. 0 = automatic
    (core/integrators/volume.py ``volume_light_samples``): 16 where every medium is
    homogeneous (along a ray through fog Volume Direct carries most of the image's variance,
    and a sample costs little beside the beam estimate), 4 where a density varies (each
    shadow ray is tracked through it); docs/volumes.md, "Volume light samples"."""
    threads: int = 0
    """Worker threads for ray tracing and shading; 0 = all cores."""

    # Photon pass (core/photons/tracing.py).
    global_photons: int = 200_000
    """Photons emitted for the global map (indirect diffuse light)."""
    caustic_photons: int = 100_000
    """Photons emitted for the caustic map (light -> specular+ -> diffuse paths)."""
    photon_max_bounces: int = 8
    """Maximum number of bounces a photon makes before it is dropped, as Cycles' Max
    Bounces: every estimate makes at most photon_max_bounces + 1 reflections, so the photons
    that final-gather rays read (one reflection after the camera's hit) are those of at
    most photon_max_bounces - 1 bounces (core/photons/tracing.py, "Bounces")."""
    projection_map: bool = True
    """Aim caustic photons at the specular objects only (flux weighted by the aimed fraction)."""
    photon_importance: bool = True
    """Share each map's photons by power x visual importance (a camera pre-pass and pilot
    photons, core/photons/importance.py) instead of by power alone; unbiased either way."""

    # Radiance estimates (core/photons/estimate.py).
    global_k: int = 50
    """Photons per radiance estimate in the global map."""
    caustic_k: int = 50
    """Photons per radiance estimate in the caustic map."""
    global_radius: float = 0.0
    """Maximum gather radius in the global map, metres; 0 = derived from the scene."""
    caustic_radius: float = 0.0
    """Maximum gather radius in the caustic map, metres; 0 = derived from the scene."""
    filter: str = "cone"
    """Radiance-estimate kernel: one of FILTERS."""

    # Second pass.
    caustics: bool = True
    """Render the caustics term (builds the caustic map when a surface is specular)."""
    indirect_mode: str = "final_gather"
    """Indirect diffuse light: one of INDIRECT_MODES."""
    final_gather_rays: int = 256
    """Final-gather rays per pixel at the first diffuse hit, at most: ``final_gather_rays
    // samples`` (at least 1) per camera sample, so a pixel that adaptive sampling stops
    at a quarter of its samples takes a quarter of them."""

    # Photon debug pass (core/integrators/debug_overlay.py).
    photon_debug_pass: bool = False
    """Add the "photons" pass: (H, W, 4) RGBA dots where the camera sees a stored photon."""
    overlay_map: str = "both"
    """The map(s) the debug pass shows: one of OVERLAY_MAPS."""
    overlay_dot_radius: float = 1.0
    """Radius of a photon's dot, pixels, in [0, MAX_DOT_RADIUS_PX]; 0 draws one pixel."""
    overlay_composite: bool = False
    """Draw the dots over "combined" too (which is then no longer the sum of the passes)."""

    # Output passes: which light terms are produced as their own images. A
    # switched-off term is still rendered into "combined" (as in Cycles) but gets no image
    # of its own: not allocated, accumulated, returned or transferred (see passes()).
    pass_emission: bool = True
    """Produce the "emission" pass."""
    pass_environment: bool = True
    """Produce the "environment" pass."""
    pass_direct: bool = True
    """Produce the "direct" pass."""
    pass_specular: bool = True
    """Produce the "specular" pass."""
    pass_caustics: bool = True
    """Produce the "caustics" pass (the term itself is switched by ``caustics``)."""
    pass_indirect: bool = True
    """Produce the "indirect" pass (the term itself is switched by ``indirect_mode``)."""
    pass_volume_direct: bool = True
    """Produce the "volume_direct" pass (single scattering of the lights in a medium; only
    for a scene with a medium)."""
    pass_volume_indirect: bool = True
    """Produce the "volume_indirect" pass (the volume photon maps' beam estimate; only for
    a scene with a medium)."""
    denoising_data: bool = False
    """Produce "denoising_albedo" and "denoising_normal" (core/integrators/denoise_features.py, Cycles'
    definitions) for the compositor's Denoise node; the Photon Map integrator only."""

    # Integrator choice and the progressive mode (core/integrators/sppm.py).
    integrator: str = "photon_map"
    """One of INTEGRATORS: "photon_map" (fixed budget) or "progressive" (SPPM)."""
    progressive_passes: int = 64
    """SPPM passes to run (without a time budget); each traces photons_per_pass photons."""
    photons_per_pass: int = 100_000
    """Photons emitted per SPPM pass (memory scales with this, not with the passes)."""
    time_budget: float = 0.0
    """Seconds for a progressive render, export included; 0 = no budget (run
    progressive_passes). With a budget the number of passes is chosen to fit it. The
    photon_map integrator has a fixed cost and ignores it."""
    progressive_alpha: float = 0.75
    """The progressive mode's alpha in (0, 1): the global radius schedule
    r_k^2 = r_1^2 prod_{j<k} (j + alpha) / (j + 1) ~ k^(alpha - 1) (Knaus & Zwicker 2011);
    smaller shrinks the radius faster (less blur, more noise)."""
    progressive_radius: float = 0.0
    """The progressive mode's first-pass gather radius r_1 in metres; 0 = automatic (about
    INITIAL_PHOTONS photons per disc, scale-invariant)."""
    progressive_block: int = 8
    """Passes summed together before they join the image (the unit of work of a distributed
    render, core/integrators/distributed.py): blocks are summed from zero in pass order and
    added to the image in block order, so a render with the same settings and seed gives
    the same image bit for bit on one machine or on many."""
    progressive_direct: str = "shadow_rays"
    """How SPPM gets direct light: one of PROGRESSIVE_DIRECT ("photons": standard SPPM)."""

    def passes(self) -> tuple[str, ...]:
        """The light passes (names in LIGHT_PASSES, summation order) produced as images."""
        return tuple(name for name in LIGHT_PASSES if getattr(self, f"pass_{name}"))

    def validated(self) -> "RenderSettings":
        checks = {
            "samples": (1, 1 << 20),
            "adaptive_min_samples": (0, 1 << 20),
            "max_specular_depth": (0, 1024),
            "seed": (0, 2**31 - 1),
            "light_samples": (1, 1024),
            "volume_light_samples": (0, 1024),
            "threads": (0, 1024),
            "global_photons": (0, 1 << 30),
            "caustic_photons": (0, 1 << 30),
            "photon_max_bounces": (1, 1024),
            "global_k": (1, 10_000),
            "caustic_k": (1, 10_000),
            "final_gather_rays": (1, 1 << 16),
            "progressive_passes": (1, MAX_PROGRESSIVE_PASSES),
            "photons_per_pass": (1, MAX_PHOTONS_PER_PASS),
            "progressive_block": (1, MAX_PROGRESSIVE_PASSES),
        }
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or not (lo <= v <= hi):
                raise SettingsError(f'"{name}" must be an integer in [{lo}, {hi}], got {v!r}')
        for name in ("global_radius", "caustic_radius"):
            v = getattr(self, name)
            ok = isinstance(v, (int, float)) and not isinstance(v, bool)
            if not ok or not (0.0 <= float(v) <= MAX_RADIUS):
                raise SettingsError(f'"{name}" must be a number in [0, {MAX_RADIUS:g}] '
                                    f'(metres; 0 = automatic), got {v!r}')
        v = self.adaptive_threshold
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not ok or not (0.0 <= float(v) <= 1.0):
            raise SettingsError(f'"adaptive_threshold" must be a number in [0, 1] '
                                f'(0 = no adaptive sampling), got {v!r}')
        v = self.overlay_dot_radius
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not ok or not (0.0 <= float(v) <= MAX_DOT_RADIUS_PX):
            raise SettingsError(f'"overlay_dot_radius" must be a number in '
                                f'[0, {MAX_DOT_RADIUS_PX:g}] (pixels), got {v!r}')
        v = self.progressive_alpha
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not ok or not (0.0 < float(v) < 1.0):
            raise SettingsError(f'"progressive_alpha" must be a number in (0, 1), got {v!r}')
        v = self.progressive_radius
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not ok or not (0.0 <= float(v) <= MAX_RADIUS):
            raise SettingsError(f'"progressive_radius" must be a number in [0, {MAX_RADIUS:g}] '
                                f'(metres, 0 = automatic), got {v!r}')
        v = self.time_budget
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not ok or not (0.0 <= float(v) <= MAX_TIME_BUDGET):
            raise SettingsError(f'"time_budget" must be a number in [0, {MAX_TIME_BUDGET:g}] '
                                f'(seconds; 0 = no budget), got {v!r}')
        for name in ("projection_map", "photon_importance", "caustics", "photon_debug_pass",
                     "overlay_composite", "denoising_data") + tuple(
                f"pass_{p}" for p in LIGHT_PASSES):
            v = getattr(self, name)
            if not isinstance(v, bool):
                raise SettingsError(f'"{name}" must be true or false, got {v!r}')
        for name, allowed in (("indirect_mode", INDIRECT_MODES), ("filter", FILTERS),
                              ("overlay_map", OVERLAY_MAPS), ("integrator", INTEGRATORS),
                              ("progressive_direct", PROGRESSIVE_DIRECT)):
            v = getattr(self, name)
            if v not in allowed:
                raise SettingsError(
                    f'"{name}" must be one of {", ".join(allowed)}; got {v!r}')
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
                    low = text.lower()
                    if low not in ("1", "true", "yes", "on", "0", "false", "no", "off"):
                        raise ValueError(text)
                    parsed[k] = low in ("1", "true", "yes", "on")
                else:
                    parsed[k] = typ(text)
            except ValueError:
                raise SettingsError(f'setting "{k}" expects {typ.__name__}, got {text!r}') from None
        return self.with_values(**parsed)

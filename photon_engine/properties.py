"""Render settings stored in the .blend: ``scene.photon_map``.

Settings flow one way: UI -> ``scene.photon_map`` -> ``to_core_settings`` -> ``core``.
Hard limits (``min``/``max``) mirror ``core.settings.RenderSettings.validated`` so Blender
never stores a value the core rejects; ``soft_max`` bounds the slider only. Enum
identifiers are the core's strings (core.settings.INDIRECT_MODES, FILTERS); their items
carry explicit indices so that a .blend keeps its choice if items are added.

Quality (core/presets.py): choosing a preset writes its values into the settings it
governs (``PRESET_FIELDS``); editing one of those by hand, from the UI or Python, turns
Quality to Custom. Loading a .blend runs no update callback, so a file keeps both its
Quality and its values. The presets' values are read from core.presets when this module
is imported (at ``register()``), so the tooltips and defaults follow their tuning.
"""

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from ..core.presets import DEFAULT_QUALITY, PRESET_FIELDS, PRESETS, QUALITIES
from ..core.scene.contract import MIN_ABBE
from ..core.settings import RenderSettings
from . import overlay

INDIRECT_MODE_ITEMS = [
    ('final_gather', "Final Gather",
     "Cosine-distributed gather rays at the first diffuse hit read the global photon map: "
     "smooth, the final-quality mode", 0),
    ('preview', "Preview (Direct Visualisation)",
     "Show the global photon map's radiance estimate directly at the first diffuse hit: "
     "fast but blotchy, for previews only", 1),
    ('off', "Off", "No indirect diffuse light (no global photon map is built)", 2),
]

FILTER_ITEMS = [
    ('none', "None", "Every photon in the gather disc counts the same (box filter)", 0),
    ('cone', "Cone", "Photons weigh less with distance from the query point (Jensen's cone "
     "filter, k = 1): sharper caustic edges", 1),
    ('gaussian', "Gaussian", "Gaussian weights (Pavicic): sharper edges, a little more noise",
     2),
]

OVERLAY_MAP_ITEMS = [
    ('global', "Global", "Photons of the global map (stored at every diffuse hit)", 0),
    ('caustic', "Caustic", "Photons of the caustic map (light, specular bounces, then a "
     "diffuse hit)", 1),
    ('both', "Both", "Photons of both maps", 2),
]

INTEGRATOR_ITEMS = [
    ('photon_map', "Photon Map",
     "Photon maps and final gathering: a fixed budget set by the photon counts, samples "
     "and gather rays; every pass (Direct, Caustics, Indirect, ...) is produced", 0),
    ('progressive', "Progressive (SPPM)",
     "Stochastic progressive photon mapping: passes of photons refine the image until the "
     "pass count or the time budget is used; converges to the right answer; Combined only", 1),
]


def preset_summary(values) -> str:
    """A preset's cost in words, for its tooltip: "200k global + 100k caustic photons,
    k 50, up to 64 samples (noise threshold 0.1), 256 gather rays"."""
    def count(n):
        return f"{n / 1e6:g}M" if n >= 1_000_000 else f"{n / 1e3:g}k" if n >= 1000 else str(n)

    samples = (f"up to {values['samples']} samples (noise threshold "
               f"{values['adaptive_threshold']:g})" if values.get("adaptive_threshold")
               else f"{values['samples']} samples")
    text = (f"{count(values['global_photons'])} global + {count(values['caustic_photons'])} "
            f"caustic photons, k {values['global_k']}, {samples}")
    if values.get("indirect_mode", "final_gather") == "final_gather":
        text += f", {values['final_gather_rays']} gather rays"
    return text


QUALITY_HINTS = {"draft": "Fastest, noisy", "preview": "A quick look",
                 "final": "For final frames", "converged": "Reference quality, slow"}

QUALITY_ITEMS = [
    (name, name.capitalize(), f"{QUALITY_HINTS.get(name, name.capitalize())}: "
     f"{preset_summary(PRESETS[name])}", i)
    for i, name in enumerate(QUALITIES)
] + [('custom', "Custom", "Hand-set values: editing a setting the presets govern selects this",
      len(QUALITIES))]

MAX_PROGRESSIVE_PASSES = 1 << 20  # core.settings.MAX_PROGRESSIVE_PASSES (kept equal by a test)
MAX_PHOTONS_PER_PASS = 1 << 26  # core.settings.MAX_PHOTONS_PER_PASS
MAX_TIME_BUDGET = 1e7  # core.settings.MAX_TIME_BUDGET, seconds
MAX_RADIUS = 1e9  # core.settings.MAX_RADIUS (imported lazily there; kept equal by a test)
MAX_DOT_RADIUS_PX = 32.0  # core.settings.MAX_DOT_RADIUS_PX (kept equal by a test)

# Properties of scene.photon_map that the core never sees (not in setting_names()).
VIEWPORT_ONLY = ("show_photons_in_viewport", "viewport_passes")
UI_ONLY = ("quality", "denoise", "dask_scheduler")  # quality: its values are in the
# governed settings the core does see; denoise: a compositor set-up
# (compat.denoise_compositor), not a core setting; dask_scheduler: where the render runs,
# not what it renders (photon_engine/render.py)


def _update_denoise(self, context):
    """Denoise on: the denoising passes and a compositor Render Layers -> Denoise -> output
    (compat.denoise_compositor); off: that compositor is removed again."""
    from . import compat

    scene = getattr(context, "scene", None) or self.id_data
    if self.denoise and not self.denoising_data:
        self.denoising_data = True
    message = compat.denoise_compositor(scene, self.denoise)
    if message:
        print(f"Photon Map: {message}")


def _update_passes(self, context):
    """Passes come and go with their switches and the integrator: re-list them."""
    view_layer = getattr(context, "view_layer", None)
    if view_layer is not None:
        view_layer.update_render_passes()


# Set while a preset writes its values, so that those writes do not turn Quality to Custom.
_applying_preset = False


def _apply_quality(self, _context):
    """Quality changed: write the chosen preset's values (Custom writes nothing)."""
    global _applying_preset
    if self.quality == 'custom' or _applying_preset:
        return
    _applying_preset = True
    try:
        for name, value in PRESETS[self.quality].items():
            setattr(self, name, value)
    finally:
        _applying_preset = False


def _governed_edited(self, _context):
    """A setting a preset governs was set by hand: the values are now Custom."""
    if not _applying_preset and self.quality != 'custom':
        self.quality = 'custom'


class PhotonMapRenderSettings(bpy.types.PropertyGroup):
    """Photon Map's per-scene render settings (defaults match core.settings.RenderSettings)."""

    quality: EnumProperty(
        name="Quality",
        description="Preset photon counts, k, radii, final-gather rays and samples, chosen "
                    "from measurements; editing one of them by hand selects Custom",
        items=QUALITY_ITEMS, default=DEFAULT_QUALITY, update=_apply_quality,
    )

    # Camera pass.
    samples: IntProperty(
        name="Samples",
        description="Camera rays per pixel, jittered within the pixel; noise falls as "
                    "1/sqrt(samples). With a Noise Threshold, the most a pixel takes",
        min=1, max=1 << 20, soft_max=4096, default=RenderSettings.samples,
    )
    adaptive_threshold: FloatProperty(
        name="Noise Threshold",
        description="Adaptive sampling: a pixel stops taking samples once its estimated "
                    "relative noise (standard error over its value, or over 0.1 in the dark) "
                    "is below this. Glossy highlights, rough glass and the light seen through "
                    "them take every sample, matte walls stop early. 0 = off, every pixel "
                    "takes all samples",
        min=0.0, max=1.0, soft_max=0.2, step=0.1, precision=3,
        default=RenderSettings.adaptive_threshold,
    )
    adaptive_min_samples: IntProperty(
        name="Min Samples",
        description="Samples every pixel takes before its noise is judged; 0 = automatic "
                    "(a quarter of Samples, at least 4)",
        min=0, max=1 << 20, soft_max=4096, default=RenderSettings.adaptive_min_samples,
    )
    max_specular_depth: IntProperty(
        name="Max Specular Depth",
        description="Maximum number of mirror and glass bounces followed from the camera",
        min=0, max=1024, soft_max=64, default=8,
    )
    light_samples: IntProperty(
        name="Light Samples",
        description="Shadow rays per light for each camera sample at each diffuse hit (in "
                    "progressive mode and the viewport: per pass at each visible point)",
        min=1, max=1024, soft_max=64, default=1,
    )
    volume_light_samples: IntProperty(
        name="Volume Light Samples",
        description="Single-scattering samples per light for each camera sample along a ray "
                    "through fog or smoke (a distance on the ray and a shadow ray; in "
                    "progressive mode and the viewport: per pass). Only scenes with a volume "
                    "read it. 0 = automatic: 16 in homogeneous media, where the fog's direct "
                    "light is most of its noise and these samples cost little beside the "
                    "volume photons' estimate; 4 where a density varies",
        min=0, max=1024, soft_max=64, default=0,
    )
    seed: IntProperty(
        name="Seed",
        description="Random seed: the same settings and seed give the same image",
        min=0, max=2**31 - 1, default=0,
    )

    # Performance.
    threads: IntProperty(
        name="Threads",
        description="Worker threads for ray tracing and shading; 0 uses all cores",
        min=0, max=1024, soft_max=64, default=0,
    )
    dask_scheduler: StringProperty(
        name="Dask Scheduler",
        description="Progressive renders (F12, blender -b) spread their passes over this Dask "
                    "cluster: tcp://host:8786, or local:N for N worker processes here; empty "
                    "renders on this machine (needs dask[distributed], docs/farm.md)",
        default="",
    )

    # Photon pass.
    global_photons: IntProperty(
        name="Global Photons",
        description="Photons emitted from the lights for the global map, which carries "
                    "indirect diffuse light (colour bleeding)",
        min=0, max=1 << 30, soft_max=5_000_000, default=200_000,
    )
    caustic_photons: IntProperty(
        name="Caustic Photons",
        description="Photons emitted toward mirrors and glass for the caustic map "
                    "(light focused by specular surfaces onto diffuse ones)",
        min=0, max=1 << 30, soft_max=5_000_000, default=100_000,
    )
    photon_max_bounces: IntProperty(
        name="Max Bounces",
        description="Maximum number of bounces a photon makes; Russian roulette usually "
                    "ends its path earlier",
        min=1, max=1024, soft_max=64, default=8,
    )
    projection_map: BoolProperty(
        name="Projection Map",
        description="Aim caustic photons only at mirrors and glass (their flux is weighted "
                    "by the aimed fraction), so small glass objects still get dense caustics",
        default=True,
    )
    photon_importance: BoolProperty(
        name="Photon Importance",
        description="Give more photons to the lights whose light the camera sees (a quick "
                    "camera pre-pass and a few pilot photons per light) and fewer, never none, "
                    "to the others; the image stays unbiased, only its noise moves",
        default=True,
    )
    global_k: IntProperty(
        name="Global k",
        description="Nearest photons used for each radiance estimate from the global map",
        min=1, max=10_000, soft_max=500, default=50,
    )
    global_radius: FloatProperty(
        name="Global Radius",
        description="Maximum gather radius in the global map; 0 derives it from the scene's "
                    "surface area and the photon count, so it follows the scene's scale",
        min=0.0, max=MAX_RADIUS, soft_max=10.0, default=0.0, subtype='DISTANCE', unit='LENGTH',
    )
    caustic_k: IntProperty(
        name="Caustic k",
        description="Nearest photons used for each radiance estimate from the caustic map",
        min=1, max=10_000, soft_max=500, default=50,
    )
    caustic_radius: FloatProperty(
        name="Caustic Radius",
        description="Maximum gather radius in the caustic map; 0 derives it from the scene's "
                    "surface area and the photon count, so it follows the scene's scale",
        min=0.0, max=MAX_RADIUS, soft_max=10.0, default=0.0, subtype='DISTANCE', unit='LENGTH',
    )
    filter: EnumProperty(
        name="Filter",
        description="Weighting of the photons inside a radiance estimate",
        items=FILTER_ITEMS, default='cone',
    )

    # Second pass.
    caustics: BoolProperty(
        name="Caustics",
        description="Render caustics from the caustic photon map (built only when some "
                    "surface is a mirror or glass)",
        default=True,
    )
    indirect_mode: EnumProperty(
        name="Indirect Light",
        description="How indirect diffuse light is rendered",
        items=INDIRECT_MODE_ITEMS, default='final_gather',
    )
    final_gather_rays: IntProperty(
        name="Final Gather Rays",
        description="Gather rays per pixel at the first diffuse hit, shared among the "
                    "pixel's samples (at least one per sample; a pixel that adaptive "
                    "sampling stops early takes its samples' share); more rays, less noise",
        min=1, max=1 << 16, soft_max=4096, default=RenderSettings.final_gather_rays,
    )

    # Photon debug pass and viewport display (core/integrators/debug_overlay.py, overlay.py).
    photon_debug_pass: BoolProperty(
        name="Photon Debug Pass",
        description="Add a Photons pass: a dot wherever the camera sees a stored photon, "
                    "coloured by its power relative to the map's typical photon",
        default=False, update=_update_passes,
    )
    overlay_map: EnumProperty(
        name="Overlay Map",
        description="Which photon map the debug pass and the viewport display show "
                    "(the viewport display changes at the next render)",
        items=OVERLAY_MAP_ITEMS, default='both',
    )
    overlay_dot_radius: FloatProperty(
        name="Dot Radius",
        description="Radius of a photon's dot in the debug pass; 0 draws one pixel",
        min=0.0, max=MAX_DOT_RADIUS_PX, soft_max=4.0, default=1.0, subtype='PIXEL',
    )
    overlay_composite: BoolProperty(
        name="Composite over Combined",
        description="Draw the photon dots over Combined for a quick look; Combined is then "
                    "no longer the sum of the light passes",
        default=False,
    )
    show_photons_in_viewport: BoolProperty(
        name="Show Photons in Viewport",
        description="Draw the photons of the last render as points in the 3D viewport "
                    "(a random sample of at most 200 000)",
        default=False, update=overlay.update_toggle,
    )

    # Output passes: a switched-off light pass is still in Combined, it only gets no image
    # of its own (core.settings.RenderSettings.passes()).
    pass_emission: BoolProperty(
        name="Emission",
        description="Emission pass: emitters, lights and emissive surfaces the camera sees",
        default=True, update=_update_passes,
    )
    pass_environment: BoolProperty(
        name="Environment",
        description="Environment pass: the world background the camera sees",
        default=True, update=_update_passes,
    )
    pass_direct: BoolProperty(
        name="Direct",
        description="Direct pass: light from the lights reflected at the first surface "
                    "(shadow rays)",
        default=True, update=_update_passes,
    )
    pass_specular: BoolProperty(
        name="Specular",
        description="Specular pass: everything seen through mirrors and glass",
        default=True, update=_update_passes,
    )
    pass_caustics: BoolProperty(
        name="Caustics",
        description="Caustics pass: light focused by mirrors and glass, from the caustic map",
        default=True, update=_update_passes,
    )
    pass_indirect: BoolProperty(
        name="Indirect",
        description="Indirect pass: indirect diffuse light (colour bleeding) from the global map",
        default=True, update=_update_passes,
    )
    pass_volume_direct: BoolProperty(
        name="Volume Direct",
        description="Volume Direct pass: the lights' light scattered once in the World's "
                    "Volume towards the camera (shadow rays); only with a World Volume",
        default=True, update=_update_passes,
    )
    pass_volume_indirect: BoolProperty(
        name="Volume Indirect",
        description="Volume Indirect pass: light scattered in the World's Volume after "
                    "other bounces, volumetric caustics included (volume photons); only "
                    "with a World Volume",
        default=True, update=_update_passes,
    )
    denoising_data: BoolProperty(
        name="Denoising Data",
        description="Denoising Albedo and Denoising Normal passes, as Cycles defines them, "
                    "for the compositor's Denoise node (Photon Map integrator)",
        default=False, update=_update_passes,
    )
    denoise: BoolProperty(
        name="Denoise",
        description="Denoise the render with OpenImageDenoise after it finishes: adds the "
                    "denoising passes and a compositor Render Layers -> Denoise -> output "
                    "(when the scene has no compositor of its own)",
        default=False, update=_update_denoise,
    )

    # Integrator and the progressive mode (core/integrators/sppm.py).
    integrator: EnumProperty(
        name="Integrator",
        description="How the image is computed",
        items=INTEGRATOR_ITEMS, default='photon_map', update=_update_passes,
    )
    progressive_passes: IntProperty(
        name="Passes",
        description="Progressive passes to run when there is no time budget; each traces "
                    "Photons per Pass photons and shrinks every pixel's gather radius",
        min=1, max=MAX_PROGRESSIVE_PASSES, soft_max=4096, default=64,
    )
    photons_per_pass: IntProperty(
        name="Photons per Pass",
        description="Photons emitted in each progressive pass; memory grows with this, "
                    "not with the number of passes",
        min=1, max=MAX_PHOTONS_PER_PASS, soft_max=2_000_000, default=100_000,
    )
    viewport_passes: IntProperty(
        name="Viewport Passes",
        description="Progressive passes the 3D viewport's Rendered shading runs before it "
                    "stops refining (it restarts when the view or the scene changes); each "
                    "traces Photons per Pass photons",
        min=1, max=MAX_PROGRESSIVE_PASSES, soft_max=4096, default=256,
    )
    time_budget: FloatProperty(
        name="Time Budget",
        description="Seconds a progressive render may take, export included; it runs as "
                    "many passes as fit and reports how many. 0 runs Passes passes",
        min=0.0, max=MAX_TIME_BUDGET, soft_max=3600.0, default=0.0,
        subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE',
    )

    @classmethod
    def register(cls):
        bpy.types.Scene.photon_map = PointerProperty(
            name="Photon Map Render Settings",
            description="Photon Map render settings",
            type=cls,
        )

    @classmethod
    def unregister(cls):
        del bpy.types.Scene.photon_map


# Every setting a preset governs turns Quality to Custom when edited by hand.
for _name in PRESET_FIELDS:
    _deferred = PhotonMapRenderSettings.__annotations__[_name]
    assert "update" not in _deferred.keywords, _name
    PhotonMapRenderSettings.__annotations__[_name] = _deferred.function(
        **_deferred.keywords, update=_governed_edited)
del _name, _deferred

class PhotonMapMaterialSettings(bpy.types.PropertyGroup):
    """Per-material Photon Map settings: ``material.photon_map``."""

    dispersion: FloatProperty(
        name="Dispersion",
        description="Abbe number V_d of the material's transmission (Glass, Refraction, "
                    "Principled Transmission): the IOR is the value at 587.6 nm and varies "
                    "with the wavelength, splitting white light into a rainbow. Smaller "
                    "disperses more (crown glass 64, flint glass 36, diamond 55); 0 is off. "
                    f"Values between 0 and {MIN_ABBE:g} are refused",
        min=0.0, soft_max=100.0, default=0.0,
    )

    @classmethod
    def register(cls):
        bpy.types.Material.photon_map = PointerProperty(
            name="Photon Map Material Settings",
            description="Photon Map material settings",
            type=cls,
        )

    @classmethod
    def unregister(cls):
        del bpy.types.Material.photon_map


classes = (PhotonMapRenderSettings, PhotonMapMaterialSettings)


def to_core_settings(props):
    """The one translator from ``scene.photon_map`` to ``core.settings.RenderSettings``.

    Raises core.settings.SettingsError naming the setting when a value is out of range.
    """
    return RenderSettings().with_values(
        samples=props.samples,
        # a float32 property: 0.1 reads 0.10000000149; 6 digits give the core's value back
        adaptive_threshold=float(f"{props.adaptive_threshold:.6g}"),
        adaptive_min_samples=props.adaptive_min_samples,
        max_specular_depth=props.max_specular_depth,
        light_samples=props.light_samples,
        volume_light_samples=props.volume_light_samples,
        seed=props.seed,
        threads=props.threads,
        global_photons=props.global_photons,
        caustic_photons=props.caustic_photons,
        photon_max_bounces=props.photon_max_bounces,
        projection_map=bool(props.projection_map),
        photon_importance=bool(props.photon_importance),
        global_k=props.global_k,
        caustic_k=props.caustic_k,
        global_radius=float(props.global_radius),
        caustic_radius=float(props.caustic_radius),
        filter=props.filter,
        caustics=bool(props.caustics),
        indirect_mode=props.indirect_mode,
        final_gather_rays=props.final_gather_rays,
        photon_debug_pass=bool(props.photon_debug_pass),
        overlay_map=props.overlay_map,
        overlay_dot_radius=float(props.overlay_dot_radius),
        overlay_composite=bool(props.overlay_composite),
        pass_emission=bool(props.pass_emission),
        pass_environment=bool(props.pass_environment),
        pass_direct=bool(props.pass_direct),
        pass_specular=bool(props.pass_specular),
        pass_caustics=bool(props.pass_caustics),
        pass_indirect=bool(props.pass_indirect),
        pass_volume_direct=bool(props.pass_volume_direct),
        pass_volume_indirect=bool(props.pass_volume_indirect),
        denoising_data=bool(props.denoising_data),
        integrator=props.integrator,
        progressive_passes=props.progressive_passes,
        photons_per_pass=props.photons_per_pass,
        time_budget=float(props.time_budget),
    )


def setting_names():
    """Names of the user settings in ``scene.photon_map`` that reach the core (what the
    CLI's ``--set`` accepts); the viewport-only ones (VIEWPORT_ONLY) and Quality
    (UI_ONLY, the CLI's ``--quality``) are left out."""
    return tuple(p.identifier for p in PhotonMapRenderSettings.bl_rna.properties
                 if p.identifier not in ("rna_type", "name") + VIEWPORT_ONLY + UI_ONLY)

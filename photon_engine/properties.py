"""Render settings stored in the .blend: ``scene.photon_map``.

Settings flow one way: UI -> ``scene.photon_map`` -> ``to_core_settings`` -> ``core``.
Hard limits (``min``/``max``) mirror ``core.settings.RenderSettings.validated`` so Blender
never stores a value the core rejects; ``soft_max`` bounds the slider only. Enum
identifiers are the core's strings (core.settings.INDIRECT_MODES, FILTERS); their items
carry explicit indices so that a .blend keeps its choice if items are added.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

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

MAX_RADIUS = 1e9  # core.settings.MAX_RADIUS (imported lazily there; kept equal by a test)
MAX_DOT_RADIUS_PX = 32.0  # core.settings.MAX_DOT_RADIUS_PX (kept equal by a test)

# Properties of scene.photon_map that the core never sees (not in setting_names()).
VIEWPORT_ONLY = ("show_photons_in_viewport",)


def _update_passes(self, context):
    """The Photons pass comes and goes with photon_debug_pass: re-list the passes."""
    view_layer = getattr(context, "view_layer", None)
    if view_layer is not None:
        view_layer.update_render_passes()


class PhotonMapRenderSettings(bpy.types.PropertyGroup):
    """Photon Map's per-scene render settings (defaults match core.settings.RenderSettings)."""

    # Camera pass.
    samples: IntProperty(
        name="Samples",
        description="Camera rays per pixel, jittered within the pixel; noise falls as 1/sqrt(samples)",
        min=1, max=1 << 20, soft_max=4096, default=16,
    )
    max_specular_depth: IntProperty(
        name="Max Specular Depth",
        description="Maximum number of mirror and glass bounces followed from the camera",
        min=0, max=1024, soft_max=64, default=8,
    )
    light_samples: IntProperty(
        name="Light Samples",
        description="Shadow rays per light for each camera sample at each diffuse hit",
        min=1, max=1024, soft_max=64, default=1,
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
                    "pixel's samples (at least one per sample); more rays, less noise",
        min=1, max=1 << 16, soft_max=1024, default=64,
    )

    # Photon debug pass and viewport display (core/debug_overlay.py, overlay.py).
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


classes = (PhotonMapRenderSettings,)


def to_core_settings(props):
    """The one translator from ``scene.photon_map`` to ``core.settings.RenderSettings``.

    Raises core.settings.SettingsError naming the setting when a value is out of range.
    """
    from ..core.settings import RenderSettings

    return RenderSettings().with_values(
        samples=props.samples,
        max_specular_depth=props.max_specular_depth,
        light_samples=props.light_samples,
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
    )


def setting_names():
    """Names of the user settings in ``scene.photon_map`` that reach the core (what the
    CLI's ``--set`` accepts); the viewport-only ones (VIEWPORT_ONLY) are left out."""
    return tuple(p.identifier for p in PhotonMapRenderSettings.bl_rna.properties
                 if p.identifier not in ("rna_type", "name") + VIEWPORT_ONLY)

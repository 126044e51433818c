"""Render settings stored in the .blend: ``scene.photon_map``.

Settings flow one way: UI -> ``scene.photon_map`` -> ``to_core_settings`` -> ``core``.
Hard limits (``min``/``max``) mirror ``core.settings.RenderSettings.validated`` so Blender
never stores a value the core rejects; ``soft_max`` bounds the slider only.
"""

import bpy
from bpy.props import IntProperty, PointerProperty


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

    # Photon pass: the photon counts, gather radius and final-gathering settings of the
    # coming issues go here, each added to to_core_settings and to a panel in ui.py.

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
    )


def setting_names():
    """Names of the user settings in ``scene.photon_map`` (what the CLI's ``--set`` accepts)."""
    return tuple(p.identifier for p in PhotonMapRenderSettings.bl_rna.properties
                 if p.identifier not in ("rna_type", "name"))

"""Properties-editor panels, and Blender's own panels opened up to the engine.

Panels only lay out ``scene.photon_map``; they never talk to the renderer.
Blender shows a built-in panel only for the engines in its ``COMPAT_ENGINES``, so
``register()`` adds "PHOTON_MAP" to the engine-neutral ones (as Cycles does) and to a few
panels that are named for EEVEE but draw plain Blender data: the light's colour, power and
shape, the material slots and the Surface node view. ``unregister()`` takes it out again.
"""

import bpy

ENGINE = 'PHOTON_MAP'


def property_split(layout):
    """``layout`` in Blender's property-split style (labels in a left column, no animation
    decorators), as Cycles draws its settings panels; returned for chaining."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class PhotonMapPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def split_layout(self):
        """The panel's layout in Blender's property-split style (labels in a left column,
        no animation decorators), as Cycles' settings panels are drawn."""
        layout = property_split(self.layout)
        return layout


class PHOTON_MAP_RENDER_PT_sampling(PhotonMapPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        layout.prop(settings, "integrator")
        layout.prop(settings, "quality")
        col = layout.column(align=True)
        col.active = settings.integrator == 'photon_map'
        col.prop(settings, "adaptive_threshold")
        col.prop(settings, "samples", text="Max Samples" if settings.adaptive_threshold > 0
                 else "Samples")
        sub = col.column(align=True)
        sub.active = settings.adaptive_threshold > 0
        sub.prop(settings, "adaptive_min_samples")
        col = layout.column(align=True)
        col.prop(settings, "light_samples")  # both integrators' shadow rays
        col.prop(settings, "volume_light_samples")
        layout.prop(settings, "seed")


class PHOTON_MAP_RENDER_PT_progressive(PhotonMapPanel, bpy.types.Panel):
    """The progressive (SPPM) integrator: passes, photons per pass, time budget; and the
    viewport's Rendered shading, which is progressive whatever the integrator."""

    bl_label = "Progressive"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        col = layout.column(align=True)
        col.active = settings.integrator == 'progressive'
        col.prop(settings, "time_budget")
        sub = col.column(align=True)
        sub.prop(settings, "progressive_passes")
        sub.active = settings.time_budget == 0.0
        # The viewport's Rendered shading is always progressive: these two apply to it too.
        layout.prop(settings, "viewport_passes")
        layout.prop(settings, "photons_per_pass")


class PHOTON_MAP_VIEWLAYER_PT_passes(PhotonMapPanel, bpy.types.Panel):
    """The passes a render produces, where Blender users look for them (View Layer
    properties, as Cycles does). They are scene settings (``scene.photon_map.pass_*``),
    shared by every view layer: one settings object, one translator, the CLI's --set."""

    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        col = layout.column(heading="Light", align=True)
        col.active = settings.integrator == 'photon_map'  # progressive: Combined only
        for name in ("emission", "environment", "direct", "specular", "caustics", "indirect",
                     "volume_direct", "volume_indirect"):
            col.prop(settings, f"pass_{name}")
        col = layout.column(heading="Data", align=True)
        col.active = settings.integrator == 'photon_map'
        col.prop(settings, "denoising_data")
        col.prop(settings, "denoise")
        col = layout.column(heading="Debug", align=True)
        col.active = settings.integrator == 'photon_map'
        col.prop(settings, "photon_debug_pass", text="Photons")


class PHOTON_MAP_RENDER_PT_light_paths(PhotonMapPanel, bpy.types.Panel):
    bl_label = "Light Paths"

    def draw(self, context):
        layout = property_split(self.layout)
        layout.prop(context.scene.photon_map, "max_specular_depth")


class PHOTON_MAP_RENDER_PT_photons(PhotonMapPanel, bpy.types.Panel):
    """The first pass: photon counts and the radiance estimate of each map."""

    bl_label = "Photons"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        col = layout.column(align=True)
        col.prop(settings, "global_photons")
        col.prop(settings, "global_k")
        col.prop(settings, "global_radius")
        col = layout.column(align=True)
        col.prop(settings, "caustics")
        col.prop(settings, "caustic_photons")
        col.prop(settings, "caustic_k")
        col.prop(settings, "caustic_radius")
        layout.prop(settings, "filter")
        layout.prop(settings, "projection_map")
        layout.prop(settings, "photon_importance")


class PHOTON_MAP_RENDER_PT_indirect(PhotonMapPanel, bpy.types.Panel):
    """The second pass: how indirect diffuse light is rendered."""

    bl_label = "Indirect"

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        layout.prop(settings, "indirect_mode")
        col = layout.column(align=True)
        col.prop(settings, "final_gather_rays")
        col.active = settings.indirect_mode == 'final_gather'
        layout.prop(settings, "photon_max_bounces")


class PHOTON_MAP_RENDER_PT_performance(PhotonMapPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = property_split(self.layout)
        layout.prop(context.scene.photon_map, "threads")
        layout.prop(context.scene.photon_map, "dask_scheduler")


class PHOTON_MAP_RENDER_PT_debug(PhotonMapPanel, bpy.types.Panel):
    """Looking at the photon maps: the Photons render pass and the viewport points."""

    bl_label = "Photon Debug"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = property_split(self.layout)
        settings = context.scene.photon_map
        layout.prop(settings, "overlay_map")
        col = layout.column(heading="Render")
        col.prop(settings, "photon_debug_pass")
        sub = col.column()
        sub.active = settings.photon_debug_pass
        sub.prop(settings, "overlay_dot_radius")
        sub.prop(settings, "overlay_composite")
        layout.prop(settings, "show_photons_in_viewport")


class PHOTON_MAP_OBJECT_PT_visibility(PhotonMapPanel, bpy.types.Panel):
    """Ray visibility flags the exporter honours (Blender shows them for Cycles/EEVEE only)."""

    bl_label = "Visibility"
    bl_context = "object"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        obj = context.object
        col = layout.column(heading="Show In")
        col.prop(obj, "hide_viewport", text="Viewports", toggle=False, invert_checkbox=True)
        col.prop(obj, "hide_render", text="Renders", toggle=False, invert_checkbox=True)
        col = layout.column(heading="Ray Visibility")
        col.prop(obj, "visible_camera", text="Camera", toggle=False)
        col.prop(obj, "visible_diffuse", text="Diffuse", toggle=False)
        col.prop(obj, "visible_glossy", text="Glossy", toggle=False)
        col.prop(obj, "visible_transmission", text="Transmission", toggle=False)
        if obj.type != 'LIGHT':
            col.prop(obj, "visible_shadow", text="Shadow", toggle=False)


class PHOTON_MAP_MATERIAL_PT_settings(PhotonMapPanel, bpy.types.Panel):
    """The material's own Photon Map settings (docs/dispersion.md)."""

    bl_label = "Photon Map"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.material is not None and context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = property_split(self.layout)
        layout.prop(context.material.photon_map, "dispersion")


classes = (
    PHOTON_MAP_RENDER_PT_sampling,
    PHOTON_MAP_RENDER_PT_progressive,
    PHOTON_MAP_RENDER_PT_light_paths,
    PHOTON_MAP_RENDER_PT_photons,
    PHOTON_MAP_RENDER_PT_indirect,
    PHOTON_MAP_RENDER_PT_performance,
    PHOTON_MAP_RENDER_PT_debug,
    PHOTON_MAP_OBJECT_PT_visibility,
    PHOTON_MAP_MATERIAL_PT_settings,
    PHOTON_MAP_VIEWLAYER_PT_passes,
)

# Engine-neutral panels (those listing 'BLENDER_RENDER') we do not want: previews need
# bl_use_preview; DATA_PT_light shows only the light type outside EEVEE (its EEVEE twin
# below shows everything); the object visibility panel is replaced by ours.
EXCLUDED_PANELS = {
    'DATA_PT_light',
    'NODE_DATA_PT_light',
    'DATA_PT_preview',
    'MATERIAL_PT_preview',
    'OBJECT_PT_visibility',
    'VIEWLAYER_PT_filter',
    'VIEWLAYER_PT_layer_passes',
}

# Built-in panels tagged for EEVEE whose draw() uses only engine-independent data.
BORROWED_PANELS = (
    'DATA_PT_EEVEE_light',  # colour, power, radius, sun angle, area shape and size
    'NODE_DATA_PT_EEVEE_light',  # the same in the Shader Editor's sidebar
    'EEVEE_MATERIAL_PT_context_material',  # material slots
    'EEVEE_MATERIAL_PT_surface',  # the Surface node view
    'EEVEE_WORLD_PT_surface',  # the world's Background node view
)


def compatible_panels():
    """The built-in panel classes that should also show for Photon Map."""
    panels = [cls for cls in bpy.types.Panel.__subclasses__()
              if 'BLENDER_RENDER' in getattr(cls, 'COMPAT_ENGINES', ())
              and cls.__name__ not in EXCLUDED_PANELS]
    panels += [getattr(bpy.types, name) for name in BORROWED_PANELS if hasattr(bpy.types, name)]
    return panels


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE)


def unregister():
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)

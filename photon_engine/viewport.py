"""Rendered shading in the 3D viewport: progressive photon mapping (SPPM) through the view,
refined while the view stays still.

Blender calls ``RenderEngine.view_update`` when the scene changes and ``view_draw`` to
draw a view (photon_engine/engine.py). ``ViewportRender`` holds one view's state: the
exported scene and a ``core.progressive`` run through the view's camera
(``view_camera``: Blender's view and window matrices, so zoom, pan, orthographic views
and the camera view with its frame all come for free).

- A scene change (``view_update``: geometry, materials, lights, world, settings)
  re-exports on the next draw and restarts the passes.
- A view change (orbit, zoom, pan, resize, Viewport Pixel Size) keeps the exported
  scene and restarts the passes with the new camera.
- Each draw runs passes for at most STEP_SECONDS (at least one), shows the image and asks
  for another draw (``tag_redraw``) until ``viewport_passes`` passes are done.
- The image has Blender's Viewport Pixel Size, coarser where the view is larger than
  MAX_PIXELS (``render_size``), so a pass stays near 0.2 s on 2 cores.

Everything runs on Blender's main thread, between draws, as small slices: no render
thread to stop and no data shared with one. The progressive integrator is the natural
fit for a view that keeps changing: its first pass is cheap, each further pass refines,
and it needs no photon map built up front.

A scene the core refuses (a SceneError or SettingsError) shows its message in the
viewport's status text and stops the passes until the next change. The image goes to
the GPU as a float texture drawn with Blender's display-space shader, so the scene's
view transform and look apply as in the Image Editor.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

STEP_SECONDS = 0.1
"""Longest time one draw spends on passes (at least one pass runs): the view's latency."""
MAX_PIXELS = 120_000
"""Most pixels the viewport renders (upscaled to the view beyond): a pass costs about
1.3 us per pixel on 2 cores (0.57 s at 740 x 600, 0.17 s at 370 x 300 on the demo box
with 100,000 photons per pass), and each pass holds Blender's interface while it runs."""


def view_camera(region_data, width: int, height: int, scene_camera=None):
    """The core Camera of a 3D view (``RegionView3D``) rendered at ``width`` x ``height``.

    scene_camera: the scene's camera object; when the view looks through it
    (``view_perspective == 'CAMERA'``), its depth of field applies, as in Cycles' viewport.
    """
    from ..core.scene.camera import camera_from_projection
    from .export_camera import depth_of_field

    to_world = np.array(region_data.view_matrix.inverted(), np.float64)
    projection = np.array(region_data.window_matrix, np.float64)
    camera = camera_from_projection(to_world, projection, width, height, name="Viewport")
    if scene_camera is not None and getattr(region_data, "view_perspective", "") == 'CAMERA' \
            and scene_camera.type == 'CAMERA':
        camera = dataclasses.replace(camera, **depth_of_field(scene_camera, scene_camera.data))
    return camera


def view_region(space, region_data, width: int, height: int, scene=None) -> tuple | None:
    """The viewport's Render Region as core pixels (x0, y0, x1, y1) of the ``width`` x
    ``height`` image, row 0 at the top, x1 and y1 exclusive; None without one.

    Outside the camera view it is View3D's own (``use_render_border``, fractions of the
    view). Looking through the camera it is the scene's (``render.use_border``, fractions of
    the camera frame), as Blender and Cycles render it: the camera frame is placed in the
    view (``camera_frame_in_view``) and the border taken as a part of it."""
    if space is None:
        return None
    if getattr(region_data, "view_perspective", "") == 'CAMERA':
        render = getattr(scene, "render", None)
        if render is None or scene.camera is None or not render.use_border:
            return None
        fx0, fy0, fx1, fy1 = camera_frame_in_view(region_data, scene)
        border = (fx0 + render.border_min_x * (fx1 - fx0), fy0 + render.border_min_y * (fy1 - fy0),
                  fx0 + render.border_max_x * (fx1 - fx0), fy0 + render.border_max_y * (fy1 - fy0))
    elif getattr(space, "use_render_border", False):
        border = (space.render_border_min_x, space.render_border_min_y,
                  space.render_border_max_x, space.render_border_max_y)
    else:
        return None

    def pixel(fraction, size):
        return int(math.floor(min(max(float(fraction), 0.0), 1.0) * size + 0.5))

    x0, x1 = pixel(border[0], width), pixel(border[2], width)
    y0, y1 = pixel(border[1], height), pixel(border[3], height)
    if x1 <= x0 or y1 <= y0 or (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return (x0, height - y1, x1, height - y0)  # Blender's rows count from the bottom


def camera_frame_in_view(region_data, scene) -> tuple[float, float, float, float]:
    """The scene camera's frame (``Camera.view_frame`` at the scene's resolution, lens shift
    and sensor fit included) in a 3D view, as fractions (x0, y0, x1, y1) of the view, y up
    from the bottom as Blender's borders are: its corners through the view's perspective
    matrix (window x view), which is Blender's camera-frame-in-view for the camera view."""
    camera = scene.camera
    corners = np.array([tuple(camera.matrix_world @ c) + (1.0,)
                        for c in camera.data.view_frame(scene=scene)], np.float64)
    projection = np.array(region_data.window_matrix, np.float64) \
        @ np.array(region_data.view_matrix, np.float64)
    clip = corners @ projection.T                   # (4, 4) homogeneous clip coordinates
    ndc = clip[:, :2] / clip[:, 3:4]                # (4, 2) in [-1, 1] across the view
    lo, hi = (ndc.min(axis=0) + 1.0) / 2.0, (ndc.max(axis=0) + 1.0) / 2.0
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def render_size(width: int, height: int, pixel_size: int = 1) -> tuple[int, int]:
    """Pixels to render for a ``width`` x ``height`` view: Blender's Viewport Pixel Size
    (``pixel_size``, 1 for full resolution), coarser still where the view holds more than
    MAX_PIXELS, at least 1 x 1."""
    scale = max(1, int(pixel_size), math.ceil(math.sqrt(width * height / MAX_PIXELS)))
    return max(1, width // scale), max(1, height // scale)


def _view_key(camera) -> tuple:
    return (camera.to_world.tobytes(), np.asarray(camera.film_size).tobytes(),
            np.asarray(camera.film_shift).tobytes(), camera.kind, camera.width,
            camera.height, camera.clip_start, camera.clip_end, camera.aperture_radius,
            camera.focus_distance, camera.aperture_blades, camera.aperture_rotation,
            camera.aperture_ratio, camera.region)


class ViewportRender:
    """One 3D view's progressive render (see the module doc)."""

    def __init__(self):
        self.scene = None        # core.Scene exported for this view
        self.origin = None       # (3,) world position of its render frame (ExportResult.origin)
        self.state = None        # core.integrators.sppm.SPPMState after the latest pass
        self.error = None        # message of a scene the core refused
        self.target = 0          # passes to run
        self._passes = None      # the running progressive_passes generator
        self._view = None        # _view_key of the camera the passes run through
        self._stale = True       # the scene changed since it was exported
        self._texture = None     # (passes shown, GPUTexture)

    def scene_changed(self) -> None:
        """``view_update``: re-export on the next ``sync``."""
        self._stale = True

    def sync(self, depsgraph, camera) -> None:
        """Restart the passes if the scene or the view changed since the last call."""
        from ..core import progressive
        from ..core.scene.contract import SceneError
        from ..core.settings import SettingsError
        from .export import export_scene
        from .export_camera import relative_camera
        from .properties import to_core_settings

        if not self._stale and _view_key(camera) == self._view:
            return
        self.close()
        self._view, self.state, self.error, self._texture = _view_key(camera), None, None, None
        try:
            if self._stale or self.scene is None:
                exported = export_scene(depsgraph, camera=camera)
                self.scene, self.origin = exported.scene, exported.origin
            else:  # the same render frame: only the view moved
                self.scene = dataclasses.replace(self.scene,
                                                 camera=relative_camera(camera, self.origin))
            props = depsgraph.scene.photon_map
            settings = to_core_settings(props)
            self.target = int(props.viewport_passes)
            self._passes = progressive(self.scene, settings, max_passes=self.target)
        except (SceneError, SettingsError) as error:
            self.error = str(error)
        self._stale = False

    def step(self, seconds: float = STEP_SECONDS) -> bool:
        """Run passes for up to ``seconds`` (at least one); True while more are to come."""
        from ..core.scene.contract import SceneError
        from ..core.settings import SettingsError

        if self._passes is None:
            return False
        started = time.perf_counter()
        try:
            while True:
                self.state = next(self._passes)
                if self.state.passes >= self.target or time.perf_counter() - started >= seconds:
                    break
        except StopIteration:
            self._passes = None
        except (SceneError, SettingsError) as error:
            self.error, self._passes = str(error), None
        if self.state is not None and self.state.passes >= self.target:
            self.close()
        return self._passes is not None

    def image(self) -> np.ndarray | None:
        """(H, W, 3) float32 radiance after the latest pass, row 0 at the top; None before."""
        return None if self.state is None else self.state.radiance()

    def status(self) -> str:
        if self.error:
            return f"Photon Map: {self.error}"
        if self.state is None:
            return "Photon Map | Viewport: starting"
        done = "" if self._passes is not None else " (done)"
        return f"Photon Map | Viewport: pass {self.state.passes} of {self.target}{done}"

    def texture(self):
        """The latest image as a GPU texture (made again only after a new pass)."""
        import gpu

        passes = self.state.passes
        if self._texture is None or self._texture[0] != passes:
            image = self.image()
            h, w = image.shape[:2]
            rgba = np.ones((h, w, 4), np.float32)
            rgba[..., :3] = image
            region = self.scene.camera.region if self.scene is not None else None
            if region is not None:  # outside the Render Region the view shows through
                x0, y0, x1, y1 = region
                inside = np.zeros((h, w), bool)
                inside[y0:y1, x0:x1] = True
                rgba[~inside] = 0.0
            rgba = np.ascontiguousarray(rgba[::-1])  # GPU textures start at the bottom row
            data = gpu.types.Buffer('FLOAT', rgba.size, rgba.ravel())
            self._texture = (passes, gpu.types.GPUTexture((w, h), format='RGBA16F', data=data))
        return self._texture[1]

    def close(self) -> None:
        """Stop the running passes (closes their Embree scene)."""
        if self._passes is not None:
            self._passes.close()
            self._passes = None


def _viewport(engine) -> ViewportRender:
    """The engine instance's ViewportRender (Blender makes one engine instance per view)."""
    viewport = getattr(engine, "photon_viewport", None)
    if viewport is None:
        engine.photon_viewport = viewport = ViewportRender()
    return viewport


def view_update(engine, depsgraph) -> None:
    """``RenderEngine.view_update``: the scene changed."""
    _viewport(engine).scene_changed()


def view_draw(engine, context, depsgraph) -> None:
    """``RenderEngine.view_draw``: refine for a slice of time, then draw the image."""
    import gpu
    from gpu_extras.presets import draw_texture_2d

    from .render import load_embree_isolated

    viewport = _viewport(engine)
    region = context.region
    width, height = render_size(region.width, region.height,
                                int(engine.get_preview_pixel_size(depsgraph.scene)))
    load_embree_isolated()
    try:
        camera = view_camera(context.region_data, width, height, depsgraph.scene.camera)
        camera = dataclasses.replace(camera, region=view_region(
            context.space_data, context.region_data, width, height, depsgraph.scene))
    except ValueError as error:  # a degenerate view matrix: nothing to render through
        engine.update_stats("", f"Photon Map: viewport: {error}")
        return
    viewport.sync(depsgraph, camera)
    more = viewport.step()
    engine.update_stats("", viewport.status())
    if viewport.state is not None:
        gpu.state.blend_set('ALPHA_PREMULT')
        engine.bind_display_space_shader(depsgraph.scene)
        draw_texture_2d(viewport.texture(), (0, 0), region.width, region.height)
        engine.unbind_display_space_shader()
        gpu.state.blend_set('NONE')
    if more:
        engine.tag_redraw()

"""The photons of the last render, drawn as points in the 3D viewport.

After a render, ``render.py`` hands the photon positions and display colours to
``set_photons``; they are kept here (module level: one set per Blender session, like the
last Render Result) as a random sample of at most ``MAX_VIEWPORT_PHOTONS``. A
``SpaceView3D`` draw handler (``'WINDOW'``, ``'POST_VIEW'``: world space, depth-tested
against the scene) draws them with the ``gpu`` module whenever the scene's
``photon_map.show_photons_in_viewport`` is on.

Threads: Blender renders on a job thread, so ``set_photons`` only swaps arrays and raises
a flag; the GPU batch is built lazily inside the draw handler (main thread, GPU context)
and a timer on the main thread tags the 3D views for redraw when the flag is up.

Background mode (``blender -b``, the ``bpy`` module) has no GPU context: ``register``
adds no handler and no timer, and ``draw`` returns before touching ``gpu``. Where a
shader cannot be created (no GPU, an old driver), drawing is switched off for the session
with one message on the console.

Imports only ``bpy`` (and ``gpu`` inside functions): every other module may import it.
"""

from __future__ import annotations

import numpy as np

import bpy

# At most this many points are drawn: 200 000 points cost ~5 MB of vertex buffer and draw
# in well under a frame; a photon map of millions would stall the viewport.
MAX_VIEWPORT_PHOTONS = 200_000
# Point diameter in pixels.
POINT_SIZE_PX = 3.0
# How often (seconds) the main thread looks for new photons to show.
REDRAW_POLL_SECONDS = 0.5
# The sample is reproducible: the same render shows the same points.
SAMPLE_SEED = 0x5EED
ENGINE = 'PHOTON_MAP'


class _Points:
    """The photons on show: positions (M, 3) float32 metres, colors (M, 4) float32 RGBA."""

    def __init__(self):
        # (positions, colors), replaced as one tuple so that the main thread never sees
        # the positions of one render with the colours of another.
        self.data: tuple[np.ndarray, np.ndarray] | None = None
        self.total = 0  # photons before sampling
        self.batch = None  # gpu.types.GPUBatch, built by draw() on the main thread
        self.batch_data = None  # the ``data`` tuple the batch was built from
        self.shader = None
        self.shader_name = ""
        self.gpu_failed = False  # a shader or batch could not be made: drawing is off
        self.dirty = False  # new points since the last redraw request


_points = _Points()
_handle = None  # the SpaceView3D draw handler, None when not registered
_timer_registered = False


def set_photons(positions, colors, *, max_points: int = MAX_VIEWPORT_PHOTONS,
                seed: int = SAMPLE_SEED) -> int:
    """Keep photons for the viewport; returns how many are kept.

    positions: (N, 3) world-space metres (any float dtype; kept as float32).
    colors: (N, 3) or (N, 4) linear RGB(A), e.g. ``core.integrators.debug_overlay.display_colors``;
        clamped to [0, 1] for display, alpha 1 when not given.
    max_points: more photons than this are replaced by a uniform random sample of this
        many (without replacement, in their original order), drawn with ``seed``.

    Safe to call from the render thread: no GPU work happens here.
    """
    positions = np.asarray(positions)
    colors = np.asarray(colors)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"photon positions must have shape (N, 3), got {positions.shape}")
    n = positions.shape[0]
    if colors.ndim != 2 or colors.shape[0] != n or colors.shape[1] not in (3, 4):
        raise ValueError(f"photon colors must have shape ({n}, 3) or ({n}, 4), got {colors.shape}")
    if int(max_points) < 0:
        raise ValueError(f"max_points must be >= 0, got {max_points}")
    if n > max_points:
        keep = np.sort(np.random.default_rng(seed).choice(n, int(max_points), replace=False))
        positions, colors = positions[keep], colors[keep]
    rgba = np.ones((positions.shape[0], 4), np.float32)
    rgba[:, :colors.shape[1]] = np.clip(np.nan_to_num(colors, nan=0.0), 0.0, 1.0)
    _points.data = (np.ascontiguousarray(positions, np.float32), rgba)
    _points.total = n
    _points.dirty = True
    return int(positions.shape[0])


def photons():
    """(positions (M, 3) float32, colors (M, 4) float32) on show, or None."""
    return _points.data


def clear() -> None:
    """Forget the photons (a new file is loaded, or the extension is disabled)."""
    _points.data = _points.batch = _points.batch_data = None
    _points.total = 0
    _points.dirty = True


def enabled(scene) -> bool:
    """The scene's toggle ``photon_map.show_photons_in_viewport`` (False if absent), and
    only while Photon Map is the scene's engine: the toggle's panel is not shown for the
    other engines, so their users could not turn the points off."""
    render = getattr(scene, "render", None)
    if getattr(render, "engine", None) != ENGINE:
        return False
    settings = getattr(scene, "photon_map", None)
    return bool(getattr(settings, "show_photons_in_viewport", False))


def draw() -> bool:
    """The POST_VIEW draw handler; returns whether it drew (for tests)."""
    data = _points.data
    if bpy.app.background or _points.gpu_failed or data is None or len(data[0]) == 0:
        return False
    if not enabled(bpy.context.scene):
        return False
    try:
        import gpu

        if _points.batch_data is not data:
            _build_batch(data)
        gpu.state.depth_test_set('LESS_EQUAL')
        gpu.state.point_size_set(POINT_SIZE_PX)
        _points.shader.bind()
        if _points.shader_name.startswith("POINT_"):
            _points.shader.uniform_float("size", POINT_SIZE_PX)
        _points.batch.draw(_points.shader)
        gpu.state.depth_test_set('NONE')
        gpu.state.point_size_set(1.0)
    except Exception as error:  # no GPU context / shader: say it once, stop trying
        _points.gpu_failed = True
        print(f"Photon Map: viewport photon display disabled ({type(error).__name__}: {error})")
        return False
    return True


def _build_batch(data):
    """The shader and the vertex batch of ``data`` (main thread, GPU context)."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    if _points.shader is None:
        # POINT_FLAT_COLOR: per-point colour, a ``size`` uniform (bpy 5.0.1 lists it, and
        # warns that drawing points with FLAT_COLOR is deprecated). FLAT_COLOR and
        # '3D_FLAT_COLOR' are the fallbacks of Blender 3.x, sized by point_size_set.
        for name in ("POINT_FLAT_COLOR", "FLAT_COLOR", "3D_FLAT_COLOR"):
            try:
                _points.shader = gpu.shader.from_builtin(name)
            except (ValueError, TypeError):
                continue
            _points.shader_name = name
            break
        else:
            raise RuntimeError("no built-in flat-colour shader")
    positions, colors = data
    _points.batch = batch_for_shader(_points.shader, 'POINTS', {"pos": positions, "color": colors})
    _points.batch_data = data


def tag_redraw() -> None:
    """Redraw every 3D view (main thread only)."""
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


def update_toggle(self, context) -> None:
    """``update=`` of ``show_photons_in_viewport`` and ``overlay_map``: redraw the views."""
    tag_redraw()


def _poll_redraw():
    if _points.dirty:
        _points.dirty = False
        tag_redraw()
    return REDRAW_POLL_SECONDS


@bpy.app.handlers.persistent
def _on_load_pre(*_args):
    clear()


def register() -> None:
    """Add the draw handler, the redraw timer and the file-load hook (not in background)."""
    global _handle, _timer_registered
    if bpy.app.background or _handle is not None:
        return
    _handle = bpy.types.SpaceView3D.draw_handler_add(draw, (), 'WINDOW', 'POST_VIEW')
    bpy.app.timers.register(_poll_redraw, first_interval=REDRAW_POLL_SECONDS, persistent=True)
    _timer_registered = True
    if _on_load_pre not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(_on_load_pre)


def unregister() -> None:
    """Remove everything ``register`` added, and the photons."""
    global _handle, _timer_registered
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, 'WINDOW')
        _handle = None
    if _timer_registered and bpy.app.timers.is_registered(_poll_redraw):
        bpy.app.timers.unregister(_poll_redraw)
    _timer_registered = False
    if _on_load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_on_load_pre)
    clear()
    _points.shader = None
    _points.gpu_failed = False


def is_registered() -> bool:
    """Whether the draw handler is installed."""
    return _handle is not None

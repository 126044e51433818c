"""One final render (F12, ``bpy.ops.render.render``, ``blender -b ... -f N``, the CLI).

``render_frame`` is the whole body of ``PhotonMapRenderEngine.render``: export the
depsgraph to a ``core.Scene``, translate the settings, run the core with a progress
callback wired to Blender's progress bar, stats line and Esc, then write the passes into
the Render Result. Bad scenes and settings end as one ERROR report naming the problem
(``bpy.ops.render.render`` raises ``RuntimeError("Error: <message>")``), never a traceback.

Heavy imports (``core``: numba, embreex) happen inside the functions, at render time.
"""

import os
import sys
import time

import numpy as np

# Core pass name -> Blender render pass name (Blender 5.0 names its own "Emission" and
# "Environment"; "Combined" is written separately with alpha). Every pass the core
# produces has an entry (tests/blender/test_engine.py checks it), so none is ever dropped.
EXTRA_PASSES = {
    "emission": "Emission",
    "environment": "Environment",
    "direct": "Direct",
    "specular": "Specular",
    "caustics": "Caustics",
    "indirect": "Indirect",
}
# The photon debug pass (core/debug_overlay.py): RGBA, registered only when switched on,
# so it is not in EXTRA_PASSES (which are RGB and always there).
DEBUG_PASS = ("photons", "Photons")


def register_passes(engine, scene, view_layer):
    """``RenderEngine.update_render_passes``: declare the passes a render will fill."""
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", 'COLOR')
    for name in EXTRA_PASSES.values():
        engine.register_pass(scene, view_layer, name, 3, "RGB", 'COLOR')
    settings = getattr(scene, "photon_map", None)
    if settings is not None and settings.photon_debug_pass:
        engine.register_pass(scene, view_layer, DEBUG_PASS[1], 4, "RGBA", 'COLOR')


def render_frame(engine, depsgraph):
    """Render ``depsgraph``'s view layer into ``engine``'s Render Result."""
    from ..core.scene import SceneError
    from ..core.settings import SettingsError

    load_embree_isolated()
    try:
        _render(engine, depsgraph)
    except (SceneError, SettingsError) as error:
        # A scene or setting the engine refuses: one message, no traceback, no result.
        engine.report({'ERROR'}, f"Photon Map: {error}")
    except Exception as error:
        # A bug: say so in the UI too (Blender would only print the traceback).
        engine.report({'ERROR'}, f"Photon Map internal error, see the console: "
                                 f"{type(error).__name__}: {error}")
        raise


def _render(engine, depsgraph):
    from ..core import integrator
    from .export import export_scene
    from .properties import to_core_settings

    started = time.perf_counter()
    # Fail fast: settings and scene are checked (by the exporter) before the render.
    settings = to_core_settings(depsgraph.scene.photon_map)
    engine.update_stats("", "Photon Map | Exporting scene")
    exported = export_scene(depsgraph)
    for warning in exported.warnings:
        engine.report({'WARNING'}, warning)

    output = integrator.render(exported.scene, settings, progress=progress_callback(engine))
    show_in_viewport(output.photon_maps, settings.overlay_map)

    # A cancelled render still delivers what it has, like Cycles.
    write_passes(engine, depsgraph.view_layer.name, output.passes)
    elapsed = time.perf_counter() - started
    state = "Cancelled" if output.cancelled else "Done"
    summary = photon_summary(output.stats)
    engine.update_stats("", f"Photon Map | {state} in {elapsed:.2f} s | {summary}")
    print(f"Photon Map: {state.lower()} in {elapsed:.2f} s; {summary}")
    for line in photon_log(output.stats):
        print(f"Photon Map: {line}")
    if not output.cancelled:
        engine.update_progress(1.0)


def show_in_viewport(maps, which):
    """Hand the render's photons (``RenderOutput.photon_maps``, None = no map) of the map(s)
    ``which`` to the viewport display; nothing in background mode, which draws nothing."""
    import bpy

    if bpy.app.background:
        return
    from ..core import debug_overlay
    from . import overlay

    positions, flux = debug_overlay.select_photons(
        maps.global_map if maps else None, maps.caustic_map if maps else None, which)
    overlay.set_photons(positions, debug_overlay.display_colors(flux))


def photon_summary(stats) -> str:
    """One line for the stats bar: the maps built with their photon counts, or why not.

    stats: ``RenderOutput.stats`` (core/integrator.py).
    """
    parts = []
    for term, key, label in (("caustics", "caustic_photons_stored", "caustic map"),
                             ("indirect", "global_photons_stored", "global map")):
        stored = int(stats.get(key, 0))
        why = stats.get("skipped", {}).get(term)
        if why:
            parts.append(f"no {label} ({why})")
        elif stored:
            parts.append(f"{label} {stored:,} photons")
    return ", ".join(parts) if parts else "no photon map"


def photon_log(stats) -> list[str]:
    """Lines for the render log: the tracer's decisions, the radii, the photon timings."""
    lines = list(stats.get("photon_maps", {}).get("decisions", []))
    for term, why in stats.get("skipped", {}).items():
        lines.append(f"{term} not rendered: {why}")
    for key, label in (("caustic", "caustic"), ("global", "global")):
        if stats.get(f"{key}_photons_stored"):
            lines.append(f"{label} map: {stats[f'{key}_photons_stored']:,} photons stored, "
                         f"gather radius {stats.get(f'{key}_radius', 0.0):.4g} m")
    if stats.get("gather_rays_per_sample"):
        lines.append(f"final gathering: {stats['gather_rays_per_sample']} rays per camera "
                     f"sample, {stats.get('rays_gather', 0):,} gather rays")
    if "time_photons" in stats:
        lines.append(f"photon pass {stats['time_photons']:.2f} s (radiance cache "
                     f"{stats.get('time_cache', 0.0):.2f} s), camera pass "
                     f"{stats.get('time_render', 0.0):.2f} s (final gathering "
                     f"{stats.get('time_gather', 0.0):.2f} s, caustics "
                     f"{stats.get('time_caustics', 0.0):.2f} s)")
    return lines


def load_embree_isolated():
    """Import embreex's extension modules so that they bind to their own Embree 4.

    Debian's Blender links the system Embree 3 (``libembree3.so.3``), whose functions have
    the same unversioned names as the Embree 4 bundled in the embreex wheel
    (``rtcNewScene``, ``rtcIntersect1``, ...). The dynamic linker resolves embreex's calls
    to the copy already in the process, and the first ray crashes Blender. When such a
    clash exists (Linux only), embreex is loaded with ``RTLD_DEEPBIND``, which makes a
    library look up its own dependencies first. Official Blender builds hide their
    Embree, so there this does nothing; once embreex is imported it is a no-op.
    """
    if "embreex.rtcore_scene" in sys.modules or not hasattr(os, "RTLD_DEEPBIND"):
        return
    import ctypes

    try:
        clash = hasattr(ctypes.CDLL(None), "rtcNewDevice")
    except OSError:
        return
    if not clash:
        return
    flags = sys.getdlopenflags()
    sys.setdlopenflags(flags | os.RTLD_DEEPBIND)
    try:
        import embreex.mesh_construction  # noqa: F401
        import embreex.rtcore_scene  # noqa: F401
    finally:
        sys.setdlopenflags(flags)


def progress_callback(engine):
    """The core's ``progress(fraction, message) -> cancel`` wired to Blender: progress bar,
    status line, and Esc (``test_break``) as the answer."""

    def progress(fraction, message):
        engine.update_progress(fraction)
        engine.update_stats("", f"Photon Map | {message}")
        return engine.test_break()

    return progress


def write_passes(engine, layer_name, passes):
    """Write core images into a new Render Result for ``layer_name``.

    passes: name -> (H, W, 3) float32 radiance, row 0 at the TOP (core convention);
    "photons" (H, W, 4) RGBA goes to the Photons pass when that is registered.
    Blender's ``RenderPass.rect`` is (H*W, channels) with row 0 at the BOTTOM.
    """
    combined = passes["combined"]
    height, width = combined.shape[:2]
    result = engine.begin_result(0, 0, width, height, layer=layer_name)
    try:
        layer = result.layers[0]
        alpha = np.ones((height, width, 1), np.float32)
        layer.passes["Combined"].rect = _to_rect(np.concatenate([combined, alpha], axis=2))
        for core_name, blender_name in EXTRA_PASSES.items():
            if core_name in passes:
                render_pass = layer.passes.get(blender_name)
                if render_pass is not None:
                    render_pass.rect = _to_rect(passes[core_name])
        core_name, blender_name = DEBUG_PASS
        if core_name in passes and layer.passes.get(blender_name) is not None:
            layer.passes[blender_name].rect = _to_rect(passes[core_name])
    finally:
        engine.end_result(result)


def _to_rect(image):
    """(H, W, C) top-first image -> (H*W, C) contiguous float32, bottom row first."""
    return np.ascontiguousarray(image[::-1], dtype=np.float32).reshape(-1, image.shape[2])

"""One final render (F12, ``bpy.ops.render.render``, ``blender -b ... -f N``, the CLI).

``render_frame`` is the whole body of ``PhotonMapRenderEngine.render``: export the
depsgraph to a ``core.Scene``, translate the settings, run the core with a progress
callback wired to Blender's progress bar, stats line and Esc, then write the passes into
the Render Result. Bad scenes and settings end as one ERROR report naming the problem
(``bpy.ops.render.render`` raises ``RuntimeError("Error: <message>")``), never a traceback.

The core's one entry point, ``core.render``, runs the setting's integrator: photon maps +
final gathering, or progressive SPPM (Combined only, passes until the pass count or the
time budget is used). Long renders fill in: the Render Result is begun once
(``ResultWriter``), partial images go to it with ``engine.update_result`` (the core's
throttled ``on_tile``: tiles, or each progressive pass), and the final passes end it, also
after Esc, which keeps what was rendered.

Heavy imports (``core``: numba, embreex) happen inside the functions, at render time.
"""

import os
import sys
import threading
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
    "volume_direct": "Volume Direct",
    "volume_indirect": "Volume Indirect",
}
VOLUME_PASSES = ("volume_direct", "volume_indirect")
"""Filled only for a scene with a medium (the World's Volume, photon_engine/export_volumes.py)."""
# The photon debug pass (core/integrators/debug_overlay.py): RGBA, not part of Combined.
DEBUG_PASS = ("photons", "Photons")
# Denoising features (core/denoise_features.py), under Cycles' pass names, which the
# compositor's Denoise node takes: (core name, Blender name, channel ids).
DENOISING_PASSES = (("denoising_albedo", "Denoising Albedo", "RGB"),
                    ("denoising_normal", "Denoising Normal", "XYZ"))

PASS_UPDATE_SECONDS = 0.2
"""Least time between two progressive images sent to Blender (very fast passes)."""


def render_passes(props, medium: bool = False):
    """The passes a render with settings ``props`` (``scene.photon_map``; None = defaults)
    fills besides Combined: [(core name, Blender name, channels, channel ids)]. The light
    passes switched on (``pass_*``; Volume Direct / Indirect only when ``medium``, the
    scene has one), then Photons when the debug pass is on (neither in progressive mode,
    which produces no light passes), then the denoising features (both integrators make
    them)."""
    progressive = props is not None and props.integrator == 'progressive'
    out = [(core_name, blender_name, 3, "RGB") for core_name, blender_name in EXTRA_PASSES.items()
           if not progressive and (props is None or getattr(props, f"pass_{core_name}"))
           and (medium or core_name not in VOLUME_PASSES)]
    if props is not None and props.photon_debug_pass and not progressive:
        out.append((*DEBUG_PASS, 4, "RGBA"))
    if props is not None and props.denoising_data:
        out.extend((core, blender, 3, chan) for core, blender, chan in DENOISING_PASSES)
    return out


def register_passes(engine, scene, view_layer):
    """``RenderEngine.update_render_passes``: declare the passes a render will fill."""
    from .export_volumes import scene_has_medium
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", 'COLOR')
    for _, name, channels, chan_id in render_passes(getattr(scene, "photon_map", None),
                                                    scene_has_medium(scene)):
        engine.register_pass(scene, view_layer, name, channels, chan_id,
                             'VECTOR' if chan_id == "XYZ" else 'COLOR')


def render_frame(engine, depsgraph):
    """Render ``depsgraph``'s view layer into ``engine``'s Render Result."""
    from ..core.scene.contract import SceneError
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
    from ..core import render as core_render
    from .export import export_scene
    from .properties import to_core_settings

    started = time.perf_counter()
    # Fail fast: settings and scene are checked (by the exporter) before the render.
    settings = to_core_settings(depsgraph.scene.photon_map)
    engine.update_stats("", "Photon Map | Exporting scene")
    exported = export_scene(depsgraph)
    for warning in exported.warnings:
        engine.report({'WARNING'}, warning)

    writer = ResultWriter(engine, depsgraph.view_layer.name)
    try:
        if settings.integrator == "progressive":
            output = render_progressive(engine, exported.scene, settings, writer, started,
                                        dask_address(depsgraph.scene.photon_map))
        else:
            on_progress, should_stop = progress_callbacks(engine)
            output = core_render(exported.scene, settings, on_progress=on_progress,
                                 on_tile=lambda done, passes: writer.update(passes),
                                 should_stop=should_stop)
            show_in_viewport(output.photon_maps, settings.overlay_map, exported.origin)
        # A cancelled render still delivers what it has, like Cycles.
        writer.finish(output.passes)
    except BaseException:
        writer.abort()
        raise
    # Render-time warnings (a heterogeneous medium's density clipped at its majorant, in
    # either pass): reported like the export's, not only in the log
    for warning in output.stats.get("medium_warnings", ()):
        engine.report({'WARNING'}, f"Photon Map: {warning}")
    elapsed = time.perf_counter() - started
    state = "Cancelled" if output.cancelled else "Done"
    if settings.integrator == "progressive":
        summary = progressive_report(output.stats, elapsed, settings.time_budget)
        log = [summary]
        engine.report({'INFO'}, f"Photon Map: {summary}")
    else:
        summary = photon_summary(output.stats)
        log = photon_log(output.stats)
        if settings.time_budget > 0:
            log.append(f"time budget {settings.time_budget:g} s not used: the Photon Map "
                       f"integrator's cost is set by its settings (Quality); the "
                       f"Progressive integrator fits a time budget")
    engine.update_stats("", f"Photon Map | {state} in {elapsed:.2f} s | {summary}")
    print(f"Photon Map: {state.lower()} in {elapsed:.2f} s; {summary}")
    for line in log:
        print(f"Photon Map: {line}")
    if not output.cancelled:
        engine.update_progress(1.0)


def render_progressive(engine, scene, settings, writer, started, address=""):
    """Progressive (SPPM) render of the exported ``scene``: each pass updates the image
    (``writer``), the status shows "Pass k of n" and Esc stops after the pass running.

    Without a time budget it runs ``settings.progressive_passes``. With one, the budget
    counts from ``started`` (export included): SPPM gets what is left and runs passes
    while the next one fits (judged by the mean pass time; at least one pass); the count
    it reached is what the engine chose (``progressive_report``). Returns the RenderOutput.
    """
    from ..core import render as core_render
    from ..core.settings import MAX_PROGRESSIVE_PASSES

    budget = float(settings.time_budget)
    if budget > 0:
        passes = MAX_PROGRESSIVE_PASSES
        remaining = max(budget - (time.perf_counter() - started), 1e-3)
    else:
        passes, remaining = settings.progressive_passes, None
    seen = {"pass": 0, "shown": -float("inf")}

    def on_pass(k, image):
        seen["pass"] = k
        now = time.perf_counter()
        if now - seen["shown"] >= PASS_UPDATE_SECONDS and k < passes:
            writer.update(image)
            seen["shown"] = time.perf_counter()

    def on_progress(fraction, _message):
        k = seen["pass"]
        if budget > 0:
            elapsed = time.perf_counter() - started
            fraction = min(elapsed / budget, 1.0)
            # The passes that fit at the mean pass time so far: honest, and it settles.
            fits = max(k, int(k * budget / max(elapsed, 1e-9)))
            text = f"Pass {k} of ~{fits} (time budget {budget:g} s)"
        else:
            text = f"Pass {k} of {passes}"
        engine.update_progress(fraction)
        engine.update_stats("", f"Photon Map | Progressive: {text}")
        if HEADLESS.on_progress is not None:
            HEADLESS.on_progress(fraction, text)

    engine.update_stats("", "Photon Map | Progressive: pass 1 (visible points, photons)")
    run = settings.with_values(progressive_passes=passes, time_budget=remaining or 0.0)
    if address:
        # One frame on a Dask cluster (core/integrators/distributed.py, docs/farm.md).
        from ..core.integrators import distributed
        engine.update_stats("", f"Photon Map | Progressive: connecting to {address}")
        try:
            with distributed.connect(address) as cluster:
                return distributed.render(scene, run, cluster.client, on_progress=on_progress,
                                          on_tile=on_pass,
                                          should_stop=progress_callbacks(engine)[1],
                                          address=address)
        except distributed.DistributedError as error:
            from ..core.settings import SettingsError
            raise SettingsError(str(error)) from None
    return core_render(scene, run, on_progress=on_progress, on_tile=on_pass,
                       should_stop=progress_callbacks(engine)[1])


def dask_address(props) -> str:
    """The Performance panel's Dask scheduler (empty: this machine)."""
    return str(getattr(props, "dask_scheduler", "") or "").strip()


def progressive_report(stats, elapsed, budget) -> str:
    """What a progressive render chose and reached, for the status bar and the log:
    "Progressive: 37 passes in 30.0 s (budget 30 s), radius 0.05 m -> 0.012 m (mean),
    100,000 photons per pass". stats: ``core.integrators.sppm.render``'s."""
    limit = f"budget {budget:g} s" if budget > 0 else "no time budget"
    why = {"cancelled": ", stopped by Esc"}.get(stats.get("stopped_by"), "")
    count = f"{stats['passes']} pass{'' if stats['passes'] == 1 else 'es'}"
    return (f"Progressive: {count} in {elapsed:.1f} s ({limit}{why}), "
            f"radius {stats['initial_radius']:.3g} m -> {stats['radius_mean']:.3g} m (mean), "
            f"{stats['photons_per_pass']:,} photons per pass")


def show_in_viewport(maps, which, origin=None):
    """Hand the render's photons (``RenderOutput.photon_maps``, None = no map) of the map(s)
    ``which`` to the viewport display; nothing in background mode, which draws nothing.
    origin: (3,) world position of the render frame (ExportResult.origin), added back."""
    import bpy

    if bpy.app.background:
        return
    from ..core.integrators import debug_overlay
    from . import overlay

    positions, flux = debug_overlay.select_photons(
        maps.global_map if maps else None, maps.caustic_map if maps else None, which)
    if origin is not None:
        positions = positions + np.asarray(origin, np.float64)
    overlay.set_photons(positions, debug_overlay.display_colors(flux))


def photon_summary(stats) -> str:
    """One line for the stats bar: the maps built with their photon counts, or why not.

    stats: ``RenderOutput.stats`` (core/integrators/photon_mapping.py).
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
        # The tracer already logged most reasons ("caustic map: skipped, <why>"): once is enough.
        if not any(why in line for line in lines):
            lines.append(f"{term} not rendered: {why}")
    for key, label in (("caustic", "caustic"), ("global", "global")):
        if stats.get(f"{key}_photons_stored"):
            lines.append(f"{label} map: {stats[f'{key}_photons_stored']:,} photons stored, "
                         f"gather radius {stats.get(f'{key}_radius', 0.0):.4g} m")
    samples, mean = stats.get("samples"), stats.get("samples_mean")
    if samples and mean is not None and mean < samples:  # adaptive sampling stopped early
        lines.append(f"adaptive sampling: {mean:.1f} samples per pixel on average "
                     f"(at most {samples})")
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


class HeadlessControl:
    """What a headless caller (the CLI, photon_engine/cli.py) adds to a render's progress:
    ``cancel``, set from a signal handler (it only sets the flag: raising inside
    ``bpy.ops.render.render`` crashes Blender), makes ``should_stop`` answer "stop", as
    Esc does, so the core stops between batches; ``on_progress(fraction, message)``, when
    set, sees every progress call (the CLI prints the stages)."""

    def __init__(self):
        self.cancel = threading.Event()
        self.on_progress = None


HEADLESS = HeadlessControl()


def progress_callbacks(engine):
    """The core's ``on_progress(fraction, message)`` and ``should_stop()`` wired to Blender:
    the progress bar and status line, and Esc (``test_break``) or a headless cancel
    (``HEADLESS``)."""

    def on_progress(fraction, message):
        engine.update_progress(fraction)
        engine.update_stats("", f"Photon Map | {message}")
        if HEADLESS.on_progress is not None:
            HEADLESS.on_progress(fraction, message)

    def should_stop():
        return HEADLESS.cancel.is_set() or bool(engine.test_break())

    return on_progress, should_stop


class ResultWriter:
    """One render's Render Result for ``layer_name``: begun once (at the first image),
    updated with partial images (``update`` -> ``engine.update_result``), ended once with
    the final passes (``finish``) or discarded after an error (``abort``).

    passes: name -> (H, W, 3) float32 radiance, row 0 at the TOP (core convention);
    "photons" (H, W, 4) RGBA goes to the Photons pass when that is registered; a pass
    missing from ``passes`` (switched off, or not rendered yet) is left as it is.
    Blender's ``RenderPass.rect`` is (H*W, channels) with row 0 at the BOTTOM.
    """

    def __init__(self, engine, layer_name):
        self.engine, self.layer_name, self.result = engine, layer_name, None

    def update(self, passes):
        """Show partial images (the unrendered pixels are 0)."""
        self._write(passes)
        self.engine.update_result(self.result)

    def finish(self, passes):
        """Write the final images and hand the result to Blender."""
        self._write(passes)
        result, self.result = self.result, None
        self.engine.end_result(result)

    def abort(self):
        if self.result is not None:
            result, self.result = self.result, None
            self.engine.end_result(result, cancel=True)

    def _write(self, passes):
        combined = passes["combined"]
        height, width = combined.shape[:2]
        if self.result is None:
            self.result = self.engine.begin_result(0, 0, width, height, layer=self.layer_name)
        layer = self.result.layers[0]
        alpha = np.ones((height, width, 1), np.float32)
        _set_rect(layer.passes["Combined"], np.concatenate([combined, alpha], axis=2))
        for core_name, blender_name in (*EXTRA_PASSES.items(), DEBUG_PASS,
                                        *((c, b) for c, b, _ in DENOISING_PASSES)):
            if core_name in passes:
                render_pass = layer.passes.get(blender_name)
                if render_pass is not None:
                    _set_rect(render_pass, passes[core_name])


def _set_rect(render_pass, image):
    """Copy an (H, W, C) top-first image into ``render_pass.rect`` ((H*W, C), bottom row
    first). ``rect.foreach_set`` copies the buffer in one go: measured with bpy 5.0.1 on a
    640 x 480 RGBA pass, 0.8 ms against 0.5 s for ``rect = array`` (element by element)."""
    rect = np.ascontiguousarray(image[::-1], dtype=np.float32).reshape(-1, image.shape[2])
    target = render_pass.rect
    try:
        target.foreach_set(rect.ravel())
    except (AttributeError, TypeError):
        # Blender 3.4's foreach_set takes only the first dimension of a 2D array (it
        # raises "expected sequence size H*W"); older ones have none: copy element-wise.
        render_pass.rect = rect

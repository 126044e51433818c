"""The core's entry points: ``render`` (one render of a ``core.Scene``, whatever the
integrator), ``render_to_exr`` (the same, written as a multilayer EXR) and
``progressive`` (the progressive integrator's passes one at a time, for a caller that
interleaves them with its own work: the 3D viewport refines between Blender's draws on
Blender's main thread, so it needs an iterator it can resume, not a call that returns
when the render is over)."""

from __future__ import annotations

from typing import Iterator

from . import memory
from .integrators import photon_mapping, sppm
from .io.exr import write_exr
from .passes import ProgressFn, RenderOutput, StopFn, TileFn
from .scene.contract import Scene
from .settings import RenderSettings

INTEGRATORS = {"photon_map": photon_mapping.render, "progressive": sppm.render}
"""settings.integrator -> the integrator's render function (same signature as ``render``)."""


def render(scene: Scene, settings: RenderSettings | None = None,
           on_progress: ProgressFn | None = None, on_tile: TileFn | None = None,
           should_stop: StopFn | None = None) -> RenderOutput:
    """Render ``scene`` with ``settings.integrator``: "photon_map" (photon maps and final
    gathering, core/integrators/photon_mapping.py) or "progressive" (SPPM,
    core/integrators/sppm.py).

    on_progress(fraction in [0, 1], message) reports progress; on_tile(done, passes) shows
    the image filling in (pixels done for photon_map, passes done for progressive);
    should_stop() -> True ends the render between two batches, keeping what it has
    (``RenderOutput.cancelled``). Raises SceneError / SettingsError on bad input, and
    memory.MemoryLimitError (a SettingsError) before any work when the render would not
    fit in memory (core/memory.py).
    """
    settings = (settings or RenderSettings()).validated()
    memory.check(scene.validate(), settings)
    return INTEGRATORS[settings.integrator](scene, settings, on_progress=on_progress,
                                            on_tile=on_tile, should_stop=should_stop)


def render_to_exr(scene: Scene, settings: RenderSettings | None, path: str,
                  on_progress: ProgressFn | None = None, should_stop: StopFn | None = None,
                  view_layer: str = "ViewLayer") -> RenderOutput:
    """Render ``scene`` (``render``) and write every pass to a multilayer float32 EXR at
    ``path``. Returns the RenderOutput (the EXR holds what was rendered even when
    cancelled)."""
    out = render(scene, settings, on_progress=on_progress, should_stop=should_stop)
    meta = {"PhotonMap.samples": str(out.stats.get("samples", "")),
            "PhotonMap.render_time": f"{out.stats.get('time_total', 0.0):.3f}"}
    write_exr(path, out.passes, view_layer=view_layer, metadata=meta)
    return out


def progressive(scene: Scene, settings: RenderSettings | None = None,
                max_passes: int | None = None) -> Iterator[sppm.SPPMState]:
    """The progressive integrator's passes (``sppm.progressive_passes``): yields the live
    per-pixel state after each pass (``SPPMState.radiance()`` is the image), up to
    ``max_passes`` (default ``settings.progressive_passes``); closing the iterator releases
    the scene's accelerator. Raises memory.MemoryLimitError here, before any work, when
    the render would not fit in memory."""
    memory.check(scene.validate(), (settings or RenderSettings()).validated())
    return sppm.progressive_passes(scene, settings, max_passes)

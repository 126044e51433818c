"""Render a ``core.Scene`` built from arrays alone and write the passes as an EXR."""

from __future__ import annotations

from .exr import write_exr
from .integrator import ProgressFn, RenderOutput, render
from .scene import Scene
from .settings import RenderSettings


def render_to_exr(scene: Scene, settings: RenderSettings | None, path: str,
                  progress: ProgressFn | None = None, view_layer: str = "ViewLayer") -> RenderOutput:
    """Render ``scene`` and write every pass to a multilayer float32 EXR at ``path``.

    Returns the RenderOutput (the EXR holds what was rendered even when cancelled).
    """
    out = render(scene, settings, progress)
    meta = {"PhotonMap.samples": str(out.stats.get("samples", "")),
            "PhotonMap.render_time": f"{out.stats.get('time_total', 0.0):.3f}"}
    write_exr(path, out.passes, view_layer=view_layer, metadata=meta)
    return out

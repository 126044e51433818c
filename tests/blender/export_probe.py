"""One probe RenderEngine for the exporter tests: ``export()`` runs
``photon_engine.export.export_scene`` inside ``bpy.ops.render.render``, on the render
depsgraph, exactly where PhotonMapRenderEngine.render calls it, and hands back its
ExportResult (or re-raises what it raised)."""

import bpy

from tests.conftest import load_extension_package

photon_map = load_extension_package()
from photon_map.photon_engine.export import export_scene  # noqa: E402


class ExportProbe(bpy.types.RenderEngine):
    """Runs the exporter on the render depsgraph; ``origin`` is export_scene's (None: the
    camera's render origin)."""

    bl_idname = "PHOTON_MAP_EXPORT_PROBE"
    bl_label = "Photon Map export probe"
    outcome = None
    origin = None

    def render(self, depsgraph):
        try:
            type(self).outcome = export_scene(depsgraph, origin=type(self).origin)
        except Exception as exc:  # handed back to the test, which re-raises it
            type(self).outcome = exc


def export(scene=None, origin=None):
    """Export ``scene`` (default: the context's) through a real render depsgraph, with
    ``origin`` (3,) world metres or None; returns the ExportResult. The scene's render engine
    is restored afterwards."""
    if not ExportProbe.is_registered:
        bpy.utils.register_class(ExportProbe)
    scene = scene or bpy.context.scene
    engine = scene.render.engine
    scene.render.engine = ExportProbe.bl_idname
    ExportProbe.outcome, ExportProbe.origin = None, origin
    try:
        bpy.ops.render.render()
    finally:
        scene.render.engine = engine
    outcome = ExportProbe.outcome
    if isinstance(outcome, Exception):
        raise outcome
    assert outcome is not None, "the probe engine did not run"
    return outcome

"""Errors the exporter raises; the engine reports them instead of rendering.

ExportError is a core SceneError, so one ``except SceneError`` in the engine catches both
a scene Blender cannot export and one the core refuses.
"""

from ..core.scene.contract import SceneError


class ExportError(SceneError):
    """The Blender scene cannot be turned into a renderable core.Scene; the message says why."""


class NoCameraError(ExportError):
    """The scene has no (usable) active camera."""

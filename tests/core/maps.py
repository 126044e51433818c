"""The photon maps of a scene as a render traces them, for tests of the photon pass."""

from core.integrators.photon_terms import trace_maps
from core.prepared import prepare


def trace(scene, settings, on_progress=None, should_stop=None, **kw):
    """``photon_terms.trace_maps`` over ``prepare(scene)`` (importance pre-pass included);
    the prepared scene is released afterwards. Returns the tracer's PhotonMaps."""
    with prepare(scene.validate(), settings.threads) as prepared:
        return trace_maps(prepared, settings, on_progress, should_stop, **kw)

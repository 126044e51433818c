"""A render that would not fit in memory is refused through Blender before any work
(core/memory.py): the message goes to report(), Blender keeps its scene and can render
again once the limit allows it."""

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = [pytest.mark.blender, pytest.mark.api]


def test_a_tiny_limit_is_reported_and_blender_keeps_its_state(monkeypatch, capfd):
    scene = scenes.plane_and_point_light(width=32, height=24)
    scenes.use_photon_map(scene, samples=1, global_photons=1_000_000, caustic_photons=0,
                          final_gather_rays=4)
    objects = sorted(o.name for o in bpy.data.objects)
    monkeypatch.setenv("PHOTON_MAP_MEMORY_LIMIT", "20M")
    with pytest.raises(RuntimeError) as refused:
        bpy.ops.render.render()
    message = str(refused.value)
    assert message.startswith("Error: Photon Map: this render needs about "), message
    assert "more than the 20 MiB available (PHOTON_MAP_MEMORY_LIMIT: 20 MiB)" in message
    assert 'lower "Global Photons"' in message and "internal error" not in message
    assert "Traceback" not in capfd.readouterr().err
    # Nothing changed: the same objects and settings; the next render works.
    assert sorted(o.name for o in bpy.data.objects) == objects
    assert scene.photon_map.global_photons == 1_000_000
    monkeypatch.delenv("PHOTON_MAP_MEMORY_LIMIT")
    scene.photon_map.global_photons = 2000
    combined = scenes.render_passes()["Combined"]
    assert np.isfinite(combined).all() and combined[..., :3].max() > 0

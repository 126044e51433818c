"""Photon Map's caustics pass against Cycles: a glass sphere's caustic from an area light
(cycles_caustic_reference.py: the scene, how Cycles' caustic is isolated, the cached
reference and the command that re-renders it). Compared on the floor pixels the camera
sees directly (where Photon Map's specular pass is empty): the caustic's total energy
within 5 %.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_caustic_reference as cc  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = pytest.mark.blender


def test_caustic_energy_matches_cycles():
    cycles = cc.load_reference()
    scene = cc.glass_sphere_scene()
    scenes.use_photon_map(scene, samples=16, seed=1, caustic_photons=400_000,
                          indirect_mode='off')
    passes = scenes.render_passes(scene)
    caustic = passes["Caustics"][..., :3].astype(np.float64)
    assert np.all(np.isfinite(caustic)) and caustic.min() >= 0
    floor = np.all(passes["Specular"][..., :3] == 0, axis=2)  # not seen through the glass
    assert 0.5 < floor.mean() < 1.0
    pm = caustic[floor].sum()
    ref = cycles["caustic"].astype(np.float64)[floor].sum()
    noise = abs(cycles["caustic_a"][floor].sum() - cycles["caustic_b"][floor].sum()) / 2
    print(f"\ncaustic energy on the floor: Photon Map {pm:.2f}, Cycles {ref:.2f} "
          f"({100 * (pm / ref - 1):+.2f} %; Cycles' own noise {100 * noise / ref:.2f} %)")
    assert pm == pytest.approx(ref, rel=0.05)
    # The caustic is where Cycles puts it: most of Photon Map's lies in the pixels holding
    # 90 % of Cycles' caustic.
    order = np.sort(cycles["caustic"].sum(axis=2)[floor])[::-1]
    level = order[np.searchsorted(np.cumsum(order), 0.9 * order.sum())]
    focus = floor & (cycles["caustic"].sum(axis=2) >= level)
    share = caustic[focus].sum() / pm
    print(f"focus: {100 * focus.sum() / floor.sum():.1f} % of the floor pixels hold "
          f"{100 * share:.1f} % of Photon Map's caustic")
    assert focus.sum() < 0.3 * floor.sum() and share > 0.8

"""The World's volume emission lighting the scene, against Cycles in the same bpy process
(cached reference: tests/blender/cycles_world_emission_reference.py, the scene and the
command that re-renders it): a grey floor and a white cube in glowing, absorbing air (the
World's Principled Volume: sigma_a 0.6 per metre, emission (1, 0.6, 0.3) W/(m^3 sr)), no
light. Cycles' air is infinite; Photon Map's photons come from the scene's bounding sphere
(radius 7.1 m; core/photons/medium_emission.py). Compared: the Combined pass and the light
the surfaces reflect (Combined minus the Emission pass, which both renderers fill with the
air's own emission along camera rays: means equal to 1e-5, pixels at the cube's edges
differ by the pixel filters).
- final gathering (400k global photons): the gather rays collect the air's emission along
  their segments (to infinity, as Cycles), the photons the rest;
- preview (2M global photons): the floor and cube show the photons' first hits, the World
  source itself (20k stored per 400k: most are absorbed in the 1530 m^3 sphere)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import cycles_world_emission_reference as world  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = [pytest.mark.blender]

MODES = {"final_gather": dict(indirect_mode='final_gather', global_photons=400_000),
         "preview": dict(indirect_mode='preview', global_photons=2_000_000)}


@pytest.fixture(scope="module", params=sorted(MODES))
def rendered(request):
    scene = world.SCENES["glow_air"]()
    scenes.use_photon_map(scene, **dict(media.PHOTON_MAP_SETTINGS, **MODES[request.param]))
    return request.param, scenes.render_passes(scene)


def test_glowing_air_lights_the_floor_and_cube_as_in_cycles(rendered):
    mode, passes = rendered
    reference = world.load_reference("glow_air")
    f = media.figures(f"glow_air {mode}", passes, reference)
    np.testing.assert_allclose(passes["Emission"][..., :3].reshape(-1, 3).mean(0),
                               reference["emission"].reshape(-1, 3).mean(0), rtol=1e-3)
    ours = passes["Combined"][..., :3] - passes["Emission"][..., :3]
    g = ref.compare(ours, reference["image"] - reference["emission"])
    print(f"{mode} reflected: channel means {np.round(100 * g['channel'], 2)} %, worst block "
          f"{100 * g['worst_block']:.1f} %, median |block| "
          f"{100 * np.nanmedian(np.abs(g['blocks'])):.2f} %")
    assert np.all(np.abs(f["channel"]) < 0.02), f["channel"]
    if mode == "final_gather":
        assert np.all(np.abs(g["channel"]) < 0.03), g["channel"]
        assert g["worst_block"] < 0.10, g["blocks"]
    else:  # the photons' own estimate: blurred by its gather radius at the cube's edges
        assert np.all(np.abs(g["channel"]) < 0.05), g["channel"]

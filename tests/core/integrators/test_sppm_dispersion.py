"""The progressive mode's visible points through a dispersive prism (camera_paths.
visible_points: the closure sampler at each path's wavelength, docs/dispersion.md), as
tests/core/integrators/test_dispersion_camera.py checks the photon-mapping camera pass:
the white emitter seen through the prism keeps its colour summed over the image, and its
edges split into colour fringes."""

import numpy as np
import pytest

from core.integrators import sppm
from core.settings import RenderSettings
from tests.core.integrators.test_dispersion_camera import check_colour_fringes, check_keeps_colour
from tests.core.scenes import prism_view_scene

pytestmark = pytest.mark.core

PASSES = 768


@pytest.fixture(scope="module")
def images():
    s = RenderSettings().with_values(progressive_passes=PASSES, photons_per_pass=100,
                                     threads=2, seed=1)
    return {abbe: sppm.render(prism_view_scene(abbe), s).passes["combined"].astype(np.float64)
            for abbe in (0.0, 20.0)}


def test_emitter_through_the_prism_keeps_its_colour(images):
    """One wavelength per camera path, its RGB weight of mean (1, 1, 1)."""
    check_keeps_colour(images[0.0], images[20.0])


def test_emitter_edges_split_into_colour_fringes(images):
    check_colour_fringes(images[0.0], images[20.0])

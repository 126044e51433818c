"""The progressive mode's visible points through a dispersive prism (camera_paths.
visible_points: the closure sampler at each path's wavelength, docs/dispersion.md), as
tests/core/integrators/test_dispersion_camera.py checks the photon-mapping camera pass:
the white emitter seen through the prism keeps its colour summed over the image, and its
edges split into colour fringes."""

import numpy as np
import pytest

from core.integrators import sppm
from core.settings import RenderSettings
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
    """One wavelength per camera path, its RGB weight of mean (1, 1, 1): the V_d 20 image
    summed is the clear prism's within 1 % per channel; the clear prism's channels are
    exactly equal (no wavelength picked)."""
    clear, disp = images[0.0], images[20.0]
    assert np.all(np.isfinite(disp)) and np.all(disp >= 0)
    total0, total = clear.sum(axis=(0, 1)), disp.sum(axis=(0, 1))
    assert total0[0] == total0[1] == total0[2] > 0
    np.testing.assert_allclose(total, total0, rtol=0.01)


def test_emitter_edges_split_into_colour_fringes(images):
    clear, disp = images[0.0], images[20.0]
    lit0 = clear.sum(axis=2) > 0.05 * clear.sum(axis=2).max()
    assert np.array_equal(clear[lit0, 0], clear[lit0, 2])  # the clear prism: grey
    lit = disp.sum(axis=2) > 0.05 * disp.sum(axis=2).max()
    ratio = disp[lit, 0] / np.maximum(disp[lit, 2], 1e-12)
    assert np.mean(np.abs(ratio - 1.0) > 0.1) > 0.2  # many pixels far from grey
    # Blue bends more: the emitter's blue image lies above its red one (rows downwards).
    rows = np.arange(disp.shape[0])[:, None]
    main = slice(0, 30)  # the direct image (the rows below hold internal reflections)
    red, blue = disp[main, :, 0], disp[main, :, 2]
    row_red = (rows[main] * red).sum() / red.sum()
    row_blue = (rows[main] * blue).sum() / blue.sum()
    assert row_red - row_blue > 1.0

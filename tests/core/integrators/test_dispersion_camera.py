"""Camera paths through a dispersive prism (core/integrators/camera_paths.py's wavelength
pick, docs/dispersion.md): the emitter seen through it keeps its colour summed over the
image, its edges split into colour fringes, and Dispersion 0 is the renderer without the
setting, bit for bit."""

import numpy as np
import pytest

from core import render
from core.settings import RenderSettings
from tests.core.scenes import prism_view_scene


def _settings(**kw):
    base = dict(global_photons=1_000, caustic_photons=1_000, samples=1024, threads=2, seed=1)
    base.update(kw)
    return RenderSettings().with_values(**base)


@pytest.fixture(scope="module")
def images():
    s = _settings()
    return {abbe: render(prism_view_scene(abbe), s).passes["combined"].astype(np.float64)
            for abbe in (0.0, 20.0)}


def check_keeps_colour(clear, disp):
    """The V_d 20 image ``disp`` summed equals the clear prism's ``clear`` within 1 % per
    channel, and the clear prism's channels are exactly equal (no wavelength picked);
    (H, W, 3) float64 each. Shared with test_sppm_dispersion.py (the progressive mode)."""
    assert np.all(np.isfinite(disp)) and np.all(disp >= 0)
    total0, total = clear.sum(axis=(0, 1)), disp.sum(axis=(0, 1))
    assert total0[0] == total0[1] == total0[2] > 0  # no wavelength picked: RGB
    np.testing.assert_allclose(total, total0, rtol=0.01)


def check_colour_fringes(clear, disp):
    """The clear prism's image is grey; the dispersive one's lit pixels are far from grey
    (colour fringes), and its blue image lies above its red one."""
    lit0 = clear.sum(axis=2) > 0.05 * clear.sum(axis=2).max()
    assert np.array_equal(clear[lit0, 0], clear[lit0, 2])  # the clear prism: grey
    lit = disp.sum(axis=2) > 0.05 * disp.sum(axis=2).max()
    ratio = disp[lit, 0] / np.maximum(disp[lit, 2], 1e-12)
    assert np.mean(np.abs(ratio - 1.0) > 0.1) > 0.2  # many pixels far from grey
    # Blue bends more: seen through the prism, the emitter's blue image lies above its red
    # one (rows grow downwards), as the rainbow caustic puts blue nearer the prism.
    rows = np.arange(disp.shape[0])[:, None]
    main = slice(0, 30)  # the direct image (the rows below hold internal reflections)
    red, blue = disp[main, :, 0], disp[main, :, 2]
    row_red = (rows[main] * red).sum() / red.sum()
    row_blue = (rows[main] * blue).sum() / blue.sum()
    assert row_red - row_blue > 1.0


def test_emitter_through_the_prism_keeps_its_colour(images):
    # Each camera path picks one wavelength at the prism and carries its RGB weight
    # (mean (1, 1, 1)): measured 0.2-0.5 % per channel. The camera looks near minimum
    # deviation, where the image keeps its size at every wavelength, so the sum is the
    # emitter's radiance times the same solid angle.
    check_keeps_colour(images[0.0], images[20.0])


def test_emitter_edges_split_into_colour_fringes(images):
    check_colour_fringes(images[0.0], images[20.0])


def test_dispersion_zero_renders_bit_identical_to_no_setting():
    s = _settings(samples=16)
    a = render(prism_view_scene(None, 32, 24), s)
    b = render(prism_view_scene(0.0, 32, 24), s)
    assert a.passes.keys() == b.passes.keys()
    for k in a.passes:
        assert np.array_equal(a.passes[k], b.passes[k]), k
    assert a.passes["combined"].sum() > 0

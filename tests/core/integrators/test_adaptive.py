"""Adaptive sampling (core/integrators/adaptive.py): the per-pixel error estimate, the
minimum, and a render that spends its samples where the image is noisy."""

import numpy as np
import pytest

from core.integrators import adaptive
from core.integrators import photon_mapping as integrator
from core.settings import RenderSettings, SettingsError
from tests.core.scenes import caustic_scene

LIGHT = dict(global_photons=4000, caustic_photons=4000, final_gather_rays=16)


def test_relative_error_is_the_standard_error_over_the_value():
    """Per pixel: sqrt(mean_c var_c / n / (mean_c^2 + 0.01)) with the unbiased variance,
    accumulated over rounds of different sizes as over one."""
    rng = np.random.default_rng(4)
    values = rng.gamma(2.0, 0.3, size=(3, 24, 3))
    m = adaptive.Moments(3)
    m.add(np.arange(3), values[:, :8].reshape(-1, 3), 8)
    m.add(np.array([0, 2]), values[[0, 2], 8:].reshape(-1, 3), 16)
    for p, n in ((0, 24), (1, 8), (2, 24)):
        v = values[p, :n]
        expected = np.sqrt(np.mean(v.var(axis=0, ddof=1) / n / (v.mean(axis=0) ** 2 + 0.01)))
        assert adaptive.relative_error(m)[p] == pytest.approx(expected, rel=1e-12)
    assert np.array_equal(m.count, [24, 8, 24])


def test_relative_error_of_constant_and_single_samples():
    m = adaptive.Moments(2)
    m.add(np.array([0]), np.full((8, 3), 2.5), 8)
    m.add(np.array([1]), np.ones((1, 3)), 1)
    err = adaptive.relative_error(m)
    assert err[0] == 0.0          # no variance: converged
    assert err[1] == np.inf       # one sample says nothing about its noise


def test_min_samples():
    assert adaptive.min_samples(RenderSettings(samples=64, adaptive_threshold=0.0)) == 64
    on = RenderSettings(samples=64, adaptive_threshold=0.05)
    assert adaptive.min_samples(on) == 16
    assert adaptive.min_samples(on.with_values(samples=8)) == 4
    assert adaptive.min_samples(on.with_values(samples=2)) == 2
    assert adaptive.min_samples(on.with_values(adaptive_min_samples=40)) == 40
    assert adaptive.min_samples(on.with_values(adaptive_min_samples=100)) == 64


@pytest.mark.parametrize("value", [-0.1, 1.5, "0.1", True])
def test_a_bad_threshold_is_named(value):
    with pytest.raises(SettingsError, match="adaptive_threshold"):
        RenderSettings(adaptive_threshold=value).validated()


@pytest.fixture(scope="module")
def renders():
    scene = caustic_scene(width=24, height=24)
    base = RenderSettings(samples=16, seed=2, **LIGHT)
    return {thr: integrator.render(scene, base.with_values(adaptive_threshold=thr))
            for thr in (0.0, 1e-12, 0.02)}


def test_a_sample_is_the_same_in_whichever_round_it_is_taken(renders):
    """A threshold only a pixel of identical samples meets (the background, a few in full
    shadow) takes every sample in rounds of 4, 4, 8: the same samples (their random numbers
    are those of their index) as one round of 16, so the same pixels up to the order of
    the sums."""
    whole, rounds = renders[0.0], renders[1e-12]
    all16 = rounds.stats["samples_per_pixel"] == 16
    lit = whole.passes["combined"][..., :3].max(axis=2) > 0
    assert np.mean(all16[lit]) > 0.95
    for name, image in whole.passes.items():
        np.testing.assert_allclose(rounds.passes[name][all16], image[all16], rtol=1e-5,
                                   atol=1e-7, err_msg=name)


def test_samples_go_where_the_image_is_noisy(renders):
    """Black background pixels (no variance) away from the lit ones in their row stop at
    the minimum;
    the glass sphere's pixels
    (a random Fresnel choice, the floor's caustic through it) take more samples than the
    floor's, and the image keeps its brightness."""
    whole, adaptive_out = renders[0.0], renders[0.02]
    taken = adaptive_out.stats["samples_per_pixel"]
    assert taken.min() >= 4 and taken.max() <= 16
    black = whole.passes["combined"][..., :3].max(axis=2) == 0
    glass = whole.passes["specular"][..., :3].max(axis=2) > 0
    floor = ~black & ~glass
    assert black.any() and glass.sum() > 20 and floor.sum() > 100
    lit_near = np.zeros_like(black)  # a lit pixel within NEIGHBOURS columns in the row
    r = adaptive.NEIGHBOURS
    padded = np.pad(~black, ((0, 0), (r, r)))
    for dx in range(-r, r + 1):
        lit_near |= padded[:, r + dx:r + dx + black.shape[1]]
    alone = black & ~lit_near
    assert alone.sum() > 20 and np.all(taken[alone] == 4)
    assert taken[glass].mean() > taken[floor].mean() + 2, (taken[glass].mean(),
                                                           taken[floor].mean())
    assert adaptive_out.stats["samples_mean"] < 16
    a = adaptive_out.passes["combined"][..., :3].astype(np.float64)
    b = whole.passes["combined"][..., :3].astype(np.float64)
    assert np.isfinite(a).all() and a.min() >= 0
    np.testing.assert_allclose(a.mean(axis=(0, 1)), b.mean(axis=(0, 1)), rtol=0.03)


def test_a_pixel_keeps_sampling_beside_a_noisy_neighbour():
    """Frame 10 x 3, a tile of rows 0-1: one noisy pixel at (x 5, row 0) keeps every
    pixel of its row within NEIGHBOURS columns of it sampling, and no other."""
    width = 10
    pixels = np.arange(20, dtype=np.int64)
    m = adaptive.Moments(20)
    quiet = np.full((20 * 4, 3), 0.5)
    quiet[5 * 4:5 * 4 + 4] = [[0.0] * 3, [2.0] * 3, [0.0] * 3, [2.0] * 3]
    m.add(np.arange(20), quiet, 4)
    got = adaptive.unconverged(m, pixels, width, 0.1)
    x, y = pixels % width, pixels // width
    near = (np.abs(x - 5) <= adaptive.NEIGHBOURS) & (y == 0)
    assert np.array_equal(got, near)
    # A pixel at the row's end does not wrap to the next row's start.
    m2 = adaptive.Moments(20)
    edge = np.full((20 * 4, 3), 0.5)
    edge[9 * 4:9 * 4 + 4] = [[0.0] * 3, [2.0] * 3, [0.0] * 3, [2.0] * 3]
    m2.add(np.arange(20), edge, 4)
    got = adaptive.unconverged(m2, pixels, width, 0.1)
    assert not got[10] and not got[19] and got[7] and got[8] and not got[6]


def test_a_wide_round_is_traced_in_batches_the_memory_estimate_allows(renders, monkeypatch):
    """An adaptive tile is whole rows, so a round can hold more samples than the memory
    estimate's SAMPLES_PER_TILE (TILE_GROWTH x TARGET_SAMPLES_PER_TILE): it is traced in
    batches of at most that many, with the same image (a sample does not depend on its
    batch) and the same samples per pixel."""
    calls = []
    trace = integrator._trace_samples

    def counted(ctx, pix, lo, hi):
        calls.append(pix.shape[0] * (hi - lo))
        return trace(ctx, pix, lo, hi)

    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 5)  # batches of 20 samples
    monkeypatch.setattr(integrator, "_trace_samples", counted)
    scene = caustic_scene(width=24, height=24)
    settings = RenderSettings(samples=16, seed=2, adaptive_threshold=0.02, **LIGHT)
    out = integrator.render(scene, settings)
    assert max(calls) <= 20
    assert max(calls) > 4  # the cap, not one sample a call
    ref = renders[0.02]
    assert np.array_equal(out.stats["samples_per_pixel"], ref.stats["samples_per_pixel"])
    for name, image in ref.passes.items():
        assert np.array_equal(out.passes[name], image), name


def test_one_pixels_samples_above_a_batch_are_traced_in_sub_ranges(monkeypatch):
    """When one pixel's samples alone exceed the batch (TILE_GROWTH x
    TARGET_SAMPLES_PER_TILE), they are traced in sub-ranges whose means are weighted by
    their sizes: the image equals the one traced in one range (to rounding), adaptive or
    not."""
    scene = caustic_scene(width=6, height=5)
    for threshold in (0.0, 0.02):
        settings = RenderSettings(samples=16, seed=3, adaptive_threshold=threshold, **LIGHT)
        ref = integrator.render(scene, settings)
        calls = []
        trace = integrator._trace_samples

        def counted(ctx, pix, lo, hi):
            calls.append(pix.shape[0] * (hi - lo))
            return trace(ctx, pix, lo, hi)

        with monkeypatch.context() as patch:
            patch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 1)  # batches of 4 samples
            patch.setattr(integrator, "_trace_samples", counted)
            out = integrator.render(scene, settings)
        assert max(calls) <= integrator.TILE_GROWTH
        assert np.array_equal(out.stats["samples_per_pixel"], ref.stats["samples_per_pixel"])
        for name, image in ref.passes.items():
            np.testing.assert_allclose(out.passes[name], image, rtol=1e-12, atol=1e-15,
                                       err_msg=name)

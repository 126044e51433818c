"""The per-cell majorant grid of heterogeneous media (core/media/density.py, docs/volumes.md
"Majorant grid"): the cells bound a sparse field, segments take the largest cell they
cross, tracking through them stays unbiased and skips the empty cells, and a density finer
than the grid is clipped and reported (in the render's stats, which Blender's report
shows)."""

import dataclasses

import numpy as np
import pytest

from core.integrators import photon_mapping, sppm
from core.media import regions
from core.media.density import GRID, DensityFields
from core.scene import shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, Camera, Lights, Materials, Mesh, Scene, World
from core.scene.media import Media
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.converters import MATH_OPS

pytestmark = pytest.mark.core

CENTRE, R, RHO0, SIGMA = np.array([0.3, 0.0, -0.1]), 0.3, 20.0, 2.0


def _ball(points, field=None):
    """rho = 20 (1 - |p - c|^2 / R^2) in a 0.3 m ball, 0 elsewhere (1.4 % of the box)."""
    q = np.asarray(points, np.float64) - CENTRE
    return RHO0 * np.maximum(0.0, 1.0 - (q * q).sum(axis=1) / R ** 2)


def _depth(x, z):
    """Exact optical depth along y through the ball at (x, z)."""
    r2 = (x - CENTRE[0]) ** 2 + (z - CENTRE[2]) ** 2
    return SIGMA * RHO0 * 4.0 / 3.0 * np.maximum(R ** 2 - r2, 0.0) ** 1.5 / R ** 2


def _medium():
    box = shapes.box([-1.0] * 3, [1.0] * 3)
    media = Media.from_list([{"bounds": 0, "name": "Puff", "boundary": box.corners,
                              "sigma_a": np.full(3, SIGMA), "density_texture": 0}])
    fields = DensityFields({0: _ball}, {0: (np.full(3, -1.0), np.full(3, 1.0))}, ("Puff",))
    return regions.Medium(media, 2.0, 1, fields, seed=1)


def test_the_cells_bound_the_field_and_segments_take_the_cells_they_cross():
    med = _medium()
    f = med.fields
    g = f.grids[0]
    assert g.cells.shape == (GRID,) * 3
    # Empty far from the ball, the ball's peak bounded (SAFETY x at least its sampled max)
    assert g.at(np.array([[-0.9, -0.9, 0.9]]))[0] == 0.0
    assert f.majorant[0] >= RHO0
    # 2000 random segments in the box: rho <= the segment's majorant at 400 points on each
    rng = np.random.default_rng(7)
    o = rng.uniform(-1, 1, (2000, 3))
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t1 = rng.uniform(0.05, 1.0, 2000)
    inside = np.all(np.abs(o + t1[:, None] * d) <= 1.0, axis=1)
    o, d, t1 = o[inside], d[inside], t1[inside]
    maj = f.segment_majorant(np.zeros(len(o), np.int64), o, d, 0.0, t1)
    s = np.linspace(0, 1, 400)
    p = o[:, None, :] + (s[None, :, None] * t1[:, None, None]) * d[:, None, :]
    rho = _ball(p.reshape(-1, 3)).reshape(len(o), 400)
    assert np.all(rho.max(axis=1) <= maj + 1e-12)
    # ... and is not the box's bound where a segment stays in empty cells
    assert np.mean(maj == 0.0) > 0.3 and maj.max() == pytest.approx(f.majorant[0])
    med.close()


def test_tracking_through_the_grid_is_unbiased_and_skips_the_empty_cells():
    """Rays along y through the ball: the mean of 20k ratio-tracking walks per ray =
    exp(-exact optical depth) within 4 standard errors; rays through empty cells get
    majorant 0 and transmittance 1 exactly; nothing is clipped."""
    med = _medium()
    n = 20_000
    for x, z in ((0.3, -0.1), (0.45, 0.05), (0.1, -0.2)):
        o = np.tile([x, -3.0, z], (n, 1))
        d = np.tile([0.0, 1.0, 0.0], (n, 1))
        T = med.transmittance(o, d, np.full(n, 10.0))[:, 0]
        exact = np.exp(-_depth(x, z))
        assert abs(T.mean() - exact) < 4 * T.std() / np.sqrt(n) + 1e-9, (x, z, T.mean(), exact)
    o = np.array([[-0.8, -3.0, 0.8], [0.9, -3.0, -0.9]])
    st = med.stretches(o, np.tile([0.0, 1.0, 0.0], (2, 1)), np.full(2, 10.0))
    het = st.field >= 0
    assert np.all(st.majorant[het] == 0.0) and np.all(st.through == 1.0)
    assert not med.fields.warnings()
    med.close()


def _fine_sine_program():
    """rho = 0.5 + sin(48 pi Generated.x): a period of exactly one grid cell, so the grid's
    corners and centres all read 0.5 and the majorant (0.75) misses the peaks (1.5)."""
    ins = np.full((5, pg.INSTRUCTION_WIDTH), -1, np.int32)
    ins[:, 1:pg.FIRST_OPERAND] = 0
    f = pg.FIRST_OPERAND
    ins[0, 0], ins[0, 1], ins[0, f] = pg.OP_INPUT, pg.SOURCE_GENERATED, 2     # regs 2-4
    ins[1, 0], ins[1, f:f + 4] = pg.OP_SEPARATE, (2, 5, 6, 7)                 # x, y, z
    ins[2, 0], ins[2, 1], ins[2, f:f + 4] = pg.OP_MATH, MATH_OPS["MULTIPLY"], (5, 0, 0, 8)
    ins[3, 0], ins[3, 1], ins[3, f:f + 4] = pg.OP_MATH, MATH_OPS["SINE"], (8, 8, 8, 9)
    ins[4, 0], ins[4, 1], ins[4, f:f + 4] = pg.OP_MATH, MATH_OPS["ADD"], (9, 1, 1, 10)
    return pg.ShaderProgram.build(ins, [48 * np.pi, 0.5], [[10, pg.TARGET_DENSITY, 0, 0]], 11,
                                  name="fine sine")


def _ripples_scene(wall: bool = False):
    """The fine sine in a 2 m box seen along +y; with ``wall`` a grey wall behind it (the
    progressive integrator traces the media on its camera paths to surfaces only)."""
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    media = Media.from_list([{"bounds": 0, "name": "Ripples",
                              "boundary": shapes.box(lo, hi).corners,
                              "sigma_a": (0.5, 0.5, 0.5), "density_texture": 0}],
                            programs=(_fine_sine_program(),))
    cam = Camera(to_world=shapes.look_at([0, -5, 0], [0, 0, 0], (0, 0, 1)), width=8,
                 height=8, film_size=np.array([1.6, 1.6]), kind=CAMERA_ORTHOGRAPHIC)
    objects = 2 if wall else 1
    base = Mesh.empty()
    if wall:  # object 1 (the box, object 0, is the medium's boundary only)
        base = shapes.assemble([(shapes.quad([0, 2, 0], [-3, 0, 0], [0, 0, 3]), 1)])
        base = dataclasses.replace(base, object_index=np.ones_like(base.object_index))
    mesh = dataclasses.replace(base, object_names=("Box", "Wall")[:objects],
                               object_to_world=np.tile(np.eye(4), (objects, 1, 1)),
                               object_texspace=np.tile([[0.0, 0, 0], [1.0, 1, 1]],
                                                       (objects, 1, 1)))
    mats = Materials.from_list([{"diffuse": [0, 0, 0]}, {"diffuse": [0.5, 0.5, 0.5]}])
    scene = Scene(mesh, mats, Lights.empty(), cam,
                  world=World(radiance=np.full(3, 1.0, np.float32)), media=media).validate()
    return scene


def test_a_density_finer_than_the_grid_is_clipped_and_reported_in_the_render_stats():
    st = RenderSettings(samples=1, caustics=False, indirect_mode="preview",
                        global_photons=1000, threads=2, seed=1)
    out = photon_mapping.render(_ripples_scene(), st)
    warnings = out.stats["medium_warnings"]
    print(warnings)
    assert len(warnings) == 1 and "medium 'Ripples'" in warnings[0] and "clipped" in warnings[0]
    assert np.all(np.isfinite(out.passes["combined"]))


def test_the_progressive_render_reports_the_clipping_in_its_stats_too():
    """sppm.render gives stats["medium_warnings"] as photon_mapping.render does (Blender's
    report, photon_engine/render.py, reads it for both integrators)."""
    st = RenderSettings(integrator="progressive", progressive_passes=2, photons_per_pass=500,
                        threads=2, seed=1)
    out = sppm.render(_ripples_scene(wall=True), st)
    warnings = out.stats["medium_warnings"]
    assert len(warnings) == 1 and "medium 'Ripples'" in warnings[0] and "clipped" in warnings[0]
    assert np.all(np.isfinite(out.passes["combined"]))


def test_a_dask_render_reports_the_clipping_of_its_workers():
    """The Dask path (core/integrators/distributed.py) merges the workers' clipping counts:
    its stats["medium_warnings"] (which Blender's report reads, as for a render on one
    machine) are the single-process render's, word for word, for three blocks each
    counted on its own (a pass's clipping depends on the pass only). One in-process
    worker: in-process workers would share one PassRenderer (``distributed._WORKER``);
    separate processes hold their own, as tests/core/integrators/test_distributed.py's."""
    pytest.importorskip("dask.distributed")
    from dask.distributed import Client

    from core.integrators import distributed
    st = RenderSettings(integrator="progressive", progressive_passes=6, photons_per_pass=300,
                        progressive_block=2, threads=1, seed=1)
    scene = _ripples_scene(wall=True)
    single = sppm.render(scene, st)
    with Client(processes=False, n_workers=1, threads_per_worker=1,
                dashboard_address=None) as client:
        out = distributed.render(scene, st, client)
    assert out.stats["tasks"] == 3 and out.stats["passes"] == 6
    np.testing.assert_array_equal(out.passes["combined"], single.passes["combined"])
    warnings = single.stats["medium_warnings"]
    assert len(warnings) == 1 and "medium 'Ripples'" in warnings[0]
    assert out.stats["medium_warnings"] == warnings

"""Per-hit closure weights (TARGET_WEIGHT, a linked Mix Shader factor): a program weight
of a known per-hit value gives the analytic mixture; a constant weight row costs nothing;
a programmed normal keeps its mirror reflection above the true surface
(``normals.valid_specular_reflection``)."""

from dataclasses import replace

import numpy as np

from core.integrators import photon_mapping, sppm
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_SUN, Camera, Lights, Materials, \
    Scene
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.converters import MATH_OPS
from core.shading.normals import valid_specular_reflection

W = pg.INSTRUCTION_WIDTH
RES = 8
E = 3.0  # W/m^2, the sun straight down


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def mix_program():
    """Closure 0 weighted by 1 - U, closure 1 by U (U the first UV map, in register 1;
    register 0 the constant 1): what the exporter compiles for a Mix Shader whose Factor
    is the U coordinate."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [1]),
            ins(pg.OP_MATH, [MATH_OPS["SUBTRACT"], 0], [0, 1, 0, 4])]
    outputs = [[4, pg.TARGET_WEIGHT, 0, 0], [1, pg.TARGET_WEIGHT, 1, 0]]
    return pg.ShaderProgram.build(code, [1.0], outputs, 5, name="mix")


def floor_scene(program, a=0.8, b=0.2):
    """A 2 m Lambert floor (UV (0, 0) to (1, 1) over x, y in [-1, 1]) made of two diffuse
    closures of albedo a and b, seen from above under a sun straight down."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    corners = mesh.vertices[mesh.triangles]
    mesh = replace(mesh, uvs=((corners[..., :2] + 1.0) / 2.0).astype(np.float32))
    row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE, "params": {"color": a, "roughness": 0.0}},
                        {"kind": closures.CLOSURE_DIFFUSE, "params": {"color": b, "roughness": 0.0}}],
           "program": program, "diffuse": [a + b] * 3}
    m = shapes.look_at([0, 0, 1], [0, 0, 0])
    m[:3, 3] = 0.0
    sun = {"kind": LIGHT_SUN, "to_world": m, "power": E, "angle": 0.0}
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=RES,
                 height=RES, film_size=np.array([2.0, 2.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list([row]), Lights.from_list([sun]), cam)


SETTINGS = RenderSettings(samples=16, global_photons=2000, caustic_photons=500,
                          final_gather_rays=4, threads=2)


def expected(a=0.8, b=0.2):
    u = (np.arange(RES) + 0.5) / RES  # the pixel's mean U is its centre's (U linear)
    return np.broadcast_to((((1 - u) * a + u * b) * E / np.pi)[None, :, None], (RES, RES, 3))


def test_a_program_weight_gives_the_analytic_mixture_per_pixel():
    out = photon_mapping.render(floor_scene(mix_program()), SETTINGS).passes["direct"]
    # Without the weights: (a + b) E / pi = 0.95 everywhere, far outside the tolerance.
    np.testing.assert_allclose(out, expected(), rtol=0.03, atol=1e-3)


def test_sppm_visible_points_read_the_weights():
    st = SETTINGS.with_values(integrator="progressive", progressive_passes=2,
                              photons_per_pass=4000, samples=4)
    img = sppm.render(floor_scene(mix_program()), st).passes["combined"]
    # SPPM's direct light is in the image; no other surface, so it is all of it.
    np.testing.assert_allclose(img, expected(), rtol=0.05, atol=2e-3)


def test_the_weights_scale_only_the_rows_they_name():
    with prepare(floor_scene(mix_program())) as prepared:
        prim = np.zeros(3, np.int32)
        u = np.array([0.1, 0.3, 0.5], np.float32)
        d = np.tile([0.0, 0.0, -1.0], (3, 1))
        tab, rows = prepared.hit_shader.closures_at(prim, u, u, d,
                                                    prepared.tri_material[prim])
        first = tab.first[rows]
        w0, w1 = tab.weight[first, 0], tab.weight[first + 1, 0]
        np.testing.assert_allclose(w0 + w1, 1.0, rtol=1e-6)
        assert np.all((w0 >= 0) & (w0 <= 1)) and len(np.unique(w0)) == 3
        # the material's own rows keep their constant weights
        np.testing.assert_array_equal(tab.weight[:2], prepared.closures.weight)


def test_valid_specular_reflection_lifts_the_mirror_direction_above_the_surface():
    rng = np.random.default_rng(3)
    n_pts = 2000
    ng = np.tile([0.0, 0.0, 1.0], (n_pts, 1))
    i = rng.normal(size=(n_pts, 3))
    i[:, 2] = np.abs(i[:, 2]) + 1e-3
    i /= np.linalg.norm(i, axis=1)[:, None]
    n = rng.normal(size=(n_pts, 3)) * [1.0, 1.0, 0.5]
    n[:, 2] = np.abs(n[:, 2]) + 0.05
    n /= np.linalg.norm(n, axis=1)[:, None]
    out = valid_specular_reflection(ng, i, n)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, rtol=1e-9)
    r = 2 * np.einsum("ij,ij->i", out, i)[:, None] * out - i
    threshold = np.minimum(0.9 * i[:, 2], 0.01)
    before = 2 * np.einsum("ij,ij->i", n, i) * n[:, 2] - i[:, 2]
    fixed = before < threshold
    assert 0.1 < fixed.mean() < 0.9  # the sample has both kinds
    np.testing.assert_array_equal(out[~fixed], n[~fixed])  # valid normals kept exactly
    # the fixed ones reflect exactly at the threshold (Cycles' closed form), no lower
    np.testing.assert_allclose(r[fixed, 2], threshold[fixed], atol=1e-6)

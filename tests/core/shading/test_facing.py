"""Fresnel, Layer Weight, the camera transform and the Box weights without Blender, against
their closed forms: normal-incidence reflectance ((eta - 1) / (eta + 1))^2, the s/p
Fresnel equations at oblique angles, Facing = 1 - |cos|^b, a projective transform by
numpy, Box weights that sum to 1."""

import math

import numpy as np

from core.shading import program as pg
from core.shading.facing import fresnel_dielectric_cos, fresnel_node, layer_weight
from core.shading.images import box_weights, map_to_sphere, map_to_tube
from core.shading.color import rgb_to_hsl, hsl_to_rgb, wavelength_xyz
from core.shading.inputs import ShadingInputs
from core.shading.interpreter import evaluate

W = pg.INSTRUCTION_WIDTH


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def fresnel_sp(cos_i, eta):
    """Unpolarised reflectance from Snell's law and the s / p amplitudes."""
    sin_t = math.sqrt(max(0.0, 1.0 - cos_i * cos_i)) / eta
    if sin_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def test_fresnel_matches_the_fresnel_equations():
    for eta in (1.1, 1.45, 2.4, 0.7):
        assert math.isclose(fresnel_dielectric_cos(1.0, eta), ((eta - 1) / (eta + 1)) ** 2,
                            rel_tol=1e-12)
        for c in (0.05, 0.3, 0.77, 0.99):
            assert math.isclose(fresnel_dielectric_cos(c, eta), fresnel_sp(c, eta),
                                rel_tol=1e-9, abs_tol=1e-12)
    # backface: the IOR inverted (total internal reflection at grazing angles)
    assert fresnel_node(1.5, 0.2, True) == 1.0
    assert math.isclose(fresnel_node(1.5, 0.9, True), fresnel_sp(0.9, 1 / 1.5), rel_tol=1e-9)


def test_layer_weight_facing_and_fresnel():
    for blend, b in ((0.3, 0.6), (0.5, 1.0), (0.8, 2.5)):
        for c in (0.1, 0.5, 0.9):
            fres, facing = layer_weight(blend, c, False)
            assert math.isclose(facing, 1.0 - c ** b, rel_tol=1e-12)
            assert math.isclose(fres, fresnel_sp(c, 1.0 / (1.0 - blend)), rel_tol=1e-9)


def test_transform_op_is_a_projective_matrix_product():
    rng = np.random.default_rng(2)
    m = rng.normal(size=(4, 4))
    m[3] = [0.1, -0.2, 0.3, 2.0]
    p = rng.uniform(-1, 1, (50, 3))
    consts = []
    for i in range(4):
        consts += list(m[i, :3]) + [m[i, 3]]
    # registers 0..15: the rows (xyz, w), 16-18 position, 19-21 result
    regs = [16] + [4 * i + k for i in range(4) for k in (0, 3)] + [19]
    for projective in (0, 1):
        prog = pg.ShaderProgram.build(
            [ins(pg.OP_INPUT, [pg.SOURCE_POSITION], [16]),
             ins(pg.OP_TRANSFORM, [projective], regs)],
            consts, [[19 + c, pg.TARGET_EMISSION, 0, c] for c in range(3)], 22)
        got = evaluate(prog, ShadingInputs.build(p, np.tile([0.0, 0.0, 1.0], (50, 1))))
        h = np.c_[p, np.ones(50)] @ m.T
        want = h[:, :3] / (h[:, 3:] if projective else 1.0)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_box_weights_sum_to_one_and_pick_the_dominant_side():
    rng = np.random.default_rng(4)
    for n in rng.normal(size=(200, 3)):
        for blend in (0.0, 0.3, 1.0):
            w = box_weights(n[0], n[1], n[2], blend)
            assert math.isclose(sum(w), 1.0, abs_tol=1e-9) and min(w) >= -1e-12
    assert box_weights(0.9, 0.1, 0.2, 0.3) == (1.0, 0.0, 0.0)
    assert box_weights(0.1, -0.1, -0.9, 0.3) == (0.0, 0.0, 1.0)


def test_sphere_and_tube_maps_and_hsl_round_trip():
    u, v = map_to_sphere(0.0, 1.0, 0.0)  # +y: u = 0.5, equator v = 0.5
    assert math.isclose(u, 0.5) and math.isclose(v, 0.5)
    assert math.isclose(map_to_sphere(0.0, 0.0, 2.0)[1], 1.0)
    u, v = map_to_tube(1.0, 0.0, 0.5)  # +x: u = 0.25, v = (z + 1) / 2
    assert math.isclose(u, 0.25) and math.isclose(v, 0.75)
    rng = np.random.default_rng(5)
    for rgb in rng.uniform(0, 1, (100, 3)):
        back = hsl_to_rgb(*rgb_to_hsl(*rgb))
        np.testing.assert_allclose(back, rgb, atol=1e-12)


def test_wavelength_table_is_interpolated_and_zero_outside():
    assert wavelength_xyz(300.0) == (0.0, 0.0, 0.0) and wavelength_xyz(780.0) == (0.0, 0.0, 0.0)
    x, y, z = wavelength_xyz(557.5)  # halfway between 555 (y 1.0) and 560 nm (y 0.995)
    assert math.isclose(y, 0.5 * (1.0 + 0.995), rel_tol=1e-6)

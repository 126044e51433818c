"""The shader program and its interpreter without Blender: every Math operation against
numpy's formulas, vector math identities, the program's validation, closure parameters
per point."""

import numpy as np
import pytest

from core.scene import closures
from core.shading import program as pg
from core.shading.inputs import ShadingInputs
from core.shading.interpreter import evaluate, closure_params
from core.shading.converters import MATH_OPS, VECTOR_MATH_OPS
from core.shading.noise import noise_texture, NOISE_FBM
from core.shading.voronoi import voronoi_texture, F1, EUCLIDEAN

W = pg.INSTRUCTION_WIDTH


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def uv_points(rng, n=400, scale=3.0):
    """Points whose UV (map 0) holds (a, b) in [-scale, scale]^2."""
    uv = rng.uniform(-scale, scale, (1, n, 2))
    p = rng.uniform(-1, 1, (n, 3))
    return ShadingInputs.build(p, np.tile([0.0, 0.0, 1.0], (n, 1)), uv=uv), uv[0]


def math_program(op, c=0.7, clamp=0):
    """regs 0: c; 1-3: UV (a, b, 0); 4: result."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [1]),
            ins(pg.OP_MATH, [MATH_OPS[op], clamp], [1, 2, 0, 4])]
    return pg.ShaderProgram.build(code, [c], [[4, pg.TARGET_EMISSION, 0, 0]], 5, name=op)


def _sm(a, b, k):
    hh = np.maximum(k - np.abs(a - b), 0) / k
    return np.minimum(a, b) - hh ** 3 * k / 6


NUMPY_MATH = {
    "ADD": lambda a, b, c: a + b, "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: np.where(b != 0, a / np.where(b != 0, b, 1), 0),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: np.where(a > 0, np.abs(a) ** b, 0.0),  # b is not integral
    "LOGARITHM": lambda a, b, c: np.where((a > 0) & (b > 0) & (b != 1),
                                          np.log(np.abs(a) + (a <= 0)) /
                                          np.log(np.where((b > 0) & (b != 1), b, 2.0)), 0),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0)),
    "INVERSE_SQRT": lambda a, b, c: np.where(a > 0, 1 / np.sqrt(np.abs(a) + (a <= 0)), 0),
    "ABSOLUTE": lambda a, b, c: np.abs(a), "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b), "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b) * 1.0, "GREATER_THAN": lambda a, b, c: (a > b) * 1.0,
    "SIGN": lambda a, b, c: np.sign(a),
    "COMPARE": lambda a, b, c: (np.abs(a - b) <= c) * 1.0,
    "SMOOTH_MIN": lambda a, b, c: _sm(a, b, c), "SMOOTH_MAX": lambda a, b, c: -_sm(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5), "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a), "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a), "MODULO": lambda a, b, c: np.fmod(a, b),
    "FLOORED_MODULO": lambda a, b, c: a - np.floor(a / b) * b,
    "WRAP": lambda a, b, c: a - (b - c) * np.floor((a - c) / (b - c)),
    "SNAP": lambda a, b, c: np.floor(a / b) * b,
    "PINGPONG": lambda a, b, c: np.abs(((a - b) / (2 * b) - np.floor((a - b) / (2 * b)))
                                       * 2 * b - b),
    "SINE": lambda a, b, c: np.sin(a), "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1, 1)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1, 1)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a), "ARCTAN2": lambda a, b, c: np.arctan2(a, b),
    "SINH": lambda a, b, c: np.sinh(a), "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a), "RADIANS": lambda a, b, c: np.radians(a),
    "DEGREES": lambda a, b, c: np.degrees(a),
}


def test_numpy_table_covers_every_math_operation():
    assert set(NUMPY_MATH) == set(MATH_OPS)


@pytest.mark.parametrize("op", sorted(MATH_OPS))
def test_math_operation_matches_numpy(op, rng):
    inputs, ab = uv_points(rng)
    a, b = ab[:, 0].astype(np.float32).astype(np.float64), \
        ab[:, 1].astype(np.float32).astype(np.float64)
    got = evaluate(math_program(op), inputs)[:, 0]
    want = NUMPY_MATH[op](a, b, 0.7)
    # discontinuous operations: skip points within float32 rounding of a jump
    safe = np.ones_like(a, bool)
    if op in ("FLOOR", "CEIL", "ROUND", "TRUNC", "FRACT", "MODULO", "FLOORED_MODULO",
              "WRAP", "SNAP", "PINGPONG", "LESS_THAN", "GREATER_THAN", "COMPARE"):
        for shift in (-1e-5, 1e-5):
            safe &= np.isclose(NUMPY_MATH[op](a + shift, b, 0.7), want, atol=1e-3)
    if op == "WRAP":  # a range b - c near 0 amplifies float32 rounding of the inputs
        safe &= np.abs(b - 0.7) > 0.1
    np.testing.assert_allclose(got[safe], want[safe], rtol=2e-5, atol=2e-5)
    assert safe.mean() > 0.9


def test_math_clamp_saturates():
    rng = np.random.default_rng(1)
    inputs, ab = uv_points(rng)
    got = evaluate(math_program("MULTIPLY", clamp=1), inputs)[:, 0]
    np.testing.assert_allclose(got, np.clip(ab[:, 0] * ab[:, 1], 0, 1), atol=1e-5)


def test_vector_math_cross_is_orthogonal_and_normalize_is_unit(rng):
    n = 100
    p = rng.normal(size=(n, 3))
    nrm = rng.normal(size=(n, 3))
    inputs = ShadingInputs.build(p, nrm)
    zero = [0.0] * 3
    code = [ins(pg.OP_INPUT, [pg.SOURCE_POSITION], [4]), ins(pg.OP_INPUT, [pg.SOURCE_NORMAL], [7]),
            ins(pg.OP_VECTOR_MATH, [VECTOR_MATH_OPS["CROSS_PRODUCT"]], [4, 7, 0, 3, 10, 13]),
            ins(pg.OP_VECTOR_MATH, [VECTOR_MATH_OPS["NORMALIZE"]], [10, 7, 0, 3, 14, 17]),
            ins(pg.OP_VECTOR_MATH, [VECTOR_MATH_OPS["DOT_PRODUCT"]], [10, 4, 0, 3, 18, 21])]
    outs = [[r, pg.TARGET_NORMAL, 0, i] for i, r in enumerate((14, 15, 16))] + \
        [[21, pg.TARGET_ALPHA, 0, 0]]
    prog = pg.ShaderProgram.build(code, zero + [1.0], outs, 22)
    out = evaluate(prog, inputs)
    c = np.cross(inputs.position.astype(np.float64), inputs.normal.astype(np.float64))
    np.testing.assert_allclose(out[:, :3], c / np.linalg.norm(c, axis=1, keepdims=True),
                               atol=1e-5)
    np.testing.assert_allclose(out[:, 3], 0.0, atol=1e-4)


def test_closure_params_write_the_slots_and_keep_the_constants(rng):
    inputs, ab = uv_points(rng, n=50)
    prog = pg.ShaderProgram.build(
        [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [1])], [0.0],
        [[1, pg.TARGET_CLOSURE, 1, closures.ROUGHNESS], [2, pg.TARGET_ALPHA, 0, 0]], 4)
    rows = np.stack([closures.params(), closures.params(metallic=1.0)])
    got = closure_params(prog, inputs, rows)
    np.testing.assert_allclose(got["params"][:, 1, closures.ROUGHNESS], ab[:, 0], rtol=1e-6)
    np.testing.assert_array_equal(got["params"][:, 0],
                                  np.broadcast_to(rows[0], (50, closures.PARAM_COUNT)))
    assert got["params"][0, 1, closures.METALLIC] == 1.0
    np.testing.assert_allclose(got["alpha"], ab[:, 1], rtol=1e-6)
    assert got["emission"] is None and got["normal"] is None


@pytest.mark.parametrize("code, outputs, n_regs, message", [
    ([ins(99, [], [])], [], 2, "unknown opcode 99"),
    ([ins(pg.OP_MATH, [0, 0], [0, 1, 3, 4])], [[4, 1, 0, 0]], 5, "reads register 3 before"),
    ([ins(pg.OP_MATH, [0, 0], [0, 1, 0, 1])], [], 5, "writes constant register 1"),
    ([ins(pg.OP_INPUT, [0], [3])], [[3, pg.TARGET_CLOSURE, 0, closures.PARAM_COUNT]], 6,
     f"slot {closures.PARAM_COUNT} outside"),
    ([ins(pg.OP_INPUT, [0], [3])], [[3, pg.TARGET_DENSITY, 0, 7]], 6, "slot 7 outside"),
    ([ins(pg.OP_INPUT, [0], [4])], [], 6, "register 4 outside [0, 3]"),
    ([ins(pg.OP_INPUT, [42], [3])], [], 6, "unknown input source 42"),
    ([ins(pg.OP_RAMP, [0, 256, 1], [0, 3, 6])], [], 7, "RAMP"),
    ([], [[5, 1, 0, 0]], 6, "never written"),
])
def test_invalid_programs_are_refused_with_the_operand_named(code, outputs, n_regs, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        pg.ShaderProgram.build(code, [0.5, 1.0], outputs, n_regs, name="bad")


def test_empty_batch_and_bad_inputs():
    prog = math_program("ADD")
    empty = ShadingInputs.build(np.zeros((0, 3)), np.zeros((0, 3)))
    assert evaluate(prog, empty).shape == (0, 1)
    with pytest.raises(ValueError, match="normal must be"):
        ShadingInputs.build(np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        ShadingInputs.build(np.full((1, 3), np.nan), np.zeros((1, 3)))


def far_points(rng, n=300):
    """Points in [-3, 3]^3, every 7th pushed beyond 1e5 (Cycles' precision guard)."""
    p = rng.uniform(-3, 3, (n, 3))
    p[::7] *= 4e4
    return ShadingInputs.build(p, np.tile([0.0, 0.0, 1.0], (n, 1)))


@pytest.mark.parametrize("scale, detail, roughness, lacunarity, distortion, normalize, colour", [
    (5.0, 2.0, 0.5, 2.0, 0.5, 1, 1), (2.0, 1.5, 0.7, 1.9, 0.0, 1, 1),
    (3.0, 0.0, 0.5, 2.0, 0.0, 0, 1), (1.5, 2.5, 0.4, -2.0, 1.2, 0, 0),
    (4.0, 3.0, 0.6, 2.2, 0.3, 1, 0)])
def test_noise_over_a_batch_is_noise_texture_at_each_point(rng, scale, detail, roughness,
                                                           lacunarity, distortion, normalize,
                                                           colour):
    """The interpreter runs a 3-D fBm Noise with constant settings over a batch
    (noise_texture3_rows, vectorised): bit for bit noise_texture at each point."""
    inputs = far_points(rng)
    consts = [0.3, scale, detail, roughness, lacunarity, 0.0, 1.0, distortion]
    code = [ins(pg.OP_INPUT, [pg.SOURCE_POSITION, 0], [8]),
            ins(pg.OP_NOISE, [3, NOISE_FBM, normalize, colour], [8, 0, 1, 2, 3, 4, 5, 6, 7,
                                                                 11, 12])]
    outs = [[11, pg.TARGET_ALPHA, 0, 0]] + [[12 + c, pg.TARGET_EMISSION, 0, c] for c in range(3)]
    got = evaluate(pg.ShaderProgram.build(code, consts, outs, 15, name="noise"), inputs)
    c = np.float32(consts).astype(np.float64)
    want = np.array([noise_texture(*p, 0.3, 3, c[1], c[2], c[3], c[4], 0.0, 1.0, c[7],
                                   NOISE_FBM, normalize != 0, colour != 0)
                     for p in inputs.position.astype(np.float64)], np.float32)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("scale, detail, roughness, lacunarity, randomness, normalize", [
    (8.0, 0.0, 0.5, 2.0, 1.0, 1), (3.0, 1.5, 0.6, 2.0, 0.4, 1), (2.5, 2.0, 0.5, 1.7, 0.8, 0),
    (-4.0, 1.0, 0.0, 2.0, 1.0, 1)])
def test_voronoi_over_a_batch_is_voronoi_texture_at_each_point(rng, scale, detail, roughness,
                                                               lacunarity, randomness,
                                                               normalize):
    """The interpreter runs a 3-D Euclidean F1 Voronoi with constant settings over a batch
    (voronoi_f1_3d_rows, cell by cell): bit for bit voronoi_texture at each point."""
    inputs = far_points(rng)
    consts = [0.3, scale, detail, roughness, lacunarity, 1.0, 1.0, randomness]
    code = [ins(pg.OP_INPUT, [pg.SOURCE_POSITION, 0], [8]),
            ins(pg.OP_VORONOI, [3, F1, EUCLIDEAN, normalize],
                [8, 0, 1, 2, 3, 4, 5, 6, 7, 11, 12, 15, 18])]
    outs = [[r, pg.TARGET_CLOSURE, 0, r - 11] for r in range(11, 19)]
    got = evaluate(pg.ShaderProgram.build(code, consts, outs, 19, name="voronoi"), inputs)
    c = np.float32(consts).astype(np.float64)
    want = np.array([voronoi_texture(*p, 0.3, 3, F1, EUCLIDEAN, normalize != 0, c[1], c[2],
                                     c[3], c[4], 1.0, 1.0, c[7], False)
                     for p in inputs.position.astype(np.float64)], np.float32)
    assert np.array_equal(got, want)

"""Emission from shader programs (core/prepared.py ``HitShader.emission_at``, the
textured emitters of core/lights/light_set.py): the pick weights are the program's mean
over each triangle, the radiance at a sampled point is the program's there, so the
emitted power is the integral, the photons leave only where the texture emits, a
constant program renders bit for bit like the constant emission, and a linear texture's
direct light matches a brute-force integral."""

import numpy as np

from core.integrators import photon_mapping
from core.photons import emission
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, Camera, Lights, Materials, Scene
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.converters import MATH_OPS

W = pg.INSTRUCTION_WIDTH
RES = 8
L0 = 5.0  # W/(m^2 sr) at U = 1


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def emission_program(kind):
    """Emission = L0 x (U, U/2, U/4) ("linear"), L0 x (U > 0.5) ("half", grey), or the
    constant L0 computed per point ("constant": U x 0 + L0)."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [3])]
    if kind == "linear":
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [3, 0, 0, 6]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [6, 1, 1, 7]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [7, 1, 1, 8]))
        consts = [L0, 0.5, 0.0]
    elif kind == "half":
        code.append(ins(pg.OP_MATH, [MATH_OPS["GREATER_THAN"], 0], [3, 1, 1, 9]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [9, 0, 0, 6]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [9, 0, 0, 7]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [9, 0, 0, 8]))
        consts = [L0, 0.5, 0.0]
    else:
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [3, 2, 0, 6]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [3, 2, 0, 7]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [3, 2, 0, 8]))
        consts = [L0, 0.5, 0.0]
    outputs = [[6 + c, pg.TARGET_EMISSION, 0, c] for c in range(3)]
    return pg.ShaderProgram.build(code, consts, outputs, 10, name=kind)


def emitter_scene(program, constant=None, height=0.5):
    """A 1 m emitter quad (UV U = x + 0.5 over x in [-0.5, 0.5]) facing down at
    ``height`` over a 4 m white Lambert floor seen from above (the camera sees the floor
    through the emitter: lights are two-sided, so a camera above sees the quad itself;
    the floor's pixels around it are its light)."""
    lamp = shapes.quad([0, 0, height], [0, 0.5, 0], [0.5, 0, 0])  # normal -Z
    floor = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mesh = shapes.assemble([(lamp, 0), (floor, 1)])
    uvs = np.array(mesh.uvs, copy=True)
    corners = mesh.vertices[mesh.triangles[mesh.material_index == 0]]
    uvs[mesh.material_index == 0] = np.stack([corners[..., 0] + 0.5, corners[..., 1] + 0.5],
                                             -1)
    from dataclasses import replace
    mesh = replace(mesh, uvs=uvs.astype(np.float32))
    lamp_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                              "params": {"color": 0.0, "roughness": 0.0}}],
                "emission": [L0] * 3 if constant is None else list(constant),
                "program": program}
    floor_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                               "params": {"color": 0.8, "roughness": 0.0}}],
                 "diffuse": [0.8] * 3}
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=RES,
                 height=RES, film_size=np.array([3.0, 3.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list([lamp_row, floor_row]), Lights.from_list([]), cam)


def test_pick_weights_are_the_mean_and_the_power_is_the_integral():
    with prepare(emitter_scene(emission_program("linear"))) as pr:
        e = pr.emissive
        assert e.count == 2 and e.textured.all()
        # U is linear: the midpoint rule over the sub-triangles is exact, so each
        # triangle's weight is L0 (mean U) x (1, 1/2, 1/4), mean U its centroid's.
        centroid_u = (e.v0 + (e.e1 + e.e2) / 3.0)[:, 0] + 0.5
        expected = L0 * centroid_u[:, None] * np.array([1.0, 0.5, 0.25])
        np.testing.assert_allclose(e.radiance, expected, rtol=1e-5)
        # Power = 2 pi integral of L dA = 2 pi L0 (1/2) (1, 1/2, 1/4) over 1 m^2.
        np.testing.assert_allclose(e.power, 2 * np.pi * L0 * 0.5 * np.array([1, 0.5, 0.25]),
                                   rtol=1e-5)
        # The photons carry it: their flux sums to the integral (stratified positions).
        n = 20000
        src = emission.Source(emission.SOURCE_TRIANGLES, e.power, "emissive triangles")
        em = emission.emit(src, pr.light_set, e, pr.world, pr.centre, pr.radius, n, 0, n,
                           seed=3, map_id=0, source_slot=0, extent=pr.extent,
                           emission_points=pr.hit_shader.emission_points)
        np.testing.assert_allclose(em.flux.sum(axis=0), e.power, rtol=0.01)


def test_photons_leave_only_where_the_texture_emits():
    with prepare(emitter_scene(emission_program("half"))) as pr:
        e = pr.emissive
        assert np.all(e.radiance > 0)  # every programmed triangle stays pickable
        n = 20000
        src = emission.Source(emission.SOURCE_TRIANGLES, e.power, "emissive triangles")
        em = emission.emit(src, pr.light_set, e, pr.world, pr.centre, pr.radius, n, 0, n,
                           seed=5, map_id=0, source_slot=0, extent=pr.extent,
                           emission_points=pr.hit_shader.emission_points)
        u = em.origin[:, 0] + 0.5
        lit = em.flux.sum(axis=1) > 0
        assert np.all(u[lit] > 0.5 - 1e-6) and np.all(~lit[u < 0.5 - 1e-6])
        np.testing.assert_allclose(em.flux.sum(axis=0), 2 * np.pi * L0 * 0.5, rtol=0.02)


def test_a_constant_program_renders_exactly_like_the_constant_emission():
    st = RenderSettings(samples=2, global_photons=4000, caustic_photons=0,
                        final_gather_rays=4, threads=2)
    plain = photon_mapping.render(emitter_scene(None, constant=(L0, L0, L0)), st).passes
    programmed = photon_mapping.render(emitter_scene(emission_program("constant"),
                                                     constant=(0.0, 0.0, 0.0)), st).passes
    assert plain["direct"].max() > 0 and plain["emission"].max() > 0
    for name, image in plain.items():
        np.testing.assert_array_equal(programmed[name], image, err_msg=name)


def test_direct_light_of_a_linear_texture_matches_the_integral():
    """The floor's direct radiance under the linear emitter: 0.8 / pi x the irradiance,
    a brute-force midpoint integral over the quad (200 x 200) averaged over each pixel
    (6 x 6), at every pixel the quad does not cover."""
    st = RenderSettings(samples=64, adaptive_threshold=0.0, light_samples=4, global_photons=0,
                        caustic_photons=0, final_gather_rays=1, threads=2)
    img = photon_mapping.render(emitter_scene(emission_program("linear")), st).passes["direct"]
    size = 3.0 / RES
    sub = (np.arange(6) + 0.5) / 6 - 0.5  # each pixel's mean over a 6 x 6 grid
    px = (np.arange(RES) + 0.5) * size - 1.5
    m = 200
    g = (np.arange(m) + 0.5) / m - 0.5
    QX, QY = np.meshgrid(g, g)
    Lq = L0 * (QX + 0.5)
    expected = np.zeros((RES, RES))
    for r in range(RES):
        for c in range(RES):
            for sy in sub:
                for sx in sub:
                    x, y = px[c] + sx * size, -(px[r] + sy * size)
                    dx, dy = QX - x, QY - y
                    r2 = dx * dx + dy * dy + 0.25
                    expected[r, c] += np.sum(Lq * 0.25 / r2 ** 2) / (m * m)
    expected *= 0.8 / np.pi / 36
    X, Y = np.meshgrid(px, -px)
    outside = (np.abs(X) - size / 2 >= 0.5) | (np.abs(Y) - size / 2 >= 0.5)  # floor only
    assert outside.sum() >= 40
    # Per pixel the light sampling is noisy (~5 % at 256 samples); the left (dim) and
    # right (bright) halves' sums are within 2 % (measured 0.2 %), and the x gradient of
    # the texture shows: the halves differ by a factor the integral predicts.
    for ch, k in enumerate((1.0, 0.5, 0.25)):
        for half in (X < 0, X > 0):
            sel = outside & half
            np.testing.assert_allclose(img[..., ch][sel].sum(), k * expected[sel].sum(),
                                       rtol=0.02)
        np.testing.assert_allclose(img[..., ch][outside], k * expected[outside], rtol=0.25)
    right, left = outside & (X > 0), outside & (X < 0)
    assert expected[right].sum() > 1.5 * expected[left].sum()

"""Shading normals from shader programs (core/shading/normals.py, ``HitShader.shade``):
the Normal Map node's frame and spaces against their analytic normals, and a Lambert
floor under a sun whose normal map tilts the shading normal renders E cos(theta') / pi."""

from dataclasses import replace

import numpy as np
import pytest

from core.integrators import photon_mapping, sppm
from core.photons import tracing
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_SUN, Camera, Lights, Materials, \
    Scene, SceneError
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.inputs import ShadingInputs
from core.shading.interpreter import evaluate
from core.shading.converters import MATH_OPS
from core.shading.normals import normal_map

W = pg.INSTRUCTION_WIDTH
RES = 8
E_SUN = 3.0
ALBEDO = 0.5


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def normal_map_program(colour, space="TANGENT", strength=1.0, invert_green=False):
    """The shading normal = Normal Map (space) of a constant colour, strength."""
    # registers: 0-2 colour, 3 strength, 4-6 tangent, 7-9 sign, 10-12 N, 13-15 backfacing,
    # 16-24 normal transform rows, 25-27 the normal
    code = [ins(pg.OP_INPUT, [pg.SOURCE_TANGENT, 0], [4]),
            ins(pg.OP_INPUT, [pg.SOURCE_TANGENT_SIGN, 0], [7]),
            ins(pg.OP_INPUT, [pg.SOURCE_NORMAL, 0], [10]),
            ins(pg.OP_INPUT, [pg.SOURCE_BACKFACING, 0], [13]),
            ins(pg.OP_INPUT, [pg.SOURCE_NORMAL_TO_WORLD, 0], [16]),
            ins(pg.OP_INPUT, [pg.SOURCE_NORMAL_TO_WORLD, 1], [19]),
            ins(pg.OP_INPUT, [pg.SOURCE_NORMAL_TO_WORLD, 2], [22]),
            ins(pg.OP_NORMAL_MAP, [pg.NORMAL_MAP_SPACES[space], int(invert_green)],
                [0, 3, 4, 7, 10, 13, 16, 19, 22, 25])]
    outputs = [[25 + c, pg.TARGET_NORMAL, 0, c] for c in range(3)]
    return pg.ShaderProgram.build(code, list(colour) + [strength], outputs, 28,
                                  name="normal map")


def tilt_colour(a):
    """The tangent-space colour of a normal tilted by a towards +T: (sin a, 0, cos a)."""
    return (0.5 + 0.5 * np.sin(a), 0.5, 0.5 + 0.5 * np.cos(a))


# --- the node --------------------------------------------------------------------------

def test_tangent_space_tilts_the_normal_towards_the_tangent_and_bitangent():
    a = np.radians(35.0)
    t = np.array([0.0, 1.0, 0.0])
    n = np.array([0.0, 0.0, 1.0])
    m = np.eye(3).ravel()
    # +T: (sin a) T + (cos a) N
    out = np.array(normal_map(0, 0, *tilt_colour(a), 1.0, *t, 1.0, *n, 0.0, *m))
    np.testing.assert_allclose(out, np.sin(a) * t + np.cos(a) * n, atol=1e-12)
    # green tilts along B = sign * N x T = (-1, 0, 0) for sign 1, (1, 0, 0) for sign -1
    c = (0.5, 0.5 + 0.5 * np.sin(a), 0.5 + 0.5 * np.cos(a))
    b = np.cross(n, t)
    for sign in (1.0, -1.0):
        out = np.array(normal_map(0, 0, *c, 1.0, *t, sign, *n, 0.0, *m))
        np.testing.assert_allclose(out, sign * np.sin(a) * b + np.cos(a) * n, atol=1e-12)
    # DirectX convention: green points along -B
    out = np.array(normal_map(0, 1, *c, 1.0, *t, 1.0, *n, 0.0, *m))
    np.testing.assert_allclose(out, -np.sin(a) * b + np.cos(a) * n, atol=1e-12)
    # strength 0: the tangent-plane part vanishes and z -> 1: the normal itself
    out = np.array(normal_map(0, 0, *tilt_colour(a), 0.0, *t, 1.0, *n, 0.0, *m))
    np.testing.assert_allclose(out, n, atol=1e-12)
    # a back face: the frame is built on the face's own normal, then flipped
    out = np.array(normal_map(0, 0, *tilt_colour(a), 1.0, *t, 1.0, *(-n), 1.0, *m))
    np.testing.assert_allclose(out, -(np.sin(a) * t + np.cos(a) * n), atol=1e-12)
    # no tangent (sign 0, a mesh without the UV map): the normal unchanged, as Cycles
    out = np.array(normal_map(0, 0, *tilt_colour(a), 1.0, 0.0, 0.0, 0.0, 0.0, *n, 0.0, *m))
    np.testing.assert_allclose(out, n)


def test_object_and_world_spaces():
    c = np.array([0.8, 0.3, 0.6])
    v = 2 * c - 1
    n = np.array([0.0, 0.0, 1.0])
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    scale = np.diag([1.0, 2.0, 0.5])
    a = rot @ scale
    m = np.linalg.inv(a).T
    world = np.array(normal_map(2, 0, *c, 1.0, 0, 0, 0, 0, *n, 0.0, *m.ravel()))
    np.testing.assert_allclose(world, v / np.linalg.norm(v), atol=1e-12)
    obj = np.array(normal_map(1, 0, *c, 1.0, 0, 0, 0, 0, *n, 0.0, *m.ravel()))
    np.testing.assert_allclose(obj, m @ v / np.linalg.norm(m @ v), atol=1e-12)
    vb = v * [1, -1, -1]  # Blender's object / world convention
    bw = np.array(normal_map(4, 0, *c, 1.0, 0, 0, 0, 0, *n, 0.0, *m.ravel()))
    np.testing.assert_allclose(bw, vb / np.linalg.norm(vb), atol=1e-12)
    bo = np.array(normal_map(3, 0, *c, 1.0, 0, 0, 0, 0, *n, 0.0, *m.ravel()))
    np.testing.assert_allclose(bo, m @ vb / np.linalg.norm(m @ vb), atol=1e-12)
    # strength 0.5 outside tangent space: the linear mix from N, normalised
    half = np.array(normal_map(2, 0, *c, 0.5, 0, 0, 0, 0, *n, 0.0, *m.ravel()))
    mix = n + 0.5 * (v / np.linalg.norm(v) - n)
    np.testing.assert_allclose(half, mix / np.linalg.norm(mix), atol=1e-12)


def test_the_interpreter_runs_the_node_on_the_points_tangents():
    a = np.radians(25.0)
    n = 5
    t = np.zeros((1, n, 4), np.float32)
    t[0, :, 0], t[0, :, 3] = 1.0, 1.0
    ins_ = ShadingInputs.build(np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), tangents=t)
    out = evaluate(normal_map_program(tilt_colour(a)), ins_)
    np.testing.assert_allclose(out, np.tile([np.sin(a), 0.0, np.cos(a)], (n, 1)), atol=1e-6)


# --- at the hits -----------------------------------------------------------------------

def sun(theta):
    """A sun of E_SUN W/m^2 whose light arrives from (sin theta, 0, cos theta)."""
    m = shapes.look_at([np.sin(theta), 0.0, np.cos(theta)], [0, 0, 0])
    m[:3, 3] = 0.0
    return {"kind": LIGHT_SUN, "to_world": m, "power": E_SUN, "angle": 0.0}


def floor_scene(program, tangent, theta, sign=1.0, to_world=None):
    """A 2 m Lambert floor of albedo ALBEDO seen from above (orthographic), with one
    tangent map of constant tangent and sign, under a sun at theta."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    tan = np.zeros((mesh.triangle_count, 3, 1, 4), np.float32)
    tan[..., :3] = tangent
    tan[..., 3] = sign
    mesh = replace(mesh, tangents=tan, tangent_maps=("",))
    if to_world is not None:
        mesh = replace(mesh, object_to_world=np.asarray(to_world, np.float64)[None])
    row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                         "params": {"color": ALBEDO, "roughness": 0.0}}],
           "program": program, "diffuse": [ALBEDO] * 3}
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=RES,
                 height=RES, film_size=np.array([2.0, 2.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list([row]), Lights.from_list([sun(theta)]), cam)


SETTINGS = RenderSettings(samples=4, global_photons=2000, caustic_photons=500,
                          final_gather_rays=4, threads=2)


@pytest.mark.parametrize("tangent_deg, expected", [
    (0.0, lambda a, th: np.cos(th - a)),             # tilted towards the sun
    (90.0, lambda a, th: np.cos(a) * np.cos(th)),    # tilted sideways: the tangent matters
    (180.0, lambda a, th: np.cos(th + a)),           # tilted away from it
])
def test_a_normal_mapped_lambert_floor_renders_e_cos_theta_prime_over_pi(tangent_deg, expected):
    a, theta = np.radians(30.0), np.radians(40.0)
    b = np.radians(tangent_deg)
    scene = floor_scene(normal_map_program(tilt_colour(a)), [np.cos(b), np.sin(b), 0.0],
                        theta)
    out = photon_mapping.render(scene, SETTINGS).passes["direct"]
    want = ALBEDO * E_SUN * expected(a, theta) / np.pi
    np.testing.assert_allclose(out, want, rtol=1e-4)


def test_a_world_space_normal_map_and_an_object_space_one_on_a_turned_object():
    theta = np.radians(40.0)
    n = np.array([0.3, 0.0, 0.9])
    n /= np.linalg.norm(n)
    colour = 0.5 + 0.5 * n
    light = np.array([np.sin(theta), 0.0, np.cos(theta)])
    out = photon_mapping.render(
        floor_scene(normal_map_program(colour, "WORLD"), [1, 0, 0], theta),
        SETTINGS).passes["direct"]
    np.testing.assert_allclose(out, ALBEDO * E_SUN * (n @ light) / np.pi, rtol=1e-4)
    # Object space on an object turned 90 degrees about z: (0.3, 0, 0.9) in object space
    # is (0, 0.3, 0.9) in the world, perpendicular to the sun's plane.
    rot = np.eye(4)
    rot[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]
    out = photon_mapping.render(
        floor_scene(normal_map_program(colour, "OBJECT"), [1, 0, 0], theta, to_world=rot),
        SETTINGS).passes["direct"]
    world = rot[:3, :3] @ n
    np.testing.assert_allclose(out, ALBEDO * E_SUN * (world @ light) / np.pi, rtol=1e-4)


def test_the_program_normal_reaches_the_photons_and_the_camera_hits():
    a, theta = np.radians(30.0), np.radians(40.0)
    scene = floor_scene(normal_map_program(tilt_colour(a)), [1.0, 0.0, 0.0], theta)
    with prepare(scene) as prepared:
        prim = np.zeros(4, np.int32)
        u = np.full(4, 0.2, np.float32)
        d = np.tile([0.0, 0.0, -1.0], (4, 1))
        ns = np.tile([0.0, 0.0, 1.0], (4, 1))
        _, _, bent = prepared.hit_shader.shade(prim, u, u, d, np.zeros(4, np.int32), ns)
        np.testing.assert_allclose(bent, np.tile([np.sin(a), 0, np.cos(a)], (4, 1)),
                                   atol=1e-6)
        # photons: the same normal, per photon (a miss keeps a zero row)
        prim2 = np.array([0, -1, 1], np.int32)
        _, _, normals = tracing.photon_closures(prepared, prim2, u[:3], u[:3], d[:3])
        np.testing.assert_allclose(normals[[0, 2]], [[np.sin(a), 0, np.cos(a)]] * 2,
                                   atol=1e-6)
        np.testing.assert_array_equal(normals[1], 0.0)


def coated_floor(program, theta, coat_weight=1.0):
    """floor_scene's floor as a coat-only Principled (black base, no specular; coat of
    roughness 0.3, unlinked Coat Normal), its Normal input the program's (None: none)."""
    row = {"closures": [{"kind": closures.CLOSURE_PRINCIPLED, "params": {
        "color": 0.0, "specular_level": 0.0, "coat_weight": coat_weight,
        "coat_roughness": 0.3}}], "program": program}
    return replace(floor_scene(program, [1.0, 0.0, 0.0], theta),
                   materials=Materials.from_list([row]))


def test_an_unlinked_coat_normal_is_the_unbent_normal_under_a_normal_mapped_normal():
    """Cycles links an unlinked Coat Normal to the geometry's normal (sd->N), which a
    Normal Map (or Bump) into the Principled's Normal input does not change: the coat of a
    normal-mapped Principled shades about the flat normal, the same as without the map
    (the coat about the shading normal, tilted 30 degrees towards the sun, as before the
    fix: 0.0623 against 0.00505, 12 times brighter)."""
    a, theta = np.radians(30.0), np.radians(40.0)
    program = normal_map_program(tilt_colour(a))
    flat = photon_mapping.render(coated_floor(None, theta), SETTINGS).passes["direct"]
    bent = photon_mapping.render(coated_floor(program, theta), SETTINGS).passes["direct"]
    assert flat.min() > 1e-3
    np.testing.assert_allclose(bent, flat, rtol=1e-4)
    # the slots: the coat's normal is the flat one; without a coat they stay unlinked (0)
    for coat_weight, want in ((1.0, [0.0, 0.0, 1.0]), (0.0, [0.0, 0.0, 0.0])):
        with prepare(coated_floor(program, theta, coat_weight)) as prepared:
            d = np.tile([0.0, 0.0, -1.0], (2, 1))
            tab, rows, _ = prepared.hit_shader.shade(
                np.zeros(2, np.int32), np.full(2, 0.2, np.float32),
                np.full(2, 0.2, np.float32), d, np.zeros(2, np.int32), -d)
            cn = tab.params[tab.first[rows], closures.COAT_NORMAL:closures.COAT_NORMAL + 3]
            np.testing.assert_allclose(cn, [want] * 2, atol=1e-6)


def test_bad_tangents_are_refused():
    scene = floor_scene(None, [1, 0, 0], 0.0, sign=0.5)
    with pytest.raises(SceneError, match="bitangent sign"):
        scene.validate()
    mesh = replace(scene.mesh, tangent_maps=("", "UV2"))
    with pytest.raises(SceneError, match="mesh.tangents"):
        replace(scene, mesh=mesh).validate()


# --- Bump ------------------------------------------------------------------------------

def bump_program(slope, distance, strength=1.0, invert=False, width=0.1):
    """The shading normal = Bump of the height h = slope * (world x), at the point and at
    the footprint's offsets (OP_INPUT's bump axis and filter width)."""
    fw = int(round(width / pg.BUMP_WIDTH_UNIT))
    # constants: 0 slope, 1 strength, 2 distance, 3 width; then registers
    code, reg = [], 4
    heights = []
    for axis in (0, 1, 2):
        code.append(ins(pg.OP_INPUT, [pg.SOURCE_POSITION, 0, axis, fw if axis else 0], [reg]))
        code.append(ins(pg.OP_SEPARATE, [0], [reg, reg + 3, reg + 4, reg + 5]))
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [reg + 3, 0, 0, reg + 6]))
        heights.append(reg + 6)
        reg += 7
    n, dx, dy, out = reg, reg + 3, reg + 6, reg + 9
    code += [ins(pg.OP_INPUT, [pg.SOURCE_NORMAL, 0], [n]),
             ins(pg.OP_INPUT, [pg.SOURCE_BUMP_DPDX, 0], [dx]),
             ins(pg.OP_INPUT, [pg.SOURCE_BUMP_DPDY, 0], [dy]),
             ins(pg.OP_BUMP, [int(invert)], [1, 2, 3, *heights, n, dx, dy, out])]
    outputs = [[out + c, pg.TARGET_NORMAL, 0, c] for c in range(3)]
    return pg.ShaderProgram.build(code, [slope, strength, distance, width], outputs, out + 3,
                                  name="bump")


def test_bump_of_a_linear_height_ramp_gives_the_analytic_tilted_normal():
    theta = np.radians(40.0)
    light = np.array([np.sin(theta), 0.0, np.cos(theta)])
    for slope, distance, invert in ((1.0, 0.5, False), (0.8, 0.5, True), (-2.0, 0.3, False)):
        scene = floor_scene(bump_program(slope, distance, invert=invert), [1, 0, 0], theta)
        out = photon_mapping.render(scene, SETTINGS).passes["direct"]
        g = -distance * slope if not invert else distance * slope
        n = np.array([g, 0.0, 1.0]) / np.hypot(g, 1.0)  # normalize(N - D grad h)
        np.testing.assert_allclose(out, ALBEDO * E_SUN * (n @ light) / np.pi, rtol=1e-4,
                                   err_msg=f"slope {slope}, distance {distance}")


def test_bump_strength_mixes_with_the_normal_and_the_node_matches_cycles_formula():
    from core.shading.normals import bump
    n = np.array([0.0, 0.0, 1.0])
    dx, dy = np.array([0.01, 0.0, 0.0]), np.array([0.0, 0.01, 0.0])
    w, grad = 0.1, np.array([0.7, -0.3])
    h_c = 0.2
    h_x, h_y = h_c + w * 0.01 * grad[0], h_c + w * 0.01 * grad[1]
    full = np.array([-0.5 * grad[0], -0.5 * grad[1], 1.0])
    full /= np.linalg.norm(full)
    got = np.array(bump(False, 1.0, 0.5, w, h_c, h_x, h_y, *n, *dx, *dy))
    np.testing.assert_allclose(got, full, atol=1e-12)
    half = 0.5 * full + 0.5 * n
    got = np.array(bump(False, 0.5, 0.5, w, h_c, h_x, h_y, *n, *dx, *dy))
    np.testing.assert_allclose(got, half / np.linalg.norm(half), atol=1e-12)
    # the footprint's size cancels: 1000 times larger offsets, the same normal
    got = np.array(bump(False, 1.0, 0.5, w, h_c, h_c + w * 10 * grad[0],
                        h_c + w * 10 * grad[1], *n, *(1000 * dx), *(1000 * dy)))
    np.testing.assert_allclose(got, full, atol=1e-12)


def test_a_bumped_floor_renders_the_same_at_every_scale():
    # The scene scaled by s (the height's distance too: a physical height field), the sun
    # unchanged: the same image. Noise-free here (direct light of a sun), so exactly.
    theta = np.radians(40.0)
    images = []
    for s in (1e-3, 1.0, 1e3):
        scene = floor_scene(bump_program(1.0 / s, 0.5 * s), [1, 0, 0], theta)
        mesh = replace(scene.mesh, vertices=(scene.mesh.vertices * s).astype(np.float32))
        cam = replace(scene.camera, to_world=scene.camera.to_world * [1, 1, 1, s],
                      film_size=scene.camera.film_size * s)
        images.append(photon_mapping.render(replace(scene, mesh=mesh, camera=cam),
                                            SETTINGS).passes["direct"])
    np.testing.assert_allclose(images[0], images[1], rtol=1e-4)
    np.testing.assert_allclose(images[2], images[1], rtol=1e-4)


def test_sppm_visible_points_see_the_program_normal():
    a, theta = np.radians(30.0), np.radians(40.0)
    scene = floor_scene(normal_map_program(tilt_colour(a)), [1.0, 0.0, 0.0], theta)
    st = SETTINGS.with_values(integrator="progressive", progressive_passes=1,
                              photons_per_pass=500)
    out = sppm.render(scene, st).passes["combined"]  # one plane: direct light only
    np.testing.assert_allclose(out, ALBEDO * E_SUN * np.cos(theta - a) / np.pi, rtol=1e-4)

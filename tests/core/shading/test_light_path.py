"""The Light Path node's inputs (core/shading/light_path.py, ``SOURCE_LIGHT_PATH``) and the
Tangent node (``OP_TANGENT``, Cycles' svm_node_tangent), in the interpreter and at the
renderer's hits: an emitter whose emission is Is Camera Ray (or its complement) is seen
by the camera and lights nothing (or lights the floor exactly as a constant emitter and
is not seen); Ray Length at camera hits is the distance from the near clip plane; a leaf
whose opacity is 1 - 0.75 Is Shadow Ray is opaque to the camera and casts a shadow of
transmittance 0.75."""

from dataclasses import replace

import numpy as np

from core.integrators import photon_mapping
from core.prepared import prepare
from core.scene import closures
from core.scene.contract import Materials
from core.settings import RenderSettings
from core.shading import light_path
from core.shading import program as pg
from core.shading.converters import MATH_OPS
from core.shading.inputs import ShadingInputs
from core.shading.interpreter import evaluate
from tests.core.shading import test_program_alpha as leaf
from tests.core.shading import test_textured_emission as lamp

W = pg.INSTRUCTION_WIDTH
ins = lamp.ins


def read_column(k):
    return pg.ShaderProgram.build([ins(pg.OP_INPUT, [pg.SOURCE_LIGHT_PATH, k], [1])], [0.0],
                                  [[1 + c, pg.TARGET_EMISSION, 0, c] for c in range(3)], 4,
                                  name=f"light path {k}")


def test_each_output_reads_its_column_and_the_contexts_are_cycles_flags():
    rng = np.random.default_rng(1)
    n = 7
    lp = rng.random((n, light_path.COUNT)).astype(np.float32)
    inputs = ShadingInputs.build(rng.random((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)),
                                 light_path=lp)
    for k in range(light_path.COUNT):
        out = evaluate(read_column(k), inputs)
        np.testing.assert_array_equal(out, np.repeat(lp[:, k:k + 1], 3, axis=1))
    # default: zeros (no flag); a (K,) context is every point's
    assert np.all(evaluate(read_column(light_path.CAMERA),
                           ShadingInputs.build(lp[:, :3], lp[:, 3:6])) == 0)
    one = light_path.camera([2.5])[0]
    out = evaluate(read_column(light_path.RAY_LENGTH),
                   ShadingInputs.build(lp[:, :3], lp[:, 3:6], light_path=one))
    np.testing.assert_array_equal(out, 2.5)
    cam = light_path.camera([2.0])[0]
    assert cam[light_path.CAMERA] == 1 and cam.sum() == 3.0
    sh = light_path.shadow([1.5])[0]
    assert sh[light_path.SHADOW] == 1 and sh[light_path.RAY_LENGTH] == 1.5 and sh.sum() == 2.5
    # a delta transmission at depth 2 (Cycles: glossy + singular + transmit flags)
    b = light_path.after_bounce([1.0], light_path.BOUNCE_SINGULAR, [True], 2,
                                glossy_depth=2, transmission_depth=1)[0]
    flags = {light_path.OUTPUTS[i] for i in range(8) if b[i]}
    assert flags == {"Is Glossy Ray", "Is Singular Ray", "Is Transmission Ray"}
    assert (b[light_path.RAY_DEPTH], b[light_path.GLOSSY_DEPTH],
            b[light_path.TRANSMISSION_DEPTH], b[light_path.DIFFUSE_DEPTH]) == (2, 2, 1, 0)
    d = light_path.after_bounce([1.0], light_path.BOUNCE_DIFFUSE, [False], 1,
                                diffuse_depth=1)[0]
    assert {light_path.OUTPUTS[i] for i in range(8) if d[i]} == \
        {"Is Diffuse Ray", "Is Reflection Ray"}


def tangent_program(mode):
    code = [ins(pg.OP_INPUT, [pg.SOURCE_TANGENT if mode == 3 else pg.SOURCE_GENERATED, 0],
                [0]),
            *[ins(pg.OP_INPUT, [pg.SOURCE_NORMAL_TO_WORLD, i], [3 + 3 * i]) for i in range(3)],
            ins(pg.OP_INPUT, [pg.SOURCE_NORMAL, 0], [12]),
            ins(pg.OP_TANGENT, [mode], [0, 3, 6, 9, 12, 15])]
    return pg.ShaderProgram.build(code, [], [[15 + c, pg.TARGET_EMISSION, 0, c]
                                             for c in range(3)], 18, name=f"tangent {mode}")


def test_tangent_node_is_cycles_radial_and_uv_map_tangent():
    rng = np.random.default_rng(2)
    n = 50
    gen = rng.random((n, 3))
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    a = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    n2w = np.broadcast_to(np.linalg.inv(a).T, (n, 3, 3))
    tan = rng.normal(size=(n, 3))
    inputs = ShadingInputs.build(rng.random((n, 3)), nrm, generated=gen, normal_to_world=n2w,
                                 tangents=np.concatenate([tan, np.ones((n, 1))], 1)[None])
    g = gen - 0.5
    radial = {0: np.stack([0 * g[:, 0], -g[:, 2], g[:, 1]], 1),
              1: np.stack([-g[:, 2], 0 * g[:, 0], g[:, 0]], 1),
              2: np.stack([-g[:, 1], g[:, 0], 0 * g[:, 0]], 1)}
    for mode in range(4):
        t = tan if mode == 3 else np.einsum("nij,nj->ni", n2w, radial[mode])
        c = np.cross(t, nrm)
        want = np.cross(nrm, c / np.linalg.norm(c, axis=1)[:, None])
        got = evaluate(tangent_program(mode), inputs)
        np.testing.assert_allclose(got, want, atol=2e-6)
        np.testing.assert_allclose(np.einsum("ij,ij->i", got, nrm), 0.0, atol=2e-6)
    # no UV map tangent: 0, as Cycles without the attribute
    bare = ShadingInputs.build(rng.random((n, 3)), nrm)
    assert np.all(evaluate(tangent_program(3), bare) == 0)


def camera_emission(kind):
    """Emission L0 x Is Camera Ray ("camera"), L0 x (1 - Is Camera Ray) ("hidden"), or
    Ray Length ("length", grey)."""
    col = light_path.RAY_LENGTH if kind == "length" else light_path.CAMERA
    code = [ins(pg.OP_INPUT, [pg.SOURCE_LIGHT_PATH, col], [3])]
    if kind == "camera":
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [3, 0, 0, 6]))
    elif kind == "hidden":  # L0 - L0 x camera
        code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [3, 1, 0, 6]))
    else:
        code.append(ins(pg.OP_MATH, [MATH_OPS["ADD"], 0], [3, 2, 2, 6]))
    return pg.ShaderProgram.build(code, [lamp.L0, -lamp.L0, 0.0],
                                  [[6, pg.TARGET_EMISSION, 0, c] for c in range(3)], 7,
                                  name=kind)


def test_is_camera_ray_and_ray_length_at_the_hits():
    st = RenderSettings(samples=2, global_photons=4000, caustic_photons=0,
                        final_gather_rays=4, threads=2)
    plain = photon_mapping.render(lamp.emitter_scene(None, constant=(lamp.L0,) * 3),
                                  st).passes
    seen = photon_mapping.render(lamp.emitter_scene(camera_emission("camera"),
                                                    constant=(0.0,) * 3), st).passes
    hidden = photon_mapping.render(lamp.emitter_scene(camera_emission("hidden"),
                                                      constant=(0.0,) * 3), st).passes
    assert plain["direct"].max() > 0 and plain["emission"].max() > 0
    # seen by the camera only: the emission pass as the constant emitter, no light
    np.testing.assert_array_equal(seen["emission"], plain["emission"])
    for name in ("direct", "indirect", "caustics"):
        if name in seen:
            assert seen[name].max() == 0, name
    # hidden from the camera: every light term as the constant emitter, nothing seen
    assert hidden["emission"].max() == 0
    for name in ("direct", "indirect"):
        np.testing.assert_array_equal(hidden[name], plain[name], err_msg=name)
    # Ray Length: the camera 3 m above, the lamp at 0.5 m, rays from the near clip plane
    scene = lamp.emitter_scene(camera_emission("length"), constant=(0.0,) * 3)
    em = photon_mapping.render(scene, st).passes["emission"][..., 0]
    inside = em[3:5, 3:5]  # the pixels the 1 m lamp covers whole (3 m film, 8 pixels)
    np.testing.assert_allclose(inside, 3.0 - 0.5 - scene.camera.clip_start, rtol=1e-6)


def shadow_alpha():
    """opacity = 1 - 0.75 Is Shadow Ray."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_LIGHT_PATH, light_path.SHADOW], [3]),
            ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [3, 0, 1, 6])]
    return pg.ShaderProgram.build(code, [-0.75, 1.0], [[6, pg.TARGET_ALPHA, 0, 0]], 7,
                                  name="shadow alpha")


def test_is_shadow_ray_makes_a_leaf_transparent_to_shadow_rays_only():
    scene = leaf.leaf_scene()
    prog = list(scene.materials.programs)
    prog[0] = shadow_alpha()
    scene = replace(scene, materials=replace(scene.materials, programs=tuple(prog)))
    with prepare(scene) as pr:  # the camera sees it opaque
        t = np.flatnonzero(pr.tri_material == 0).astype(np.int32)
        np.testing.assert_array_equal(pr.surfaces.opacity(t, np.full(t.size, 0.3),
                                                          np.full(t.size, 0.3)), 1.0)
    st = RenderSettings(samples=4, global_photons=20000, caustic_photons=0,
                        final_gather_rays=4, threads=2)
    out = photon_mapping.render(scene, st).passes
    direct = out["direct"][..., 0]
    c = (np.arange(leaf.RES) + 0.5) / leaf.RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    lit = 0.8 / np.pi * leaf.SUN * np.cos(np.pi / 4)
    shadow = (Y > 0.5) & (Y < 1.0) & (np.abs(X) < 0.5)
    np.testing.assert_allclose(direct[shadow], 0.75 * lit, rtol=1e-4)
    on_leaf = (np.abs(Y) < 0.5) & (np.abs(X) < 0.5)  # the leaf itself, opaque: its own
    np.testing.assert_allclose(direct[on_leaf], 0.5 / np.pi * leaf.SUN * np.cos(np.pi / 4),
                               rtol=1e-4)


def test_is_camera_ray_in_sppm():
    """SPPM's camera paths (visible points) and photons: an emitter of L0 x (1 - Is Camera
    Ray) is not seen and lights the floor exactly as the constant emitter; L0 x Is Camera
    Ray is seen as the constant emitter at its own pixels and lights nothing."""
    from core.integrators import sppm
    st = RenderSettings(integrator="progressive", progressive_passes=2,
                        photons_per_pass=2000, threads=2)
    plain = sppm.render(lamp.emitter_scene(None, constant=(lamp.L0,) * 3), st).passes
    seen = sppm.render(lamp.emitter_scene(camera_emission("camera"), constant=(0.0,) * 3),
                       st).passes
    hidden = sppm.render(lamp.emitter_scene(camera_emission("hidden"), constant=(0.0,) * 3),
                         st).passes
    lamp_px = np.s_[3:5, 3:5]  # covered whole by the lamp
    floor = np.ones((lamp.RES, lamp.RES), bool)
    floor[2:6, 2:6] = False  # away from the lamp's pixels
    for name, image in plain.items():
        if image.ndim != 3 or image.max() == 0:
            continue
        print(name, float(image[lamp_px].mean()), float(image[floor].mean()),
              float(seen[name][lamp_px].mean()), float(seen[name][floor].max()),
              float(hidden[name][lamp_px].mean()), float(hidden[name][floor].mean()))
        np.testing.assert_array_equal(hidden[name][floor], image[floor], err_msg=name)
        np.testing.assert_array_equal(seen[name][lamp_px], image[lamp_px], err_msg=name)
        assert seen[name][floor].max() == 0, name
    # measured: the lamp's pixels 5.0 = L0 (plain and seen), 0 hidden; the floor's mean
    # 0.1293 (plain and hidden), 0 seen
    assert plain["combined"][lamp_px].min() == lamp.L0
    assert hidden["combined"][lamp_px].max() == 0


def wall_program(col, k=1.0):
    """COLOR = 0.8 x Light Path column col (col None: x the constant k)."""
    code = [] if col is None else [ins(pg.OP_INPUT, [pg.SOURCE_LIGHT_PATH, col], [2])]
    code.append(ins(pg.OP_MATH, [MATH_OPS["MULTIPLY"], 0], [0, 1 if col is None else 2, 0,
                                                            5]))
    return pg.ShaderProgram.build(code, [0.8, k], [[5, pg.TARGET_CLOSURE, 0,
                                                    closures.COLOR + c] for c in range(3)],
                                  6, name=f"wall {col}")


def walls_scene(program):
    """tests/core/shading/test_at_hits.py's floor under a sun, its four walls (out of the
    camera's view: only final-gather rays and photons meet them) of colour ``program``."""
    from tests.core.shading import test_at_hits as at
    s = at.scene(None, 0.5)
    floor_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                               "params": {"color": 0.5, "roughness": 0.0}}],
                 "diffuse": [0.5] * 3}
    wall_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                              "params": {"color": 0.8, "roughness": 0.0}}],
                "diffuse": [0.8] * 3, "program": program}
    return replace(s, materials=Materials.from_list([floor_row, wall_row]))


def test_final_gather_and_photon_hits_are_diffuse_rays_not_camera_rays():
    """Walls of colour 0.8 x Is Diffuse Ray render every pass bit for bit like walls of
    0.8 x 1 (final-gather and photon hits are diffuse rays); 0.8 x Is Camera Ray like 0.8
    x 0 there (they are not camera rays)."""
    st = RenderSettings(samples=2, global_photons=3000, caustic_photons=1000,
                        final_gather_rays=4, threads=2)
    one = photon_mapping.render(walls_scene(wall_program(None)), st).passes
    diffuse = photon_mapping.render(walls_scene(wall_program(light_path.DIFFUSE)), st).passes
    camera = photon_mapping.render(walls_scene(wall_program(light_path.CAMERA)), st).passes
    zero = photon_mapping.render(walls_scene(wall_program(None, 0.0)), st).passes
    assert one["indirect"].max() > zero["indirect"].max()
    for name, image in one.items():
        np.testing.assert_array_equal(diffuse[name], image, err_msg=name)
        np.testing.assert_array_equal(camera[name], zero[name], err_msg=name)


def test_a_bad_light_path_output_or_tangent_mode_is_a_clear_error():
    import pytest
    with pytest.raises(ValueError, match="Light Path output 15"):
        read_column(light_path.COUNT)
    bad = [ins(pg.OP_INPUT, [pg.SOURCE_GENERATED, 0], [0]),
           ins(pg.OP_TANGENT, [4], [0, 0, 0, 0, 0, 3])]
    with pytest.raises(ValueError, match="unknown mode 4"):
        pg.ShaderProgram.build(bad, [], [[3, pg.TARGET_EMISSION, 0, 0]], 6, name="bad")

"""Opacity from shader programs (TARGET_ALPHA; core/prepared.py ``HitShader.alpha_at``
through ``SurfaceTextures.use_program_alpha``): a leaf whose opacity is 0.25 on one half
and 0.75 on the other (a step in U) casts a shadow of transmittance 0.75 / 0.25 through
shadow rays, the camera sees through it stochastically, and photons pass it."""

from dataclasses import replace

import numpy as np

from core.integrators import photon_mapping
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_SUN, Camera, Lights, Materials, \
    Scene
from core.settings import RenderSettings
from core.shading import program as pg
from core.shading.converters import MATH_OPS

W = pg.INSTRUCTION_WIDTH
RES = 16
SUN = 3.0


def ins(op, ints, regs):
    row = [op] + list(ints) + [0] * (4 - len(ints)) + list(regs)
    return row + [-1] * (W - len(row))


def step_alpha():
    """alpha = 0.25 + 0.5 (U > 0.5)."""
    code = [ins(pg.OP_INPUT, [pg.SOURCE_UV, 0], [3]),
            ins(pg.OP_MATH, [MATH_OPS["GREATER_THAN"], 0], [3, 0, 0, 6]),
            ins(pg.OP_MATH, [MATH_OPS["MULTIPLY_ADD"], 0], [6, 0, 1, 7])]
    return pg.ShaderProgram.build(code, [0.5, 0.25, 0.0], [[7, pg.TARGET_ALPHA, 0, 0]], 8,
                                  name="step alpha")


def leaf_scene():
    """A 1 m leaf (U = x + 0.5) 0.5 m over a 4 m white floor; the sun 45 degrees from
    the vertical, from -y, so the shadow lies at y in [0, 1] (beside the leaf seen from
    above, x in [-0.5, 0.5]); an orthographic camera above."""
    leaf = shapes.quad([0, 0, 0.5], [0.5, 0, 0], [0, 0.5, 0])
    floor = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mesh = shapes.assemble([(leaf, 0), (floor, 1)])
    uvs = np.array(mesh.uvs, copy=True)
    corners = mesh.vertices[mesh.triangles[mesh.material_index == 0]]
    uvs[mesh.material_index == 0] = corners[..., :2] + 0.5
    mesh = replace(mesh, uvs=uvs.astype(np.float32))
    leaf_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                              "params": {"color": 0.5, "roughness": 0.0}}],
                "diffuse": [0.5] * 3, "program": step_alpha()}
    floor_row = {"closures": [{"kind": closures.CLOSURE_DIFFUSE,
                               "params": {"color": 0.8, "roughness": 0.0}}],
                 "diffuse": [0.8] * 3}
    m = shapes.look_at([0, -1, 1], [0, 0, 0])
    m[:3, 3] = 0.0
    sun = {"kind": LIGHT_SUN, "to_world": m, "power": SUN, "angle": 0.0}
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=RES,
                 height=RES, film_size=np.array([4.0, 4.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list([leaf_row, floor_row]), Lights.from_list([sun]),
                 cam)


def test_the_program_opacity_is_the_hits_opacity():
    with prepare(leaf_scene()) as pr:
        assert pr.surfaces.cutout
        prim = np.flatnonzero(pr.tri_material == 0).astype(np.int32)
        u = np.array([0.1, 0.6])
        for t in prim:
            p = np.repeat(t, 2)
            a = pr.surfaces.opacity(p, u, u)
            point = pr.tri_vertices[t, 0] + u[:, None] * (
                pr.tri_vertices[t, 1] - pr.tri_vertices[t, 0] + pr.tri_vertices[t, 2]
                - pr.tri_vertices[t, 0])
            np.testing.assert_allclose(a, np.where(point[:, 0] + 0.5 > 0.5, 0.75, 0.25))


def test_the_shadow_through_a_programmed_cut_out_is_the_transmittance():
    st = RenderSettings(samples=4, global_photons=20000, caustic_photons=0,
                        final_gather_rays=4, threads=2)
    out = photon_mapping.render(leaf_scene(), st).passes
    direct = out["direct"][..., 0]
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    lit = 0.8 / np.pi * SUN * np.cos(np.pi / 4)
    # the shadow: y in (0.5, 1) beside the leaf (pixel edges on its borders)
    shadow = (Y > 0.5) & (Y < 1.0)
    left = shadow & (X < 0.0) & (X > -0.5)
    right = shadow & (X > 0.0) & (X < 0.5)
    assert left.any() and right.any()
    np.testing.assert_allclose(direct[left], 0.75 * lit, rtol=1e-4)
    np.testing.assert_allclose(direct[right], 0.25 * lit, rtol=1e-4)
    free = (Y < -1.0) & (np.abs(X) > 0.75)  # no shadow, no leaf in front
    np.testing.assert_allclose(direct[free], lit, rtol=1e-4)

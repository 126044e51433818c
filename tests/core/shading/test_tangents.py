"""The BSDF frames' tangents (core/prepared.py ``HitShader.tangents``): Cycles' radial
default for anisotropic closures, the default tangent everywhere else."""

from dataclasses import replace

import numpy as np

from core.integrators import photon_mapping
from core.materials import closure
from core.prepared import prepare
from core.scene import closures, shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_POINT, Camera, Lights, Materials, \
    Scene
from core.settings import RenderSettings

RES = 16


def glossy(anisotropic, kind=closures.CLOSURE_GLOSSY):
    return {"kind": kind, "params": {"color": 0.8, "roughness": 0.4,
                                      "anisotropic": anisotropic}}


def floor_scene(rows, to_world=None, res=RES):
    """A 2 m floor at z = 0 (material 0) under a point light 1 m above its centre, seen
    straight down by an orthographic camera; to_world: the floor object's matrix (only
    shader inputs read it: Generated and the tangent's transform)."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    if to_world is not None:
        mesh = replace(mesh, object_to_world=np.asarray(to_world, np.float64)[None])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.0, 0.0, 1.0],
                                "power": 100.0}])
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=res,
                 height=res, film_size=np.array([2.0, 2.0]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list(rows), lights, cam)


def test_anisotropic_rows_name_the_rows_whose_closures_depend_on_the_tangent():
    tab = closure.table(Materials.from_list([
        {"closures": [glossy(0.5)]},
        {"closures": [glossy(0.0, closures.CLOSURE_PRINCIPLED)]},
        {"closures": [glossy(-0.5)]},  # Glossy: negative stretches along the bitangent
        {"closures": [glossy(-0.5, closures.CLOSURE_PRINCIPLED)]},  # clamped to 0 there
        {"closures": [{"kind": closures.CLOSURE_DIFFUSE, "params": {"color": 0.5}}]},
        {"closures": [{"kind": closures.CLOSURE_DIFFUSE, "params": {"color": 0.5}},
                      glossy(0.3, closures.CLOSURE_METALLIC)]},
    ]))
    assert closure.anisotropic_rows(tab).tolist() == [True, False, True, False, False, True]


def _hits(scene, n=200, seed=3):
    """n points on the floor: prim (n,) int32, positions (n, 3)."""
    rng = np.random.default_rng(seed)
    b = rng.random((n, 2))
    b = np.where(b.sum(axis=1, keepdims=True) > 1, 1 - b, b)
    prim = rng.integers(0, scene.mesh.triangle_count, n).astype(np.int32)
    tri = scene.mesh.triangle_vertices()[prim].astype(np.float64)
    pos = tri[:, 0] + b[:, :1] * (tri[:, 1] - tri[:, 0]) + b[:, 1:] * (tri[:, 2] - tri[:, 0])
    return prim, pos


def test_isotropic_hits_keep_the_default_tangent():
    sc = floor_scene([{"closures": [glossy(0.0)]}])
    pr = prepare(sc, threads=1)
    prim, pos = _hits(sc)
    t = pr.hit_shader.tangents(prim, pos, pr.closures, sc.mesh.material_index[prim])
    assert (t == np.array(closure.DEFAULT_TANGENT)).all()
    pr.close()


def test_the_radial_tangent_circles_the_object_z_axis_as_cycles():
    # Cycles (svm_node_tangent, radial, axis Z): t = (-(g.y - 0.5), g.x - 0.5, 0) of
    # Generated g, through inv(A)^T. Identity object, default texture space: g = p + 0.5,
    # so t = (-y, x, 0), orthogonal to the radius.
    sc = floor_scene([{"closures": [glossy(0.7)]}])
    pr = prepare(sc, threads=1)
    prim, pos = _hits(sc)
    t = pr.hit_shader.tangents(prim, pos, pr.closures, sc.mesh.material_index[prim])
    np.testing.assert_allclose(t, np.stack([-pos[:, 1], pos[:, 0], 0 * pos[:, 0]], 1),
                               atol=1e-12)
    pr.close()
    # A rotated and scaled object (A = R S): t_world = inv(A)^T t_obj, t_obj from the
    # object-space point p_obj = inv(A) p.
    ang = 0.6
    r = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    a = np.eye(4)
    a[:3, :3] = r @ np.diag([2.0, 0.5, 1.0])
    sc = floor_scene([{"closures": [glossy(0.7)]}], to_world=a)
    pr = prepare(sc, threads=1)
    t = pr.hit_shader.tangents(prim, pos, pr.closures, sc.mesh.material_index[prim])
    inv = np.linalg.inv(a[:3, :3])
    p_obj = pos @ inv.T
    t_obj = np.stack([-p_obj[:, 1], p_obj[:, 0], 0 * pos[:, 0]], 1)
    np.testing.assert_allclose(t, t_obj @ inv, atol=1e-12)  # rows: (inv^T t)^T = t^T inv
    # The BSDF frame built from it is orthonormal with the normal.
    for i in range(0, len(t), 37):
        tx, ty, tz, bx, by, bz = closure.frame(0.0, 0.0, 1.0, *t[i])
        assert abs(tz) < 1e-12 and abs(tx * tx + ty * ty - 1) < 1e-12
        assert abs(bx * tx + by * ty + bz * tz) < 1e-12
    pr.close()


def test_an_anisotropic_floor_lit_from_its_axis_renders_rotationally_symmetric():
    # Light and camera on the object's Z axis: with the radial tangent every point sees the
    # same configuration (half vector along the radius, tangent across it), so the image
    # is unchanged by a quarter turn. The default tangent (1, 0, 0) stretches the
    # highlight along x at every point, which a quarter turn does not preserve.
    sc = floor_scene([{"closures": [glossy(0.9)]}])
    st = RenderSettings(samples=32, global_photons=0, caustic_photons=0, threads=2)
    img = photon_mapping.render(sc, st).passes["direct"].mean(axis=2)
    assert np.isfinite(img).all() and (img >= 0).all() and img.max() > 0
    blocks = img.reshape(4, RES // 4, 4, RES // 4).mean(axis=(1, 3))
    turned = np.rot90(blocks)
    np.testing.assert_allclose(turned, blocks, rtol=0.03)

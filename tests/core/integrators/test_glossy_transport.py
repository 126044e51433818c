"""Glossy transport in the camera pass (issue 13): camera paths sample rough lobes and go
on, direct light on glossy lobes is weighted against BSDF sampling (power heuristic), for
the world, emissive triangles and area lights. References are independent of the samplers:
the GGX lobe's directional albedo integrated numerically from ``bsdf.ggx_brdf``, and light
sampling alone (no MIS) with many light samples."""

import numpy as np
import pytest

from core.integrators import photon_mapping as integrator
from core.materials import bsdf
from core.scene import shapes
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, LIGHT_AREA, Camera, Lights, Materials,
                                 Scene, World)
from core.settings import RenderSettings

TINT = np.array([0.9, 0.7, 0.5])


def ggx_albedo(alpha, theta, n=400_000, seed=0):
    """int f cos dw of the legacy GGX lobe (tint 1) at view angle theta, by uniform
    hemisphere directions (independent of the renderer's samplers)."""
    u = np.random.default_rng(seed).random((n, 2))
    z = u[:, 0]
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(2 * np.pi * u[:, 1]), r * np.sin(2 * np.pi * u[:, 1]), z], 1)
    wo = np.tile([np.sin(theta), 0.0, np.cos(theta)], (n, 1))
    f = bsdf.ggx_brdf(alpha, np.tile([0.0, 0.0, 1.0], (n, 1)), wo, wi)
    return float(np.mean(f * z) * 2 * np.pi)


def view(theta, target=(0.0, 0.0, 0.0), dist=1.0, res=4, size=0.2):
    eye = np.asarray(target) + dist * np.array([np.sin(theta), 0.0, np.cos(theta)])
    return Camera(to_world=shapes.look_at(eye, target, up=(0, 1, 0)), width=res, height=res,
                  film_size=np.array([size, size]), kind=CAMERA_ORTHOGRAPHIC)


SETTINGS = RenderSettings(samples=64, light_samples=1, indirect_mode="off", caustics=False,
                          max_specular_depth=1, threads=2)


@pytest.mark.parametrize("roughness, theta", [(0.3, 0.5), (0.6, 1.0)])
def test_rough_metal_in_a_uniform_world_reflects_its_albedo(roughness, theta):
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"specular": list(TINT), "roughness": roughness}])
    scene = Scene(shapes.assemble([(plane, 0)]), mats, Lights.empty(), view(theta),
                  World(radiance=np.ones(3, np.float32)))
    exp = TINT * ggx_albedo(roughness ** 2, theta)
    out = integrator.render(scene, SETTINGS)
    # The world reaches the lobe both ways: light (cosine) samples and glossy rays that escape.
    assert out.passes["direct"].mean() > 0 and out.passes["specular"].mean() > 0
    np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), exp, rtol=0.02)
    # Light sampling alone (no continuation) is unbiased too: the MIS weights sum to one.
    alone = integrator.render(scene, SETTINGS.with_values(max_specular_depth=0,
                                                          light_samples=32))
    assert np.all(alone.passes["specular"] == 0)
    np.testing.assert_allclose(alone.passes["combined"].mean(axis=(0, 1)), exp, rtol=0.03)


def test_rough_metal_inside_an_emissive_box_reflects_its_albedo():
    """Emissive triangles all around (radiance 1): shadow rays to them and glossy rays that
    hit them share the lobe by the power heuristic."""
    theta, roughness = 0.7, 0.4
    room = shapes.box([-1, -1, -0.5], [1, 1, 1.5], inward=True)
    plane = shapes.quad([0, 0, 0], [0.5, 0, 0], [0, 0.5, 0])
    mats = Materials.from_list([{"specular": list(TINT), "roughness": roughness},
                                {"emission": [1.0, 1.0, 1.0]}])
    scene = Scene(shapes.assemble([(plane, 0), (room, 1)]), mats, Lights.empty(),
                  view(theta, dist=0.8))
    out = integrator.render(scene, SETTINGS)
    exp = TINT * ggx_albedo(roughness ** 2, theta)
    assert out.passes["specular"].mean() > 0
    np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), exp, rtol=0.02)


def test_small_area_light_highlight_is_cleaner_with_mis():
    """A small bright area light on a low-roughness lobe: MIS (light + BSDF samples) and
    light sampling alone agree on the mean; MIS has the smaller error against many light
    samples at the same number of camera samples."""
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"specular": [0.8, 0.8, 0.8], "roughness": 0.12}])
    theta = 0.6
    light = {"kind": LIGHT_AREA, "to_world": shapes.look_at([-0.8, 0, 1.2], [0, 0, 0]),
             "power": 30.0, "size": [0.3, 0.3]}
    cam = view(theta, dist=1.5, res=12, size=0.6)
    scene = Scene(shapes.assemble([(plane, 0)]), mats, Lights.from_list([light]), cam)
    base = SETTINGS.with_values(samples=4)
    ref = integrator.render(scene, base.with_values(samples=16, light_samples=64,
                                                    max_specular_depth=0)).passes["combined"]
    mis = integrator.render(scene, base).passes["combined"]
    alone = integrator.render(scene, base.with_values(max_specular_depth=0)).passes["combined"]
    assert ref.mean() > 0.05
    np.testing.assert_allclose(mis.mean(), ref.mean(), rtol=0.05)

    def rmse(a):
        return float(np.sqrt(np.mean((a - ref) ** 2)))
    assert rmse(mis) < 0.7 * rmse(alone), (rmse(mis), rmse(alone))


@pytest.mark.parametrize("roughness, theta", [(0.3, 0.5)])
def test_progressive_mode_renders_a_rough_metal_in_a_uniform_world(roughness, theta):
    """SPPM's visible points go on through a rough lobe without a diffuse one (no photon
    is stored there): the metal reflects the world, converging to its albedo."""
    from core.integrators import sppm
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"specular": list(TINT), "roughness": roughness}])
    scene = Scene(shapes.assemble([(plane, 0)]), mats, Lights.empty(), view(theta, res=8),
                  World(radiance=np.ones(3, np.float32)))
    out = sppm.render(scene, RenderSettings(integrator="progressive", progressive_passes=64,
                                            photons_per_pass=100, threads=2))
    exp = TINT * ggx_albedo(roughness ** 2, theta)
    np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), exp, rtol=0.02)


def _world_plane(closures, theta=0.5):
    """A 2 x 2 m plane of the closures, alone in a uniform world of radiance 1 (hidden from
    the camera), seen at theta from its front."""
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"closures": closures}])
    return Scene(shapes.assemble([(plane, 0)]), mats, Lights.empty(), view(theta),
                 World(radiance=np.ones(3, np.float32), visible_to_camera=False)).validate()


@pytest.mark.parametrize("indirect", ["off", "final_gather"])
def test_translucent_plane_shows_the_world_behind_it(indirect):
    """A Translucent plane (colour 0.8) in a uniform world L = 1: what leaves its front is
    int over the back hemisphere of (0.8 / pi) L cos = 0.8 L, all of it the world behind
    the plane, which direct light reaches by sampling the world over the whole sphere
    (the front hemisphere alone gave 0). Plus an Add of Diffuse 0.3 (the front world:
    0.3 L) and Translucent 0.5 (the back: 0.5 L): 0.8 L again. The photon terms add
    nothing the shadow rays already hold (no double count). (Lambert: the Diffuse of
    roughness 0.)"""
    from core.scene import closures as cl
    settings = SETTINGS.with_values(indirect_mode=indirect, max_specular_depth=2, samples=128)
    for closures in ([dict(kind=cl.CLOSURE_TRANSLUCENT, params=dict(color=0.8))],
                     [dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=0.3, roughness=0.0)),
                      dict(kind=cl.CLOSURE_TRANSLUCENT, params=dict(color=0.5))]):
        out = integrator.render(_world_plane(closures), settings)
        np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), 0.8, rtol=0.02)


@pytest.mark.parametrize("roughness", [0.3, 0.6])
def test_rough_glass_sheet_in_a_uniform_world_keeps_its_albedo(roughness):
    """One rough glass interface (multiscatter GGX, IOR 1.5, white) in a uniform world of
    radiance 1: its reflection and its transmission both end in the world, so the plane
    shows the lobe's albedo, 1 within 2 % (furnace, docs/materials.md). Shadow rays to the
    world behind the sheet and transmitted rays that escape share the transmission by the
    power heuristic: both sides' light samples are weighed, none counted twice."""
    from core.scene import closures as cl
    closures = [dict(kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=roughness,
                                                        ior=1.5))]
    out = integrator.render(_world_plane(closures), SETTINGS.with_values(samples=128))
    assert out.passes["direct"].mean() > 0.01  # the world by light sampling, both sides
    np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), 1.0, rtol=0.02)

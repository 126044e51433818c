"""Light units and sampling against closed forms (Cycles' conventions, DESIGN.md "Units").

Renders look straight down with an orthographic camera at a Lambert plane z = 0, so each
pixel sees a known patch, whose radiance must be albedo * E / pi for the irradiance E of
each light type, with cos(theta) and 1/r^2.
"""

import numpy as np
import pytest

from core import sampling
from core.integrators import photon_mapping as integrator
from core.lights import light_set as lights
from core.scene import shapes
from core.scene.contract import (AREA_ELLIPSE, AREA_RECTANGLE, CAMERA_ORTHOGRAPHIC, LIGHT_AREA,
                        LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, Camera, Lights, Materials, Scene,
                        World)
from core.settings import RenderSettings

ALBEDO = np.array([0.8, 0.5, 0.25])
RES, HALF = 16, 1.0  # 16 x 16 pixels over the square [-1, 1]^2


def top_camera():
    return Camera(to_world=shapes.look_at([0, 0, 5], [0, 0, 0], up=(0, 1, 0)), width=RES, height=RES,
                  film_size=np.array([2 * HALF, 2 * HALF]), kind=CAMERA_ORTHOGRAPHIC)


def plane_scene(light_rows, world=None):
    plane = shapes.quad([0, 0, 0], [3, 0, 0], [0, 3, 0])
    return Scene(shapes.assemble([(plane, 0)]), Materials.from_list([{"diffuse": ALBEDO}]),
                 Lights.from_list(light_rows), top_camera(), world or World())


def pixel_patches(sub=6):
    """World points (RES, RES, sub*sub, 3) sampling each pixel's patch (row 0 = +y)."""
    g = (np.arange(sub) + 0.5) / sub
    cols = (np.arange(RES)[:, None] + g[None, :]) / RES * 2 * HALF - HALF  # (RES, sub)
    rows = HALF - (np.arange(RES)[:, None] + g[None, :]) / RES * 2 * HALF
    x = np.broadcast_to(cols[None, :, None, :], (RES, RES, sub, sub))
    y = np.broadcast_to(rows[:, None, :, None], (RES, RES, sub, sub))
    return np.stack([x, y, np.zeros_like(x)], axis=-1).reshape(RES, RES, sub * sub, 3)


def expected_radiance(irradiance_fn):
    e = irradiance_fn(pixel_patches()).mean(axis=2)  # (RES, RES)
    return ALBEDO[None, None, :] * e[..., None] / np.pi


def render(scene, **kw):
    return integrator.render(scene, RenderSettings(**{"samples": 16, "adaptive_threshold": 0.0,
                                                      **kw}))


def point_irradiance(pos, power):
    def e(p):
        d = np.asarray(pos) - p
        r2 = np.sum(d * d, axis=-1)
        return power / (4 * np.pi) * d[..., 2] / np.sqrt(r2) / r2
    return e


def light_frame(direction_to_light):
    """A light matrix whose local +Z points along ``direction_to_light`` (it emits along -Z)."""
    z = np.asarray(direction_to_light, np.float64)
    return shapes.look_at(np.zeros(3), -z)


def test_point_light_on_lambert_plane():
    pos, power = np.array([0.3, -0.2, 1.5]), 200.0
    out = render(plane_scene([{"kind": LIGHT_POINT, "position": pos, "power": power}]))
    np.testing.assert_allclose(out.passes["direct"], expected_radiance(point_irradiance(pos, power)), rtol=0.01)
    assert np.all(out.passes["emission"] == 0)


def test_point_light_colour_multiplies_power():
    pos = np.array([0.0, 0.0, 1.0])
    rows = [{"kind": LIGHT_POINT, "position": pos, "power": 100.0, "color": [1.0, 0.5, 0.0]}]
    img = render(plane_scene(rows)).passes["direct"]
    exp = expected_radiance(point_irradiance(pos, 100.0)) * np.array([1.0, 0.5, 0.0])
    np.testing.assert_allclose(img, exp, rtol=0.01, atol=1e-7)


@pytest.mark.parametrize("angle", [0.0, np.radians(10.0)])
def test_sun_irradiance_is_strength_times_cosine(angle):
    theta = np.radians(35.0)
    to_sun = np.array([np.sin(theta), 0.0, np.cos(theta)])
    rows = [{"kind": LIGHT_SUN, "to_world": light_frame(to_sun), "power": 3.0, "angle": angle}]
    img = render(plane_scene(rows)).passes["direct"]
    # A uniform disc entirely above the horizon: E = S cos(theta) exactly, any angle.
    exp = ALBEDO * 3.0 * np.cos(theta) / np.pi
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), exp, rtol=0.01)
    np.testing.assert_allclose(img, np.broadcast_to(exp, img.shape), rtol=0.01 if angle == 0 else 0.05)


def rectangle_irradiance(center, sx, sy, radiance):
    """Closed form for a Lambertian rectangle parallel to the receiver plane (z = 0),
    facing down: sum of four corner rectangles (form factor of a differential area)."""
    cx, cy, h = center

    def corner(a, b):
        x, y = a / h, b / h
        return (x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
                + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))) / (2 * np.pi)

    def e(p):
        x0, x1 = cx - sx / 2 - p[..., 0], cx + sx / 2 - p[..., 0]
        y0, y1 = cy - sy / 2 - p[..., 1], cy + sy / 2 - p[..., 1]
        f = (np.sign(x1) * np.sign(y1) * corner(abs(x1), abs(y1))
             - np.sign(x0) * np.sign(y1) * corner(abs(x0), abs(y1))
             - np.sign(x1) * np.sign(y0) * corner(abs(x1), abs(y0))
             + np.sign(x0) * np.sign(y0) * corner(abs(x0), abs(y0)))
        return np.pi * radiance * f
    return e


def test_small_area_light_on_lambert_plane():
    center, sx, sy, power = np.array([0.2, 0.1, 0.8]), 0.3, 0.2, 50.0
    rows = [{"kind": LIGHT_AREA, "position": center, "power": power, "size": [sx, sy]}]
    img = render(plane_scene(rows), light_samples=8).passes["direct"]
    radiance = power / (np.pi * sx * sy)  # Cycles: L = P / (pi A)
    exp = expected_radiance(rectangle_irradiance(center, sx, sy, radiance))
    np.testing.assert_allclose(img.mean(axis=(0, 1)), exp.mean(axis=(0, 1)), rtol=0.01)
    np.testing.assert_allclose(img, exp, rtol=0.04)


def test_area_light_is_one_sided():
    rows = [{"kind": LIGHT_AREA, "to_world": shapes.look_at([0, 0, 1], [0, 0, 2]), "power": 50.0}]
    assert np.all(render(plane_scene(rows)).passes["combined"] == 0)


def monte_carlo_irradiance(ls, i, point, normal, n=200_000, sub=None):
    """E = mean(weight * cos) of the light's own sampler at one point."""
    pts = np.broadcast_to(np.asarray(point, np.float64), (n, 3))
    idx = np.arange(n)
    u1 = sampling.uniform(7, idx, np.zeros(n, np.int64), 0)
    u2 = sampling.uniform(7, idx, np.zeros(n, np.int64), 1)
    s = lights.sample_direct(ls, i, pts, u1, u2)
    cos = np.clip(s.direction @ np.asarray(normal, np.float64), 0, None)
    return (s.weight * (cos * s.valid)[:, None]).mean(axis=0)


def test_disk_area_light_on_axis_closed_form():
    r, d, power = 0.25, 0.6, 10.0
    li = Lights.from_list([{"kind": LIGHT_AREA, "position": [0, 0, d], "power": power,
                            "shape": AREA_ELLIPSE, "size": [2 * r, 2 * r]}])
    ls = lights.LightSet.from_lights(li)
    radiance = power / (np.pi * np.pi * r * r)
    e = monte_carlo_irradiance(ls, 0, [0, 0, 0], [0, 0, 1])
    np.testing.assert_allclose(e, radiance * np.pi * r * r / (r * r + d * d), rtol=0.005)


def test_rectangle_area_light_closed_form_off_axis():
    center, sx, sy = np.array([0.3, -0.1, 0.5]), 0.8, 0.4
    li = Lights.from_list([{"kind": LIGHT_AREA, "position": center, "power": 7.0,
                            "shape": AREA_RECTANGLE, "size": [sx, sy]}])
    ls = lights.LightSet.from_lights(li)
    p = np.array([-0.2, 0.1, 0.0])
    exact = rectangle_irradiance(center, sx, sy, 7.0 / (np.pi * sx * sy))(p[None])[0]
    np.testing.assert_allclose(monte_carlo_irradiance(ls, 0, p, [0, 0, 1]), exact, rtol=0.005)


def test_spot_cone_cut_and_smoothstep():
    half, blend, power = np.radians(30.0), 0.25, 100.0
    li = Lights.from_list([{"kind": LIGHT_SPOT, "position": [0, 0, 2], "power": power,
                            "spot_size": 2 * half, "spot_blend": blend}])
    ls = lights.LightSet.from_lights(li)
    angles = np.radians([0.0, 20.0, 27.0, 29.5, 31.0, 60.0])
    pts = np.stack([2 * np.tan(angles), np.zeros_like(angles), np.zeros_like(angles)], axis=1)
    s = lights.sample_direct(ls, 0, pts, np.full(6, 0.5), np.full(6, 0.5))
    d2 = np.sum((pts - [0, 0, 2]) ** 2, axis=1)
    # The contract stores angles as float32: use the stored values.
    cos_half = np.cos(np.float64(np.float32(2 * half)) / 2)
    x = (np.cos(angles) - cos_half) / ((1 - cos_half) * np.float64(np.float32(blend)))
    smooth = np.where(x <= 0, 0, np.where(x >= 1, 1, x * x * (3 - 2 * x)))
    np.testing.assert_allclose(s.weight[:, 0], power / (4 * np.pi) / d2 * smooth, rtol=1e-12, atol=1e-15)
    assert smooth[0] == 1 and 0 < smooth[3] < 1 and smooth[4] == 0
    assert not np.any(s.valid[4:])
    # Same intensity as a point light of equal power inside the cone.
    p = lights.LightSet.from_lights(Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 2], "power": power}]))
    ps = lights.sample_direct(p, 0, pts[:1], np.full(1, 0.5), np.full(1, 0.5))
    np.testing.assert_allclose(s.weight[0], ps.weight[0], rtol=1e-12)


def test_spot_hard_edge_when_blend_is_zero():
    li = Lights.from_list([{"kind": LIGHT_SPOT, "position": [0, 0, 1], "power": 1.0,
                            "spot_size": np.radians(60), "spot_blend": 0.0}])
    ls = lights.LightSet.from_lights(li)
    pts = np.array([[np.tan(np.radians(29.0)), 0, 0], [np.tan(np.radians(31.0)), 0, 0]])
    s = lights.sample_direct(ls, 0, pts, np.full(2, 0.5), np.full(2, 0.5))
    assert s.weight[0, 0] > 0 and s.weight[1, 0] == 0


def test_spot_render_inside_and_outside_the_cone():
    rows = [{"kind": LIGHT_SPOT, "position": [0, 0, 1], "power": 100.0,
             "spot_size": np.radians(40), "spot_blend": 0.0}]
    img = render(plane_scene(rows)).passes["direct"][..., 0]
    # Cone radius on the plane: tan(20 deg) = 0.36 m. Pixel centres at 0.0625 and 0.9375 m.
    inside = expected_radiance(point_irradiance([0, 0, 1], 100.0))[..., 0]
    np.testing.assert_allclose(img[7:9, 7:9], inside[7:9, 7:9], rtol=0.01)
    assert img[0, 0] == 0 and img[15, 15] == 0


@pytest.mark.parametrize("soft", [False, True])
def test_sphere_light_far_away_equals_point_light(soft):
    rows = [{"kind": LIGHT_POINT, "position": [0, 0, 10], "power": 100.0, "radius": 0.1,
             "soft_falloff": soft}]
    ls = lights.LightSet.from_lights(Lights.from_list(rows))
    p = np.array([1.0, 0.5, 0.0])
    e = monte_carlo_irradiance(ls, 0, p, [0, 0, 1], n=50_000)
    exact = point_irradiance([0, 0, 10], 100.0)(p[None])[0]
    np.testing.assert_allclose(e, exact, rtol=0.002)


def test_sphere_light_close_up_closed_forms():
    r, d, power = 0.5, 1.0, 100.0
    sphere = lights.LightSet.from_lights(Lights.from_list(
        [{"kind": LIGHT_POINT, "position": [0, 0, d], "power": power, "radius": r, "soft_falloff": False}]))
    disk = lights.LightSet.from_lights(Lights.from_list(
        [{"kind": LIGHT_POINT, "position": [0, 0, d], "power": power, "radius": r}]))
    # A uniform sphere facing the receiver gives exactly the point light's I / d^2.
    np.testing.assert_allclose(monte_carlo_irradiance(sphere, 0, [0, 0, 0], [0, 0, 1]),
                               power / (4 * np.pi * d * d), rtol=0.003)
    # Cycles' soft falloff: a facing disk of the same radiance, E = P / (4 pi (r^2 + d^2)).
    np.testing.assert_allclose(monte_carlo_irradiance(disk, 0, [0, 0, 0], [0, 0, 1]),
                               power / (4 * np.pi * (r * r + d * d)), rtol=0.003)


def test_emissive_triangles_light_like_an_area_light():
    """An emissive square ceiling panel: irradiance below its centre from the closed form."""
    panel = shapes.quad([0, 0, 0.7], [0.2, 0, 0], [0, -0.3, 0])  # faces down
    mesh = shapes.assemble([(panel, 0)])
    tris = lights.EmissiveTriangles.from_mesh(mesh, Materials.from_list([{"emission": [2.0, 1.0, 0.5]}]))
    n = 200_000
    idx = np.arange(n)
    u = [sampling.uniform(3, idx, np.zeros(n, np.int64), k) for k in range(3)]
    s = lights.sample_emissive(tris, np.zeros((n, 3)), *u)
    e = (s.weight * np.clip(s.direction[:, 2], 0, None)[:, None]).mean(axis=0)
    exact = rectangle_irradiance([0, 0, 0.7], 0.4, 0.6, 1.0)(np.zeros((1, 3)))[0] * np.array([2.0, 1.0, 0.5])
    np.testing.assert_allclose(e, exact, rtol=0.005)
    np.testing.assert_allclose(tris.power, 2 * np.pi * 0.24 * np.array([2.0, 1.0, 0.5]))


def test_uniform_world_lights_an_open_plane():
    img = render(plane_scene([], World(radiance=np.array([0.5, 1.0, 2.0], np.float32)))).passes
    # Unoccluded hemisphere of radiance L: E = pi L, so the plane shows albedo * L.
    np.testing.assert_allclose(img["direct"], np.broadcast_to(ALBEDO * [0.5, 1.0, 2.0], img["direct"].shape), rtol=1e-6)


def test_visible_area_light_shows_its_radiance():
    """Camera looking up at a light (visible to camera): radiance P / (pi A) on its front."""
    cam = Camera(to_world=shapes.look_at([0, 0, 0], [0, 0, 1], up=(0, 1, 0)), width=8, height=8,
                 film_size=np.array([0.2, 0.2]), kind=CAMERA_ORTHOGRAPHIC)
    rows = [{"kind": LIGHT_AREA, "position": [0, 0, 2], "power": 30.0, "size": [1.0, 2.0],
             "color": [1.0, 0.5, 0.25], "visible_to_camera": True}]
    scene = Scene(shapes.assemble([]), Materials.from_list([]), Lights.from_list(rows), cam)
    img = integrator.render(scene, RenderSettings(samples=4)).passes["emission"]
    np.testing.assert_allclose(img, np.broadcast_to(np.array([1.0, 0.5, 0.25]) * 30 / (np.pi * 2.0), img.shape), rtol=1e-6)
    rows[0]["visible_to_camera"] = False
    scene = Scene(shapes.assemble([]), Materials.from_list([]), Lights.from_list(rows), cam)
    assert np.all(integrator.render(scene, RenderSettings(samples=1)).passes["combined"] == 0)


@pytest.mark.parametrize("soft", [False, True])
def test_sphere_light_seen_by_the_camera_has_its_radiance(soft):
    """Radius r: radiance P / (4 pi^2 r^2) on the sphere (or the disk facing the camera)."""
    cam = Camera(to_world=shapes.look_at([0, -5, 0], [0, 0, 0]), width=5, height=5,
                 film_size=np.array([0.1, 0.1]), kind=CAMERA_ORTHOGRAPHIC)
    rows = [{"kind": LIGHT_POINT, "position": [0, 0, 0], "power": 20.0, "radius": 0.5,
             "soft_falloff": soft, "visible_to_camera": True}]
    scene = Scene(shapes.assemble([]), Materials.from_list([]), Lights.from_list(rows), cam)
    img = integrator.render(scene, RenderSettings(samples=2)).passes["emission"]
    np.testing.assert_allclose(img, 20.0 / (4 * np.pi ** 2 * 0.25), rtol=1e-6)


def test_sun_disc_is_seen_in_a_mirror():
    """A mirror facing up under a sun straight overhead shows the disc's radiance S / (pi sin^2 h)."""
    half = np.radians(5.0)
    mirror = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], up=(0, 1, 0)), width=4, height=4,
                 film_size=np.array([1.0, 1.0]), kind=CAMERA_ORTHOGRAPHIC)
    rows = [{"kind": LIGHT_SUN, "to_world": light_frame([0, 0, 1]), "power": 2.0, "angle": 2 * half}]
    scene = Scene(shapes.assemble([(mirror, 0)]), Materials.from_list([{"specular": [0.5, 0.5, 0.5]}]),
                  Lights.from_list(rows), cam)
    img = integrator.render(scene, RenderSettings(samples=2)).passes["specular"]
    np.testing.assert_allclose(img, 0.5 * 2.0 / (np.pi * np.sin(np.float32(2 * half) / 2) ** 2), rtol=1e-5)

"""Direct light by shadow rays (core/integrators/direct.py) on its own: ``shade`` at floor
points built by hand, against the closed forms of Cycles' light units
(DESIGN.md, "Units"): point light I = P / (4 pi), area light radiance
P / (pi A) one-sided, sun irradiance = strength; Lambert reflects albedo / pi x E."""

import numpy as np
import pytest

from core.integrators import direct
from core.prepared import prepare
from core.scene import geometry, shapes
from core.scene.contract import LIGHT_AREA, LIGHT_POINT, LIGHT_SUN, Lights, Materials, Scene
from core.settings import RenderSettings

ALBEDO = np.array([0.8, 0.5, 0.25])
HALF = 2.0  # the floor is [-2, 2]^2 at z = 0, facing +Z
CAM = shapes.pinhole([0, 0, 5], [0, 0, 0], 8, 8, 1.0)


def _scene(lights, extra_parts=()):
    parts = [(shapes.quad([0, 0, 0], [HALF, 0, 0], [0, HALF, 0]), 0)]
    parts += [(p, 0) for p in extra_parts]
    mats = Materials.from_list([{"diffuse": list(ALBEDO)}])
    return Scene(shapes.assemble(parts), mats, Lights.from_list(lights), CAM).validate()


def _points(xy):
    """ShadingPoints on the floor at (x, y), reached from above, throughput 1."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    n = xy.shape[0]
    pos = np.c_[xy, np.zeros(n)]
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    return pos, up


def _shade(scene, xy, light_samples=1, seed=7, throughput=None):
    """Radiance (N, 3) that direct.shade adds at floor points xy (N, 2)."""
    pos, up = _points(xy)
    n = pos.shape[0]
    settings = RenderSettings().with_values(seed=seed, light_samples=light_samples, threads=2)
    with prepare(scene, 2) as prepared:
        ctx = direct.prepare(settings, prepared, 1)
        thr = np.ones((n, 3)) if throughput is None else np.tile(throughput, (n, 1))
        hit = direct.ShadingPoints(
            position=pos, ng=up, ns=up, direction=-up, material=np.zeros(n, np.int32),
            eps=geometry.point_eps(pos, prepared.extent), throughput=thr,
            albedo=np.tile(ALBEDO, (n, 1)), rows=np.arange(n, dtype=np.int64))
        target = np.zeros((n, 3))
        direct.shade(ctx, hit, np.arange(n, dtype=np.int64), np.zeros(n, np.int64), 0, target)
        return target, ctx.stats


def _grid(m, half=1.8):
    g = np.linspace(-half, half, m)
    return np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)


# --- point light ------------------------------------------------------------------------

@pytest.mark.parametrize("height, power", [(1.5, 100.0), (0.25, 3.0), (4.0, 1000.0)])
def test_point_light_matches_inverse_square_law(height, power):
    light = np.array([0.3, -0.2, height])
    xy = _grid(9)
    got, stats = _shade(_scene([{"kind": LIGHT_POINT, "position": light, "power": power}]), xy)
    pos, _ = _points(xy)
    v = light - pos
    d2 = (v * v).sum(axis=1)
    cos = v[:, 2] / np.sqrt(d2)
    intensity = power / (4 * np.pi)  # W/sr, Cycles' point light
    want = ALBEDO / np.pi * (intensity * cos / d2)[:, None]
    np.testing.assert_allclose(got, want, rtol=1e-6)  # measured 4.4e-16
    assert stats["rays_shadow"] == xy.shape[0]  # one shadow ray per point, none occluded


def test_point_light_scales_with_throughput_and_colour():
    lights = [{"kind": LIGHT_POINT, "position": [0, 0, 1.0], "power": 10.0,
               "color": [1.0, 0.5, 0.0]}]
    got, _ = _shade(_scene(lights), [[0.0, 0.0]], throughput=[2.0, 1.0, 0.5])
    want = ALBEDO / np.pi * 10.0 / (4 * np.pi) * np.array([2.0, 0.5, 0.0])
    np.testing.assert_allclose(got[0], want, rtol=1e-6)


@pytest.mark.parametrize("cast_shadow", [True, False])
def test_occluder_between_point_and_light_gives_exactly_zero(cast_shadow):
    h = 2.0
    light = np.array([0.0, 0.0, h])
    # A 0.4 m square at half height: its shadow on the floor is the 0.8 m square
    # centred at (0.5, 0.5) (the ray to the light crosses z = h/2 at the midpoint).
    blocker = shapes.quad([0.25, 0.25, h / 2], [0.2, 0, 0], [0, 0.2, 0])
    lights = [{"kind": LIGHT_POINT, "position": light, "power": 50.0,
               "cast_shadow": cast_shadow}]
    scene = _scene(lights, [blocker])
    inside = np.array([[0.5, 0.5], [0.15, 0.15], [0.85, 0.2], [0.2, 0.85], [0.84, 0.84]])
    outside = np.array([[0.0, 0.0], [0.05, 0.5], [0.95, 0.5], [-1.0, 1.0], [1.5, 1.5]])
    got, _ = _shade(scene, np.vstack([inside, outside]))
    pos, _ = _points(np.vstack([inside, outside]))
    v = light - pos
    d2 = (v * v).sum(axis=1)
    want = ALBEDO / np.pi * (50.0 / (4 * np.pi) * v[:, 2] / np.sqrt(d2) / d2)[:, None]
    if cast_shadow:
        assert np.all(got[:5] == 0.0)
    else:
        np.testing.assert_allclose(got[:5], want[:5], rtol=1e-6)
    np.testing.assert_allclose(got[5:], want[5:], rtol=1e-6)


# --- area light -------------------------------------------------------------------------

def _corner(x, y, h):
    """Signed integral of h^2 / (x'^2 + y'^2 + h^2)^2 over [0, x] x [0, y]: the
    irradiance per unit radiance of a rectangle parallel to the floor, one corner above
    the point (the differential-area-to-rectangle form factor times pi)."""
    ax = np.sqrt(x * x + h * h)
    ay = np.sqrt(y * y + h * h)
    return 0.5 * (x / ax * np.arctan(y / ax) + y / ay * np.arctan(x / ay))


def _rect_irradiance_per_radiance(pos, centre, sx, sy):
    """Exact E / L at floor points below a downward-facing sx x sy rectangle."""
    h = centre[2] - pos[:, 2]
    x1, x2 = centre[0] - sx / 2 - pos[:, 0], centre[0] + sx / 2 - pos[:, 0]
    y1, y2 = centre[1] - sy / 2 - pos[:, 1], centre[1] + sy / 2 - pos[:, 1]
    return _corner(x2, y2, h) - _corner(x1, y2, h) - _corner(x2, y1, h) + _corner(x1, y1, h)


def _rect_estimator_std(pos, centre, sx, sy, radiance, m=400):
    """Standard deviation of one area sample's estimate L cos cos' A / r^2 (uniform on
    the rectangle), by midpoint quadrature on an m x m grid."""
    gx = centre[0] + ((np.arange(m) + 0.5) / m - 0.5) * sx
    gy = centre[1] + ((np.arange(m) + 0.5) / m - 0.5) * sy
    lx, ly = np.meshgrid(gx, gy, indexing="ij")
    out = np.empty(pos.shape[0])
    for i, p in enumerate(pos):
        h = centre[2] - p[2]
        r2 = (lx - p[0]) ** 2 + (ly - p[1]) ** 2 + h * h
        f = radiance * h * h / (r2 * r2) * sx * sy
        out[i] = np.sqrt(max(np.mean(f * f) - np.mean(f) ** 2, 0.0))
    return out


@pytest.mark.parametrize("light_samples", [16, 64])
def test_area_light_against_the_rectangle_closed_form(light_samples):
    centre, sx, sy, power = np.array([0.2, -0.1, 1.0]), 1.2, 0.6, 40.0
    radiance = power / (np.pi * sx * sy)  # one-sided Lambertian emitter
    lights = [{"kind": LIGHT_AREA, "position": centre, "power": power, "size": [sx, sy]}]
    xy = _grid(8)
    got, _ = _shade(_scene(lights), xy, light_samples=light_samples)
    pos, _ = _points(xy)
    e = radiance * _rect_irradiance_per_radiance(pos, centre, sx, sy)
    want = ALBEDO / np.pi * e[:, None]
    # Monte Carlo bound, 4 standard deviations of the mean of light_samples samples
    # (the stratified Sobol samples do better than that).
    tol = 4.0 * _rect_estimator_std(pos, centre, sx, sy, radiance) / np.sqrt(light_samples)
    err = np.abs(got - want)
    assert np.all(err <= ALBEDO / np.pi * tol[:, None] + 1e-12), (err / want).max()
    # Measured (seed 7): max relative error 2.6 % at 16 samples, 0.35 % at 64 (0.2 and
    # 0.06 of the Monte Carlo sigma: the Sobol strata converge ~ 1 / samples).
    assert (err / want).max() < (0.04 if light_samples == 16 else 0.006)


def test_small_far_area_light_acts_like_a_cosine_point_emitter():
    # A 5 cm light 3 m up: E = L A cos cos' / d^2 = (P / pi) cos cos' / d^2 to ~ (s/d)^2.
    centre, s, power = np.array([0.0, 0.0, 3.0]), 0.05, 7.0
    lights = [{"kind": LIGHT_AREA, "position": centre, "power": power, "size": [s, s]}]
    xy = np.array([[0.0, 0.0], [1.0, 0.5], [-1.5, 1.5]])
    got, _ = _shade(_scene(lights), xy, light_samples=16)
    pos, _ = _points(xy)
    v = centre - pos
    d2 = (v * v).sum(axis=1)
    cos = v[:, 2] / np.sqrt(d2)  # at the floor and at the light (both horizontal)
    e = power / np.pi * cos * cos / d2
    # The rectangle's closed form agrees (measured 9e-5): the two oracles check each other.
    exact = power / (np.pi * s * s) * _rect_irradiance_per_radiance(pos, centre, s, s)
    np.testing.assert_allclose(exact, e, rtol=2e-4)
    want = ALBEDO / np.pi * e[:, None]
    np.testing.assert_allclose(got, want, rtol=5e-4)  # measured 2.2e-4


def test_area_light_is_one_sided():
    # 1 m above the floor, emitting upwards (away from it): no light reaches the floor.
    up = np.eye(4)
    up[:3, :3] = np.diag([1.0, -1.0, -1.0])  # local -Z = world +Z
    up[:3, 3] = [0.0, 0.0, 1.0]
    lights = [{"kind": LIGHT_AREA, "to_world": up, "power": 40.0, "size": [1.0, 1.0]}]
    got, stats = _shade(_scene(lights), _grid(4), light_samples=4)
    assert np.all(got == 0.0) and stats["rays_shadow"] == 0


# --- sun --------------------------------------------------------------------------------

def _sun(strength, elevation, angle=0.0):
    """A sun whose light arrives from elevation (radians) above the +X horizon."""
    to_sun = np.array([np.cos(elevation), 0.0, np.sin(elevation)])
    m = shapes.look_at(to_sun, [0, 0, 0])  # local -Z points from the sun to the origin
    m[:3, 3] = 0.0
    return {"kind": LIGHT_SUN, "to_world": m, "power": strength, "angle": angle}, to_sun


@pytest.mark.parametrize("elevation", [np.pi / 2, np.radians(30.0), np.radians(5.0)])
def test_sun_irradiance_is_strength_times_cosine(elevation):
    sun, to_sun = _sun(3.0, elevation)
    got, _ = _shade(_scene([sun]), _grid(5))
    want = ALBEDO / np.pi * 3.0 * to_sun[2]  # E = S on a surface facing it, x cos
    np.testing.assert_allclose(got, np.broadcast_to(want, got.shape), rtol=1e-6)  # 2e-16


def test_soft_sun_keeps_the_irradiance():
    # A disc of angular radius a and radiance S / (pi sin^2 a), fully above the horizon:
    # E = L pi sin^2 a cos(theta) = S cos(theta) exactly, sampled over the cone.
    angle = 0.2
    sun, to_sun = _sun(2.0, np.radians(50.0), angle=angle)
    k = 64
    got, _ = _shade(_scene([sun]), _grid(6), light_samples=k)
    want = ALBEDO / np.pi * 2.0 * to_sun[2]
    # One sample's estimate is about S (w . n), w in the cone of half angle a about the
    # sun's axis: its spread is below S sin(theta) sin(a); 4 sigma of the mean of k samples
    # (tol 3 %).
    sigma = 2.0 * np.cos(np.radians(50.0)) * np.sin(angle / 2)
    tol = 4.0 * sigma / np.sqrt(k) / (2.0 * to_sun[2])
    np.testing.assert_allclose(got, np.broadcast_to(want, got.shape), rtol=tol)  # 6.7e-4

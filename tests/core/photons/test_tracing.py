"""Photon tracing (core/photons/tracing.py, core/photons/scatter.py): flux bookkeeping against analytic
series, the caustic of a glass sphere against an independent analytic-sphere tracer, the
projection map, skipped maps, determinism, and leaks through a thin wall."""

import numpy as np
import pytest
from scipy.integrate import trapezoid

from tests.core.maps import trace
from core.photons import store
from core.materials import bsdf, closure
from core.photons import scatter
from core.scene import shapes
from core.scene.contract import LIGHT_POINT, LIGHT_SPOT, Lights, Materials, Scene
from core.settings import RenderSettings
from core.lights.light_set import sample_direct
from core.prepared import prepare

CAM = shapes.pinhole([0, 0, 0.5], [0, 0, 0], 8, 8, 1.0)


def _settings(**kw):
    base = dict(global_photons=20_000, caustic_photons=20_000, photon_max_bounces=8, threads=2)
    base.update(kw)
    return RenderSettings().with_values(**base)


def _box_scene(albedo, power=100.0, position=(0.1, 0.2, 0.3)):
    mesh = shapes.assemble([(shapes.box([-1, -1, -1], [1, 1, 1], inward=True), 0)])
    mats = Materials.from_list([{"diffuse": [albedo] * 3}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": position, "power": power}])
    return Scene(mesh, mats, lights, CAM).validate()


def _check_finite(pm):
    for m in (pm.global_map, pm.caustic_map):
        if m is not None:
            assert np.all(np.isfinite(m.flux)) and np.all(m.flux >= 0)
            assert np.all(np.isfinite(m.positions))
            assert np.allclose(np.linalg.norm(m.directions, axis=1), 1.0, atol=1e-3)


@pytest.mark.parametrize("include_direct", [True, False])
def test_closed_box_geometric_series(include_direct):
    # Every photon stays in the closed box; at each hit a fraction a is reflected, so the
    # stored flux is phi (1 + a + a^2 + ...) with the direct hit, phi (a + a^2 + ...)
    # without; 20 bounces truncate the series at a^21 ~ 5e-7.
    a, phi = 0.5, 100.0
    pm = trace(_box_scene(a, phi), _settings(global_photons=100_000,
                                                             photon_max_bounces=20),
                               include_direct=include_direct)
    assert pm.caustic_map is None
    assert "caustic map: skipped, no mirror, glass or glossy surface" in pm.stats["decisions"]
    total = pm.global_map.flux.astype(np.float64).sum(axis=0)
    expected = phi / (1 - a) if include_direct else phi * a / (1 - a)
    np.testing.assert_allclose(total, expected, rtol=0.02)
    # Grey albedo: Russian roulette keeps every stored photon at the emitted power.
    f = pm.global_map.flux
    np.testing.assert_allclose(f, phi / pm.global_emitted, rtol=1e-3)
    _check_finite(pm)


def test_coloured_albedo_keeps_flux_bounded():
    # Roulette by the max component: a red wall scales flux by colour / max, never up.
    mesh = shapes.assemble([(shapes.box([-1, -1, -1], [1, 1, 1], inward=True), 0)])
    mats = Materials.from_list([{"diffuse": [0.6, 0.3, 0.0]}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 0), "power": 10.0}])
    scene = Scene(mesh, mats, lights, CAM).validate()
    pm = trace(scene, _settings(global_photons=50_000, photon_max_bounces=30))
    f = pm.global_map.flux.astype(np.float64)
    assert f.max() <= 10.0 / pm.global_emitted * (1 + 1e-3)
    # Per channel: phi (1 + c + c^2 + ...), c the channel's albedo.
    np.testing.assert_allclose(f.sum(axis=0), 10.0 / (1 - np.array([0.6, 0.3, 0.0])), rtol=0.03)


# --- glass sphere caustic ------------------------------------------------------------------

def _oracle_floor(light, centre, radius, ior, half_floor, n_side=400, depth=12):
    """Independent tracer: an analytic sphere lit by a point light of power 1 W, every
    interface split into Fresnel reflection and refraction (no randomness), up to
    ``depth`` interactions; returns landing points (M, 2) and their flux (M,) on the floor
    z = 0, |x|, |y| <= half_floor, for rays that leave the sphere downwards."""
    axis = centre - light
    dist = np.linalg.norm(axis)
    axis /= dist
    omc = 1 - np.sqrt(1 - (radius / dist) ** 2)
    g = (np.arange(n_side) + 0.5) / n_side
    u1, u2 = [a.ravel() for a in np.meshgrid(g, g, indexing="ij")]
    z = 1 - u1 * omc
    r = np.sqrt(np.maximum(0, 1 - z * z))
    t = np.cross(axis, [1.0, 0, 0] if abs(axis[0]) < 0.9 else [0, 1.0, 0])
    t /= np.linalg.norm(t)
    b = np.cross(axis, t)
    d = (r * np.cos(2 * np.pi * u2))[:, None] * t + (r * np.sin(2 * np.pi * u2))[:, None] * b + z[:, None] * axis
    w = np.full(d.shape[0], omc / 2 / d.shape[0])  # (Omega / 4 pi) / N of 1 W
    o = np.broadcast_to(light, d.shape).copy()
    inside = np.zeros(d.shape[0], bool)
    land_p, land_w = [], []
    for _ in range(depth):
        oc = o - centre
        bq = np.sum(oc * d, axis=1)
        c = np.sum(oc * oc, axis=1) - radius ** 2
        disc = bq * bq - c
        ok = disc >= 0
        sq = np.sqrt(np.maximum(disc, 0))
        th = np.where(inside, -bq + sq, -bq - sq)
        ok &= th > 1e-9
        o, d, w, inside, th = o[ok], d[ok], w[ok], inside[ok], th[ok]
        p = o + th[:, None] * d
        n = (p - centre) / radius
        n = np.where(inside[:, None], -n, n)  # faces the ray
        cos_i = -np.sum(d * n, axis=1)
        eta = np.where(inside, 1 / ior, ior)
        sin2_t = (1 - cos_i ** 2) / eta ** 2
        tir = sin2_t >= 1
        cos_t = np.sqrt(np.maximum(0, 1 - sin2_t))
        rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        f = np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))
        refl = d + 2 * cos_i[:, None] * n
        refr = d / eta[:, None] + (cos_i / eta - cos_t)[:, None] * n
        # Rays now outside the sphere never meet it again (convex): land them.
        out_d = np.concatenate([refl[~inside], refr[inside & ~tir]])
        out_w = np.concatenate([(w * f)[~inside], (w * (1 - f))[inside & ~tir]])
        out_p = np.concatenate([p[~inside], p[inside & ~tir]])
        down = out_d[:, 2] < 0
        tt = -out_p[down, 2] / out_d[down, 2]
        xy = out_p[down, :2] + tt[:, None] * out_d[down, :2]
        on = np.all(np.abs(xy) <= half_floor, axis=1)
        land_p.append(xy[on])
        land_w.append(out_w[down][on])
        # Rays inside continue: refracted entering rays and internal reflections.
        o = np.concatenate([p[~inside], p[inside]])
        d = np.concatenate([refr[~inside], refl[inside]])
        w = np.concatenate([(w * (1 - f))[~inside], (w * f)[inside]])
        keep = w > 0
        o, d, w = o[keep], d[keep], w[keep]
        inside = np.ones(o.shape[0], bool)
    return np.concatenate(land_p), np.concatenate(land_w)


def _weighted_quantile(x, w, q):
    order = np.argsort(x)
    return x[order][np.searchsorted(np.cumsum(w[order]), q * w.sum())]


def _glass_scene(light_z=4.0, radius=0.5, centre_z=1.0, half_floor=20.0, power=1000.0):
    c = np.array([0, 0, centre_z])
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [half_floor, 0, 0], [0, half_floor, 0]), 0),
                            (shapes.uv_sphere(c, radius, 48, 96), 1)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, light_z], "power": power}])
    return Scene(mesh, mats, lights, CAM).validate()


def test_glass_sphere_caustic_matches_analytic_sphere():
    power = 1000.0
    scene = _glass_scene(power=power)
    pm = trace(scene, _settings(global_photons=1000, caustic_photons=100_000))
    _check_finite(pm)
    cm = pm.caustic_map
    flux = cm.flux.astype(np.float64)[:, 0]
    pos = cm.positions.astype(np.float64)
    assert np.all(np.abs(pos[:, 2]) < 1e-3)  # only the floor is diffuse
    o_xy, o_w = _oracle_floor(np.array([0, 0, 4.0]), np.array([0, 0, 1.0]), 0.5, 1.5, 20.0)
    o_w = o_w * power
    # The intercepted flux times what leaves downwards: < intercepted (Fresnel losses,
    # light reflected upwards), and the photon caustic within 3% of the oracle (the issue
    # asks for 10%; measured 0.2%: 100k photons and a 48 x 96 tessellation).
    d = 3.0
    intercepted = power / (4 * np.pi) * 2 * np.pi * (1 - np.sqrt(1 - 0.25 / d ** 2))
    assert 0.7 * intercepted < o_w.sum() < intercepted
    assert flux.sum() == pytest.approx(o_w.sum(), rel=0.03)
    # Where it lands: the focus under the sphere holds the same share of the flux.
    o_r = np.hypot(o_xy[:, 0], o_xy[:, 1])
    r = np.hypot(pos[:, 0], pos[:, 1])
    for q in (0.5, 0.8, 0.95):
        rq = _weighted_quantile(o_r, o_w, q)
        share = flux[r <= rq].sum() / flux.sum()
        assert share == pytest.approx(q, abs=0.03), (q, rq)
    # The focus region: every photon that went through the sphere (not reflected off
    # it) lands within the sphere's shadow on the floor, radius < 0.5 * 4 / 3 at most.
    r_focus = _weighted_quantile(o_r, o_w, 0.5)
    assert r_focus < 0.5


def _floor_irradiance(pm, edges):
    """Irradiance (W/m^2, red channel) of the global map's photons on the floor z = 0 in
    the annuli about the z axis between ``edges`` (metres)."""
    p = pm.global_map.positions.astype(np.float64)
    f = pm.global_map.flux.astype(np.float64)[:, 0]
    on = np.abs(p[:, 2]) < 1e-4
    rho = np.hypot(p[on, 0], p[on, 1])
    return np.array([f[on][(rho >= a) & (rho < b)].sum() / (np.pi * (b * b - a * a))
                     for a, b in zip(edges[:-1], edges[1:])])


@pytest.mark.parametrize("soft", [True, False])
@pytest.mark.parametrize("height", [1.0, 2.0, 5.0])
def test_soft_falloff_photons_light_a_plane_as_the_facing_disk(height, soft):
    """A point light of radius r = 1 m, height D above a floor: with Soft Falloff Cycles'
    (and the shadow rays') light is a disk of radiance L = S / (4 pi^2 r^2) facing each
    floor point X at distance d from the centre; it fills a cone of half angle
    atan(r / d) about X's axis, which makes an angle alpha (cos alpha = D / d) with the
    floor's normal, so E = L pi sin^2(atan(r / d)) cos alpha = S D / (4 pi d (r^2 + d^2))
    while the cone stays above the horizon. Without it the light is a sphere: the cone's
    half angle is asin(r / d), E = S D / (4 pi d^3), the point light's. The facing disk's
    field is 1.95 times darker at d = r: photons emitted as from a sphere fail."""
    r, power = 1.0, 100.0
    half = 3.0 * height
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [half, 0, 0], [0, half, 0]), 0)])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, height], "power": power,
                                "radius": r, "soft_falloff": soft}])
    scene = Scene(mesh, Materials.from_list([{"diffuse": [0.5] * 3}]), lights,
                  shapes.pinhole([0, 0, height + 3], [0, 0, 0], 8, 8, 1.0)).validate()
    pm = trace(scene, _settings(global_photons=400_000, caustic_photons=0,
                                photon_max_bounces=1), include_direct=True)
    edges = height * np.array([0.0, 0.5, 1.0])
    got = _floor_irradiance(pm, edges)
    expected = []
    for a, b in zip(edges[:-1], edges[1:]):
        x = np.linspace(a, b, 4001)
        d = np.hypot(height, x)
        e = power * height / (4 * np.pi * d * ((r * r + d * d) if soft else d * d))
        expected.append(trapezoid(e * x, x) * 2 / (b * b - a * a))
        assert np.arctan(r / d[-1]) + np.arccos(height / d[-1]) <= np.pi / 2
    print(f"\nsoft {soft}, D = {height} m: photons / disk {np.round(got / expected, 4)}")
    # ~10k photons per annulus (1 % noise); measured within 1.5 %.
    np.testing.assert_allclose(got, expected, rtol=0.03)


@pytest.mark.parametrize("kind", [LIGHT_POINT, LIGHT_SPOT])
def test_soft_falloff_photons_see_the_disk_past_an_occluder(kind):
    """An opaque square (half side 0.5 m) 0.8 m under a soft-falloff light of radius 1 m,
    2 m above a floor, hides the light's centre from the floor within ~1.25 m of the axis
    while the rim of the disk facing each point shows around it. The photons' irradiance
    there must be the shadow rays' (an independent estimate: uniform floor points, one
    light sample each through ``lights.sample_direct``, occlusion by Embree): photons
    from the centre, reweighted at their first event, left it dark."""
    r, power, height = 1.0, 100.0, 2.0
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [4, 0, 0], [0, 4, 0]), 0),
                            (shapes.quad([0, 0, 1.2], [0.5, 0, 0], [0, 0.5, 0]), 1)])
    mats = Materials.from_list([{"diffuse": [0.5] * 3}, {"diffuse": [0.0] * 3}])
    light = {"kind": kind, "power": power, "radius": r}
    if kind == LIGHT_SPOT:
        light.update(to_world=shapes.look_at([0, 0, height], [0, 0, 0], (0, 1, 0)),
                     spot_size=np.radians(50), spot_blend=0.2)
    else:
        light["position"] = [0, 0, height]
    scene = Scene(mesh, mats, Lights.from_list([light]),
                  shapes.pinhole([0, 0, 5], [0, 0, 0], 8, 8, 1.0)).validate()
    pm = trace(scene, _settings(global_photons=1_000_000, caustic_photons=0,
                                photon_max_bounces=1), include_direct=True)
    edges = np.array([0.0, 0.4, 0.8, 1.2, 2.0])
    got = _floor_irradiance(pm, edges)
    rng = np.random.default_rng(7)
    n = 200_000
    expected = []
    with prepare(scene, 2) as prepared:
        for a, b in zip(edges[:-1], edges[1:]):
            rho, phi = np.sqrt(rng.uniform(a * a, b * b, n)), rng.uniform(0, 2 * np.pi, n)
            x = np.stack([rho * np.cos(phi), rho * np.sin(phi), np.zeros(n)], axis=1)
            s = sample_direct(prepared.light_set, 0, x, rng.random(n), rng.random(n))
            blocked = prepared.accel.occluded((x + [0, 0, 1e-5]).astype(np.float32),
                                              s.direction.astype(np.float32),
                                              (s.distance * (1 - 1e-6)).astype(np.float32))
            expected.append(np.where(s.valid & ~blocked,
                                     s.weight[:, 0] * s.direction[:, 2], 0.0).mean())
    expected = np.array(expected)
    open_field = power / (4 * np.pi * (r * r + height * height))  # at the axis, no occluder
    assert expected[0] < 0.2 * open_field and expected[0] > 0.05 * open_field
    print(f"\nphotons / shadow rays {np.round(got / expected, 4)}")
    # Measured: spot within 1.4 %; point light 0.986 to 1.047, its inner annulus holding
    # ~1.4k photons (2.7 % noise).
    np.testing.assert_allclose(got, expected, rtol=0.1 if kind == LIGHT_POINT else 0.04)
    np.testing.assert_allclose(got[1:], expected[1:], rtol=0.04)


def test_glass_never_adds_flux_to_a_channel():
    """A red light through clear glass (tint 1): green and blue stay zero (nothing may leak
    into them), and the flux stays within the sampler's bounds: photons scatter by the
    camera paths' sampler, which picks reflection with probability clamp(F, 1/8, 7/8), so a
    refraction weighs (1 - F) / p <= 8/7 (Russian roulette brings weights below 1 back to
    1): a caustic photon crossing up to 4 interfaces keeps at most (8/7)^4 of the smallest
    flux. The geometric-normal fallback's leak of a Fresnel factor into the blue flux was
    caught by test_integrator's scale tests."""
    # A coarse sphere with smooth normals: shading and geometric normals disagree a lot,
    # so the geometric-normal fallbacks of the dielectric (and their TIR) are exercised.
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [20, 0, 0], [0, 20, 0]), 0),
                            (shapes.uv_sphere(np.array([0, 0, 1.0]), 0.5, 6, 12), 1)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 4.0], "power": 1000.0,
                                "color": [1.0, 0.0, 0.0]}])
    scene = Scene(mesh, mats, lights, CAM).validate()
    pm = trace(scene, _settings(global_photons=1000, caustic_photons=50_000))
    flux = pm.caustic_map.flux
    assert len(flux) > 1000
    assert np.all(flux[:, 1:] == 0.0)
    assert flux[:, 0].max() <= flux[:, 0].min() * (8 / 7) ** 4


def test_caustic_map_only_from_specular_first_hits():
    # A diffuse cube next to the glass sphere: photons that hit it first never enter the
    # caustic map, whatever they do next.
    scene = _glass_scene()
    pm = trace(scene, _settings(projection_map=False, global_photons=1000,
                                                caustic_photons=20_000))
    assert pm.caustic_map is not None
    assert pm.stats["caustic_emitted"] == 20_000
    assert any("photons emitted unaimed (projection map off)" in s for s in pm.stats["decisions"])


def _room_scene(size, sphere_r=0.05):
    """A closed diffuse room of side ``size`` with a glass sphere of radius sphere_r
    resting 0.1 m above the floor, lit from the ceiling's centre."""
    h = size / 2
    c = np.array([0, 0, 0.1 + sphere_r])
    mesh = shapes.assemble([(shapes.box([-h, -h, 0], [h, h, size], inward=True), 0),
                            (shapes.uv_sphere(c, sphere_r, 24, 48), 1)])
    mats = Materials.from_list([{"diffuse": [0.5] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 0.95 * size],
                                "power": 100.0}])
    return Scene(mesh, mats, lights, CAM).validate()


def _focus_count(pm, radius=0.2):
    """Caustic photons on the floor within ``radius`` of the point under the sphere: the
    light that went through the 5 cm sphere converges below it and lands well inside
    4 sphere radii for both rooms (the oracle test above checks where caustics land)."""
    p = pm.caustic_map.positions if pm.caustic_map is not None else np.zeros((0, 3))
    return int(np.sum((np.hypot(p[:, 0], p[:, 1]) < radius) & (p[:, 2] < 1e-3)))


def test_projection_map_keeps_small_caustics_dense():
    n = 20_000
    counts = {}
    for size in (1.0, 10.0):
        for proj in (True, False):
            pm = trace(_room_scene(size), _settings(
                global_photons=1000, caustic_photons=n, projection_map=proj))
            counts[size, proj] = _focus_count(pm)
    # Aimed: every caustic photon heads for the sphere, so the focus holds the same count
    # (most of n: Fresnel reflection loses ~10%) whatever the room; 5 sigma + 2% for
    # the different light distance (0.8 m vs 9.4 m).
    on1, on10 = counts[1.0, True], counts[10.0, True]
    assert on1 > 0.7 * n
    assert abs(on10 - on1) < 5 * np.sqrt(on1) + 0.02 * on1
    # Unaimed: the sphere subtends (0.05 / 0.8)^2 / 4 ~ 1/1000 of the directions in the
    # 1 m room, 100 times less in the 10 m one.
    assert counts[1.0, False] < 0.01 * n
    assert counts[10.0, False] < 0.001 * on10


def test_no_caustic_map_without_specular_and_no_global_when_off():
    pm = trace(_box_scene(0.5), _settings(indirect_mode="off"))
    assert pm.global_map is None and pm.caustic_map is None
    assert "global map: skipped, indirect light is off" in pm.stats["decisions"]
    assert "caustic map: skipped, no mirror, glass or glossy surface" in pm.stats["decisions"]
    assert pm.global_emitted == 0 and pm.caustic_emitted == 0


def test_no_global_map_when_nothing_diffuse():
    mesh = shapes.assemble([(shapes.box([-1, -1, -1], [1, 1, 1], inward=True), 0)])
    mats = Materials.from_list([{"specular": [0.9] * 3}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 0), "power": 10.0}])
    pm = trace(Scene(mesh, mats, lights, CAM).validate(), _settings())
    assert pm.global_map is None and pm.caustic_map is None
    assert any("global map: skipped, no surface has a diffuse lobe" in s
               for s in pm.stats["decisions"])


def test_deterministic_across_runs_and_threads():
    scene = _glass_scene(half_floor=3.0)
    maps = [trace(scene, _settings(threads=t, global_photons=5000,
                                                   caustic_photons=5000)) for t in (1, 2, 2)]
    for m in maps[1:]:
        for a, b in ((maps[0].global_map, m.global_map), (maps[0].caustic_map, m.caustic_map)):
            assert len(a) == len(b)
            assert np.array_equal(a.positions, b.positions)
            assert np.array_equal(a.flux, b.flux)
            assert np.array_equal(a.directions, b.directions)
    other = trace(scene, _settings(seed=1, global_photons=5000,
                                                   caustic_photons=5000))
    assert not np.array_equal(other.global_map.positions[:100], maps[0].global_map.positions[:100])


def test_thin_wall_blocks_photons():
    # A closed room split by a 1 mm wall at x = 0; the light is on the left: nothing may
    # be stored on the right.
    mesh = shapes.assemble([(shapes.box([-1, -1, -1], [1, 1, 1], inward=True), 0),
                            (shapes.box([0.0, -1.0, -1.0], [0.001, 1.0, 1.0]), 0)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (-0.5, 0.3, 0.2), "power": 10.0}])
    pm = trace(Scene(mesh, mats, lights, CAM).validate(),
                               _settings(global_photons=50_000, photon_max_bounces=10))
    p = pm.global_map.positions
    assert len(p) > 50_000
    assert np.all(p[:, 0] <= 1e-6)


def test_mirror_and_glossy_paths_reach_the_caustic_map():
    # A mirror above a diffuse floor reflects a point light's photons down (L S D), and
    # so does a rough glossy one; the flux that reaches the floor via the mirror is the
    # flux that hits the mirror times its tint (the mirror's far side faces away).
    for rough in (0.0, 0.3):
        mesh = shapes.assemble([(shapes.quad([0, 0, 0], [50, 0, 0], [0, 50, 0]), 0),
                                (shapes.quad([0, 0, 2], [0.5, 0, 0], [0, -0.5, 0]), 1)])
        mats = Materials.from_list([{"diffuse": [0.5] * 3},
                                    {"specular": [0.8] * 3, "roughness": rough}])
        lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 1), "power": 100.0}])
        scene = Scene(mesh, mats, lights, CAM).validate()
        pm = trace(scene, _settings(global_photons=1000, caustic_photons=40_000))
        _check_finite(pm)
        total = pm.caustic_map.flux.astype(np.float64)[:, 0].sum()
        # Solid angle of the 1 m square at 1 m: 4 asin(1/ (1 + 4)) ... of a square of
        # half side s at distance h: 4 asin(s^2 / (s^2 + h^2)).
        omega = 4 * np.arcsin(0.25 / 1.25)
        hit = 100.0 / (4 * np.pi) * omega
        if rough == 0.0:
            assert total == pytest.approx(0.8 * hit, rel=0.02)
        else:
            # GGX loses a little to shadowing and to directions that miss the floor's
            # edge; never more than the mirror.
            assert 0.6 * hit < total < 0.8 * hit * 1.01


def test_projection_map_is_unbiased_for_an_area_light():
    # The aimed caustic flux equals the unaimed one (which needs no weights at all)
    # within the unaimed estimate's noise: the aiming weights are right end to end.
    c = np.array([0.3, 0.1, 0.6])
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [5, 0, 0], [0, 5, 0]), 0),
                            (shapes.uv_sphere(c, 0.4, 24, 48), 1)])
    mats = Materials.from_list([{"diffuse": [0.8] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": 3, "position": [0, 0, 2.0], "power": 100.0,
                                "size": [0.8, 0.5]}])
    scene = Scene(mesh, mats, lights, CAM).validate()
    totals, counts = {}, {}
    for proj in (True, False):
        pm = trace(scene, _settings(global_photons=1000, caustic_photons=100_000,
                                                    projection_map=proj))
        _check_finite(pm)
        totals[proj] = pm.caustic_map.flux.astype(np.float64)[:, 0].sum()
        counts[proj] = len(pm.caustic_map)
    assert counts[True] > 4 * counts[False]
    sigma = 1.0 / np.sqrt(counts[False])
    assert totals[True] == pytest.approx(totals[False], rel=4 * sigma + 0.005)


def test_spot_aimed_away_costs_nothing():
    away = shapes.look_at([0, 0, 0.5], [0, 0, 5])   # inside the box, pointing at the ceiling
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    mats = Materials.from_list([{"diffuse": [0.5] * 3}])
    lights = Lights.from_list([
        {"kind": 1, "to_world": away, "power": 100.0, "spot_size": 0.6, "name": "Away"},
        {"kind": LIGHT_POINT, "position": (0, 0, 1), "power": 10.0, "name": "Bulb"}])
    pm = trace(Scene(mesh, mats, lights, CAM).validate(), _settings())
    assert pm.stats["sources"] == ["Bulb"]
    assert any("'Away': no photons" in s for s in pm.stats["decisions"])
    # All the photons go to the bulb: the floor gets what a 10 W point light sends down.
    total = pm.global_map.flux.astype(np.float64)[:, 0].sum()
    omega = 4 * np.arcsin(1 / 2)  # the 2 m square seen from 1 m above its centre
    assert total == pytest.approx(10.0 / (4 * np.pi) * omega, rel=0.02)


def test_emissive_triangles_do_not_stop_their_own_photons():
    # Black walls store nothing; the only diffuse surface is the emitting panel, which
    # cannot light itself: any stored photon would be a photon stopped by its own
    # triangle at its origin.
    mesh = shapes.assemble([(shapes.box([-1, -1, -1], [1, 1, 1], inward=True), 0),
                            (shapes.quad([0.1, 0.2, 0.3], [0.3, 0.1, 0], [0, 0.2, 0.1]), 1)])
    mats = Materials.from_list([{"diffuse": [0.0] * 3},
                                {"diffuse": [0.5] * 3, "emission": [5.0, 5.0, 5.0]}])
    scene = Scene(mesh, mats, Lights.empty(), CAM).validate()
    pm = trace(scene, _settings(global_photons=50_000, photon_max_bounces=1))
    assert pm.stats["global_emitted"] == 50_000
    assert pm.global_map is None
    assert "global map: empty, no photon was stored" in pm.stats["decisions"]


# --- the scatter kernel's lobes against the BSDF ----------------------------------------------

def _lobes(m, rows):
    """The scatter kernel's material inputs: the ClosureTable, has_diffuse, has_specular."""
    spec = np.any(m["specular"] > 0, axis=1) | np.any(m["transmission"] > 0, axis=1)
    return closure.table(Materials.from_list(rows)), np.any(m["diffuse"] > 0, axis=1), spec


def _scatter_once(material, theta, n=200_000):
    """Send n photons of flux 1 at angle theta onto one triangle in z = 0 (normal +Z) and
    return (alive, new directions, new flux) of the scatter kernel's bounce."""
    tri_v = np.array([[[-10, -10, 0], [10, -10, 0], [0, 10, 0]]], np.float32)
    tri_n = np.array([[[0, 0, 1]] * 3], np.float32)
    material_rows = [material]
    m = bsdf.material_table(Materials.from_list(material_rows))
    d = np.tile(np.array([np.sin(theta), 0.0, -np.cos(theta)], np.float32), (n, 1))
    out = [np.zeros(n, bool), np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32),
           np.zeros((n, 3), np.float32), np.zeros(n, bool), np.zeros((n, 3), np.float32),
           np.zeros((n, 3), np.float32), np.zeros((n, 3))]
    scatter.scatter_kernel(tri_v, tri_n, np.zeros(1, np.int32), 20.0, *_lobes(m, material_rows),
                           np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros((0, 3)),
                           np.zeros((0, 3)), np.zeros(0),
                           np.zeros(n, np.int32),
                           np.full(n, 0.3, np.float32), np.full(n, 0.3, np.float32), d,
                           np.ones((n, 3)), np.arange(n, dtype=np.int64), np.zeros(n, np.int32),
                           np.zeros(n, np.int32), np.zeros(n), np.int64(5),
                           np.arange(5, dtype=np.int64),
                           np.int64(0), store.MODE_GLOBAL, store.STORE_ALL, False, *out)
    alive, d_new, f_new = out[4], out[6].astype(np.float64), out[7]
    return alive, d_new, np.where(alive[:, None], f_new, 0.0)


def test_glossy_lobe_reflects_the_ggx_albedo():
    # The flux leaving a rough glossy surface, in total and per band of outgoing angle,
    # equals the integral of the GGX BRDF (bsdf.ggx_brdf, evaluated, not sampled) x cos.
    from core.materials import bsdf
    theta, rough = np.radians(40), 0.5
    alive, d_new, f = _scatter_once({"specular": [1, 1, 1], "roughness": rough}, theta)
    # Quadrature of f cos over the hemisphere (midpoint in cos(theta_i) and phi).
    nc, nphi = 800, 400
    ci = (np.arange(nc) + 0.5) / nc
    phi = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    c, p = np.meshgrid(ci, phi, indexing="ij")
    s = np.sqrt(1 - c * c)
    wi = np.stack([s * np.cos(p), s * np.sin(p), c], axis=-1).reshape(-1, 3)
    wo = np.tile([-np.sin(theta), 0.0, np.cos(theta)], (wi.shape[0], 1))
    nrm = np.tile([0.0, 0.0, 1.0], (wi.shape[0], 1))
    fc = (bsdf.ggx_brdf(rough ** 2, nrm, wo, wi) * wi[:, 2]).reshape(nc, nphi)
    band = fc.sum(axis=1) * (1.0 / nc) * (2 * np.pi / nphi)   # flux per cos band
    assert f[:, 0].mean() == pytest.approx(band.sum(), rel=0.01)
    assert 0.8 < band.sum() < 1.0  # shadowing loses some, never gains
    edges = np.linspace(0, 1, 11)
    got = np.histogram(d_new[alive, 2], bins=edges, weights=f[alive, 0])[0] / f.shape[0]
    want = band.reshape(10, -1).sum(axis=1)
    big = want > 0.01
    np.testing.assert_allclose(got[big], want[big], rtol=0.05)


def _fresnel(cos_i, eta):
    # Textbook unpolarised Fresnel (independent of bsdf.fresnel_dielectric).
    sin_t = np.sqrt(1 - cos_i ** 2) / eta
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (cos_t - eta * cos_i) / (cos_t + eta * cos_i)
    return 0.5 * (rs ** 2 + rp ** 2)


@pytest.mark.parametrize("theta_deg", [0.0, 60.0, 85.0])
def test_dielectric_splits_by_fresnel_and_refracts_by_snell(theta_deg):
    theta = np.radians(theta_deg)
    alive, d_new, f = _scatter_once({"transmission": [1, 1, 1], "ior": 1.5}, theta)
    # The camera paths' sampler picks reflection with probability p = clamp(F, 1/8, 7/8)
    # and weighs F / p or (1 - F) / (1 - p); Russian roulette on that weight keeps a
    # reflected photon with probability F / p at flux 1. So the flux splits by Fresnel:
    # F reflected, 1 - F refracted, and no photon carries more than 8/7.
    n = alive.size
    fr = _fresnel(np.cos(theta), 1.5)
    up = alive & (d_new[:, 2] > 0)
    down = alive & (d_new[:, 2] < 0)
    assert np.all(f[alive] <= 8 / 7 + 1e-6) and np.allclose(f[up], 1.0)
    assert up.sum() + down.sum() == alive.sum()
    sigma = np.sqrt(fr * (1 - fr) / n) * 8 / 7
    assert f[up, 0].sum() / n == pytest.approx(fr, abs=4 * sigma + 1e-4)
    assert f[down, 0].sum() / n == pytest.approx(1 - fr, abs=4 * sigma + 1e-4)
    d_new = d_new[alive]
    up = d_new[:, 2] > 0
    # Reflected: mirror direction; refracted: Snell's law, in the plane of incidence.
    assert np.allclose(d_new[up], [np.sin(theta), 0, np.cos(theta)], rtol=0, atol=1e-6)
    sin_t = np.hypot(d_new[~up, 0], d_new[~up, 1])
    np.testing.assert_allclose(sin_t, np.sin(theta) / 1.5, atol=1e-6)
    np.testing.assert_allclose(d_new[~up, 1], 0.0, atol=1e-6)


def test_lambert_bounce_is_cosine_distributed_with_the_albedo():
    alive, d_new, f = _scatter_once({"diffuse": [0.6, 0.3, 0.15]}, np.radians(30))
    # Roulette by the max component (0.6): survivors carry colour / 0.6.
    assert alive.mean() == pytest.approx(0.6, abs=0.005)
    assert np.allclose(f[alive], [1.0, 0.5, 0.25], rtol=1e-6, atol=0)  # float32 tints
    cz = d_new[alive, 2]
    assert np.all(cz > 0)
    assert cz.mean() == pytest.approx(2 / 3, abs=0.003)
    assert np.mean(cz ** 2) == pytest.approx(0.5, abs=0.003)  # E[cos^2] under cos/pi


@pytest.mark.parametrize("rule, stored_for", [
    (store.STORE_ALL, {(0, 0), (0, 1), (1, 0), (2, 3)}),
    (store.STORE_BOUNCED, {(1, 0), (2, 3)}),
    (store.STORE_NOT_DIRECT, {(0, 1), (1, 0), (2, 3)}),   # all but light -> diffuse
])
def test_global_store_rules_by_path(rule, stored_for):
    """Which photons the global map stores at a diffuse plane, by the (diffuse, specular)
    bounces they made before it."""
    paths = [(0, 0), (0, 1), (1, 0), (2, 3)]
    n = len(paths)
    tri_v = np.array([[[-10, -10, 0], [10, -10, 0], [0, 10, 0]]], np.float32)
    tri_n = np.array([[[0, 0, 1]] * 3], np.float32)
    material_rows = [{"diffuse": [0.5] * 3}]
    m = bsdf.material_table(Materials.from_list(material_rows))
    d = np.tile(np.array([0.0, 0.0, -1.0], np.float32), (n, 1))
    out = [np.zeros(n, bool), np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32),
           np.zeros((n, 3), np.float32), np.zeros(n, bool), np.zeros((n, 3), np.float32),
           np.zeros((n, 3), np.float32), np.zeros((n, 3))]
    n_diff = np.array([p[0] for p in paths], np.int32)
    n_spec = np.array([p[1] for p in paths], np.int32)
    scatter.scatter_kernel(tri_v, tri_n, np.zeros(1, np.int32), 20.0, *_lobes(m, material_rows),
                           np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros((0, 3)),
                           np.zeros((0, 3)), np.zeros(0),
                           np.zeros(n, np.int32), np.full(n, 0.3, np.float32),
                           np.full(n, 0.3, np.float32), d, np.ones((n, 3)),
                           np.arange(n, dtype=np.int64), n_diff, n_spec, np.zeros(n), np.int64(5),
                           np.arange(5, dtype=np.int64), np.int64(0), store.MODE_GLOBAL,
                           np.int64(rule), False, *out)
    assert {p for p, s in zip(paths, out[0]) if s} == stored_for

"""Photon emission (core/photons/emission.py): the flux of every light kind sums to its power in
Blender's units, directions follow the emission profile, the sun's disc covers the scene,
aimed emission (projection map) carries the flux that the unaimed emission sends into the
same spheres, and lights that cannot contribute get no photons."""

import numpy as np
import pytest

from core.color import luminance
from core.photons import emission
from core.scene.bounds import Targets
from core.scene import shapes
from core.lights import kernels as lk
from core.lights.light_set import EmissiveTriangles, LightSet
from core.scene.contract import (AREA_ELLIPSE, LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, Lights,
                        Materials)

N = 1 << 15
CENTRE = np.array([0.0, 0.0, 0.0])
NO_TRIS = EmissiveTriangles.from_mesh(shapes.assemble([]), Materials.from_list([]))


def _emit(lights, i=0, n=N, seed=0, targets=None, probs=None, radius=2.0, tris=NO_TRIS,
          world=np.zeros(3), index=None):
    ls = LightSet.from_lights(lights)
    src = emission.Source(i if index is None else index, np.zeros(3), "x")
    return emission.emit(src, ls, tris, world, CENTRE, radius, n, 0, n, seed=seed, map_id=0,
                         source_slot=0, targets=targets, target_prob=probs), ls


def _light(**kw):
    kw.setdefault("position", (0.0, 0.0, 0.0))
    return Lights.from_list([kw])


def _powers(lights, tris=NO_TRIS, world=np.zeros(3), radius=2.0, spheres=None):
    ls = LightSet.from_lights(lights)
    return emission.source_powers(ls, tris, world, CENTRE, radius, spheres, True)


@pytest.mark.parametrize("radius,soft", [(0.0, True), (0.3, True), (0.3, False)])
def test_point_light_flux_and_isotropy(radius, soft):
    li = _light(kind=LIGHT_POINT, power=50.0, color=(1.0, 0.5, 0.25), radius=radius,
                soft_falloff=soft)
    em, _ = _emit(li)
    np.testing.assert_allclose(em.flux.sum(axis=0), 50.0 * np.array([1.0, 0.5, 0.25]), rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(em.direction, axis=1), 1.0, atol=1e-12)
    # Uniform over the sphere: mean direction ~ 0 (stratified: much better than 1/sqrt(N)).
    assert np.all(np.abs(em.direction.mean(axis=0)) < 0.01)
    off = np.linalg.norm(em.origin, axis=1)
    assert np.all(off <= radius * (1 + 1e-6))
    if radius > 0 and not soft:
        # Lambertian sphere: origins on the surface, leaving outwards with cos-weighted
        # angles to the normal (mean cos 2/3).
        np.testing.assert_allclose(off, radius, rtol=1e-6)
        cos = np.sum(em.origin / radius * em.direction, axis=1)
        assert np.all(cos >= -1e-12)
        assert cos.mean() == pytest.approx(2 / 3, abs=0.01)


def _spot_flux_oracle(power, size, blend):
    """S / (4 pi) x integral of Cycles' falloff over the sphere, by the midpoint rule."""
    ls = LightSet.from_lights(_light(kind=LIGHT_SPOT, power=power, spot_size=size,
                                     spot_blend=blend))
    m = 200_000
    c = -1 + (np.arange(m) + 0.5) * (2.0 / m)
    att = np.array([lk.spot_attenuation(x, ls.spot_cos_half[0], ls.spot_smooth[0]) for x in c[c > 0.3]])
    return power / (4 * np.pi) * 2 * np.pi * att.sum() * (2.0 / m)


@pytest.mark.parametrize("size,blend", [(np.pi / 4, 0.15), (1.2, 1.0), (0.5, 0.0), (2.5, 0.4)])
def test_spot_flux_is_the_falloff_integral(size, blend):
    li = _light(kind=LIGHT_SPOT, power=80.0, spot_size=size, spot_blend=blend)
    em, ls = _emit(li)
    expected = _spot_flux_oracle(80.0, size, blend)
    assert em.flux[:, 0].sum() == pytest.approx(expected, rel=0.01)
    (src,) = _powers(li)
    assert src.power[0] == pytest.approx(expected, rel=1e-3)
    # Directions inside the cone about -Z (Blender's default: pointing down).
    cos = -em.direction[:, 2]
    assert np.all(cos >= np.cos(size / 2) - 1e-12)


@pytest.mark.parametrize("angle_deg", [0.0, 10.0])
def test_sun_flux_and_disc_covers_the_bounds(angle_deg):
    angle = np.radians(angle_deg)
    axis = np.array([0.3, -0.2, 1.0])
    axis /= np.linalg.norm(axis)
    m = shapes.look_at(axis * 5, [0, 0, 0])
    li = Lights.from_list([{"kind": LIGHT_SUN, "to_world": m, "power": 3.0, "angle": angle}])
    r_scene = 2.0
    em, ls = _emit(li, radius=r_scene)
    az = ls.axis_z[0]
    # Every direction of the cone sees the sphere's cross-section pi R^2 with the sun's
    # radiance L = S / (pi sin^2 h) over the cone: S pi R^2 x 2 pi (1 - cos h) / (pi sin^2 h).
    h = angle / 2
    per_area = 3.0 if angle == 0 else 3.0 * 2 * (1 - np.cos(h)) / np.sin(h) ** 2
    assert em.flux[:, 0].sum() == pytest.approx(per_area * np.pi * r_scene ** 2, rel=0.005)
    (src,) = _powers(li, radius=r_scene)
    assert src.power[0] == pytest.approx(per_area * np.pi * r_scene ** 2, rel=1e-6)
    cos = -em.direction @ az
    assert np.all(cos >= np.cos(h) - 1e-12)
    # Origins outside the scene's sphere on the sun's side (nothing between them and the
    # sun), each ray crossing the sphere's disc, and the rays filling that disc.
    assert np.all(em.origin @ az > r_scene)
    along = np.sum(em.origin * em.direction, axis=1)
    perp = np.linalg.norm(em.origin - along[:, None] * em.direction, axis=1)
    assert np.all(perp <= r_scene * (1 + 1e-9))
    assert perp.max() == pytest.approx(r_scene, rel=0.01)
    assert np.mean(perp < r_scene / 2) == pytest.approx(0.25, abs=0.01)


@pytest.mark.parametrize("shape", [0, AREA_ELLIPSE])
def test_area_light_flux_and_cosine(shape):
    m = shapes.look_at([0, 0, 2], [1, 0, 0])
    li = Lights.from_list([{"kind": LIGHT_AREA, "to_world": m, "power": 40.0, "shape": shape,
                            "size": (0.5, 0.2), "color": (0.2, 0.4, 1.0)}])
    em, ls = _emit(li)
    np.testing.assert_allclose(em.flux.sum(axis=0), 40.0 * np.array([0.2, 0.4, 1.0]), rtol=1e-6)
    cos = -em.direction @ ls.axis_z[0]
    assert np.all(cos > 0)
    assert cos.mean() == pytest.approx(2 / 3, abs=0.003)
    # Positions on the light: in its plane, inside the rectangle / ellipse.
    rel = em.origin - ls.position[0]
    assert np.allclose(rel @ ls.axis_z[0], 0, atol=1e-12)
    x, y = rel @ ls.axis_x[0], rel @ ls.axis_y[0]
    if shape == AREA_ELLIPSE:
        assert np.all((x / 0.25) ** 2 + (y / 0.1) ** 2 <= 1 + 1e-9)
    else:
        assert np.all((np.abs(x) <= 0.25 + 1e-12) & (np.abs(y) <= 0.1 + 1e-12))


def test_emissive_triangles_two_sided_flux():
    part = shapes.quad([0, 0, 1], [0.5, 0, 0], [0, 0.25, 0])
    part2 = shapes.quad([2, 0, 0], [0, 0.1, 0], [0, 0, 0.1])
    mesh = shapes.assemble([(part, 0), (part2, 1)])
    mats = Materials.from_list([{"emission": [2.0, 1.0, 0.5]}, {"emission": [0.0, 3.0, 0.0]}])
    tris = EmissiveTriangles.from_mesh(mesh, mats)
    em, _ = _emit(Lights.empty(), tris=tris, index=emission.SOURCE_TRIANGLES)
    # pi L A per side, two sides.
    expected = 2 * np.pi * (np.array([2.0, 1.0, 0.5]) * 0.5 + np.array([0, 3.0, 0]) * 0.04)
    np.testing.assert_allclose(em.flux.sum(axis=0), expected, rtol=0.01)
    np.testing.assert_allclose(tris.power, expected, rtol=1e-6)
    up = em.origin[:, 2] > 0.5
    cz = em.direction[up, 2]
    assert np.mean(cz > 0) == pytest.approx(0.5, abs=0.02)
    assert np.abs(cz).mean() == pytest.approx(2 / 3, abs=0.01)


def test_world_flux():
    em, _ = _emit(Lights.empty(), world=np.array([0.5, 0.5, 0.5]), index=emission.SOURCE_WORLD,
                  radius=1.5)
    # Radiance L through a disc of radius R from every direction: L pi R^2 4 pi.
    assert em.flux[:, 0].sum() == pytest.approx(0.5 * np.pi * 1.5 ** 2 * 4 * np.pi, rel=1e-9)


def test_mixed_set_shares_photons_by_power():
    li = Lights.from_list([
        {"kind": LIGHT_POINT, "position": (0, 0, 0), "power": 100.0},
        {"kind": LIGHT_POINT, "position": (1, 0, 0), "power": 0.0},
        {"kind": LIGHT_AREA, "position": (0, 0, 1), "power": 300.0, "color": (1.0, 1.0, 1.0)},
        {"kind": LIGHT_SPOT, "position": (0, 0, 1), "power": 50.0},
    ])
    sources = _powers(li)
    assert [s.index for s in sources] == [0, 2, 3]  # the zero-power light gets nothing
    counts = emission.allocate(np.array([luminance(s.power) for s in sources]), 10_000)
    assert counts.sum() == 10_000
    lum = np.array([luminance(s.power) for s in sources])
    np.testing.assert_allclose(counts / 10_000, lum / lum.sum(), atol=1e-4)
    ls = LightSet.from_lights(li)
    total = np.zeros(3)
    for slot, (src, n) in enumerate(zip(sources, counts)):
        em = emission.emit(src, ls, NO_TRIS, np.zeros(3), CENTRE, 2.0, int(n), 0, int(n), seed=3,
                           map_id=0, source_slot=slot)
        total += em.flux.sum(axis=0)
    expected = sum(s.power for s in sources)
    np.testing.assert_allclose(total, expected, rtol=0.01)
    # Equal power per photon across lights (up to the spot falloff's variation).
    assert total[0] / 10_000 == pytest.approx(expected[0] / 10_000, rel=0.01)


def test_lights_that_reach_nothing_get_no_photons():
    spheres = Targets(np.array([[0.0, 0.0, -3.0]]), np.array([1.0]))
    up = shapes.look_at([0, 0, 0], [0, 0, 5])      # pointing away from the object
    down = shapes.look_at([0, 0, 0], [0, 0, -5])
    li = Lights.from_list([
        {"kind": LIGHT_SPOT, "to_world": up, "power": 10.0, "spot_size": 0.5},
        {"kind": LIGHT_SPOT, "to_world": down, "power": 10.0, "spot_size": 0.5},
        {"kind": LIGHT_AREA, "to_world": up, "power": 10.0},
        {"kind": LIGHT_AREA, "to_world": down, "power": 10.0},
    ])
    sources = _powers(li, spheres=spheres)
    assert [s.index for s in sources] == [1, 3]


def _hits_sphere(o, d, c, r):
    oc = o - c
    b = np.sum(oc * d, axis=1)
    disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
    return (disc >= 0) & (-b + np.sqrt(np.maximum(disc, 0)) > 0)


@pytest.mark.parametrize("kind", ["point", "spot", "area", "triangles", "sun"])
def test_aimed_emission_carries_the_flux_sent_into_the_targets(kind):
    # Two overlapping target spheres: the aimed photons that hit them carry, in total,
    # what the unaimed emission sends into them (mixture pdf, no double counting).
    centres = np.array([[0.3, 0.0, -2.0], [0.8, 0.2, -2.2]])
    radii = np.array([0.5, 0.4])
    targets = Targets(centres, radii)
    tris = NO_TRIS
    index = None
    if kind == "point":
        li = _light(kind=LIGHT_POINT, power=10.0, radius=0.05)
    elif kind == "spot":
        li = _light(kind=LIGHT_SPOT, power=10.0, spot_size=0.8, spot_blend=0.5)
    elif kind == "area":
        li = _light(kind=LIGHT_AREA, power=10.0, size=(1.0, 0.6))
    elif kind == "sun":
        m = shapes.look_at([0.2, 0.1, 1.0], [0, 0, 0])
        li = Lights.from_list([{"kind": LIGHT_SUN, "to_world": m, "power": 2.0, "angle": 0.2}])
    else:
        li = Lights.empty()
        tris = EmissiveTriangles.from_mesh(
            shapes.assemble([(shapes.quad([0, 0, 0], [0.4, 0, 0], [0, 0.3, 0]), 0)]),
            Materials.from_list([{"emission": [1.0, 1.0, 1.0]}]))
        index = emission.SOURCE_TRIANGLES
    ls = LightSet.from_lights(li)
    src = emission.Source(0 if index is None else index, np.zeros(3), kind)
    power, probs = emission.aimed_power(src, ls, tris, targets, CENTRE, 3.0)
    assert np.all(probs > 0) and probs.sum() == pytest.approx(1.0)
    n = 1 << 17
    aimed, _ = _emit(li, n=n, targets=targets, probs=probs, radius=3.0, tris=tris, index=index)
    free, _ = _emit(li, n=n, radius=3.0, tris=tris, index=index, seed=7)

    def into(em):
        hit = _hits_sphere(em.origin, em.direction, centres[0], radii[0]) | \
            _hits_sphere(em.origin, em.direction, centres[1], radii[1])
        return em.flux[hit, 0].sum(), hit

    a, hit_a = into(aimed)
    f, hit_f = into(free)
    assert hit_a.mean() > 0.5           # aimed photons mostly hit the targets
    assert hit_f.mean() < 0.5 * hit_a.mean()
    # Statistical error of the unaimed estimate: the hitting photons' count.
    tol = 4.0 / np.sqrt(max(hit_f.sum(), 1)) + 0.01
    assert a == pytest.approx(f, rel=tol)
    assert np.all(np.isfinite(aimed.flux)) and np.all(aimed.flux >= 0)


def _entry_bins(em, centres, radii):
    """(N,) int: the bin (of 16) of each photon's first entry into the target spheres,
    -1 for a miss: the sphere (2) x the sign of the entry normal's x and z (4) x a grazing
    (|cos| < 0.6) or steep entry (2), so the bins tell lines apart by where and in which
    direction they cross the targets."""
    o, d = em.origin, em.direction
    best = np.full(len(o), np.inf)
    k_best = np.full(len(o), -1)
    for k, (c, r) in enumerate(zip(centres, radii)):
        oc = o - c
        b = np.sum(oc * d, axis=1)
        disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
        root = np.sqrt(np.maximum(disc, 0.0))
        t = np.where(-b - root > 0, -b - root, -b + root)  # origin inside: the exit
        ok = (disc >= 0) & (t > 0) & (t < best)
        best = np.where(ok, t, best)
        k_best = np.where(ok, k, k_best)
    hit = k_best >= 0
    n = (o + best[:, None] * d - np.asarray(centres)[np.maximum(k_best, 0)]) \
        / np.asarray(radii)[np.maximum(k_best, 0), None]
    cos = np.abs(np.sum(n * d, axis=1))
    b = k_best * 8 + (n[:, 0] > 0) * 4 + (n[:, 2] > 0) * 2 + (cos < 0.6)
    return np.where(hit, b, -1)


@pytest.mark.parametrize("inside", [False, True], ids=["apart", "inside"])
@pytest.mark.parametrize("soft", [True, False], ids=["soft", "sphere"])
@pytest.mark.parametrize("kind", [LIGHT_POINT, LIGHT_SPOT], ids=["point", "spot"])
def test_large_light_aimed_lines_carry_the_unaimed_flux(kind, soft, inside):
    # A light of radius r > 0 aims lines (module doc, "Aimed emission"): the flux into the
    # targets (two overlapping spheres, one smaller than r, one larger: the target's and
    # the light's disk; apart from the light's ball, or reaching into it, where every
    # direction is in the grown cone) equals unaimed emission's, in total (4 sigma of the
    # two estimates) and over 16 bins of where and how the lines enter (two-sample chi^2).
    from scipy import stats

    r = 0.5
    if inside:
        centres, radii = np.array([[0.0, 0.0, -0.6], [0.4, 0.1, -1.1]]), np.array([0.25, 0.6])
    else:
        centres, radii = np.array([[0.3, 0.0, -2.0], [0.9, 0.2, -2.2]]), np.array([0.3, 0.8])
    light = dict(kind=kind, power=10.0, radius=r, soft_falloff=soft)
    if kind == LIGHT_SPOT:
        light.update(spot_size=1.2, spot_blend=0.5)  # narrower than the grown cones
    li = _light(**light)
    targets = Targets(centres, radii)
    ls = LightSet.from_lights(li)
    power, probs = emission.aimed_power(emission.Source(0, np.zeros(3), "x"), ls, NO_TRIS,
                                        targets, CENTRE, 3.0)
    aimed, _ = _emit(li, n=1 << 17, targets=targets, probs=probs, radius=3.0)
    free, _ = _emit(li, n=1 << 21, radius=3.0, seed=7)
    assert np.all(np.isfinite(aimed.flux)) and np.all(aimed.flux >= 0)
    # Lines off the light's disk carry nothing; the others start as unaimed photons do.
    lit = aimed.flux[:, 0] > 0
    o, d = aimed.origin[lit], aimed.direction[lit]
    if not soft:
        np.testing.assert_allclose(np.linalg.norm(o, axis=1), r, rtol=1e-6)
        assert np.all(np.sum(o * d, axis=1) >= -1e-9)
    else:
        assert np.all(np.linalg.norm(o, axis=1) <= r * (1 + 1e-6))
        assert np.all(np.abs(np.sum(o * d, axis=1)) < 1e-9)
        np.testing.assert_allclose(aimed.lead[lit], np.sum(o * o, axis=1), rtol=1e-9, atol=1e-15)
    sums, variances = [], []
    for em in (aimed, free):
        b = _entry_bins(em, centres, radii)
        x = em.flux[:, 0]
        w = np.bincount(b[b >= 0], weights=x[b >= 0], minlength=16)
        # Var of a bin's sum of n i.i.d. terms: n var(x 1_bin) ~ sum x^2 - (sum x)^2 / n.
        w2 = np.bincount(b[b >= 0], weights=x[b >= 0] ** 2, minlength=16) - w ** 2 / len(x)
        sums.append(w)
        variances.append(w2)
        if em is aimed:
            hit_a = np.mean(b >= 0)
        else:
            hit_f = np.mean(b >= 0)
    assert hit_a > hit_f
    print(f"\nhit {100 * hit_a:.1f} % aimed, {100 * hit_f:.2f} % unaimed; flux into the targets "
          f"{sums[0].sum():.5f} W aimed, {sums[1].sum():.5f} W unaimed")
    diff = sums[0].sum() - sums[1].sum()
    sigma = np.sqrt(variances[0].sum() + variances[1].sum())
    assert abs(diff) < 4.0 * sigma, (sums[0].sum(), sums[1].sum(), sigma)
    used = (variances[0] + variances[1]) > 0
    chi2 = np.sum((sums[0] - sums[1])[used] ** 2 / (variances[0] + variances[1])[used])
    assert stats.chi2.sf(chi2, int(used.sum())) > 1e-3, (chi2, sums)

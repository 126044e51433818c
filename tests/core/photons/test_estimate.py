"""Density estimates against closed forms: a uniform photon field gives Phi/A with every
filter, photons from behind count for nothing, and the weights match hand computations."""

import math

import numpy as np
import pytest

from core.photons import estimate
from core.photons.photon_map import PhotonMap

UP = np.array([0.0, 0.0, 1.0], np.float32)


def uniform_field(rng, side=120, width=2.0, power=(3.0, 2.0, 1.0), facing=1.0):
    """side^2 photons, one per cell of a jittered grid on the square [0, width]^2 at z = 0,
    total flux ``power`` (W), arriving from random directions of the ``facing`` side."""
    cells = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1)
    xy = (cells.reshape(-1, 2) + rng.random((side * side, 2))) * (width / side)
    n = xy.shape[0]
    directions = rng.normal(size=(n, 3))
    directions[:, 2] = facing * (np.abs(directions[:, 2]) + 1e-3)
    flux = np.tile(np.asarray(power) / n, (n, 1))
    return np.c_[xy, np.zeros(n)].astype(np.float32), flux, directions


def interior_points(rng, m=300, lo=0.4, hi=1.6):
    points = np.c_[rng.uniform(lo, hi, (m, 2)), np.zeros(m)].astype(np.float32)
    return points, np.tile(UP, (m, 1))


@pytest.mark.parametrize("filter", ["none", "cone", "gaussian"])
def test_uniform_field_gives_power_over_area(filter, rng):
    positions, flux, directions = uniform_field(rng)
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng)
    e = estimate.irradiance(pm, points, normals, 200, np.inf, filter=filter)
    expected = np.array([3.0, 2.0, 1.0]) / 4.0  # Phi / A, W/m^2
    rel = e / expected - 1.0
    assert np.isfinite(e).all() and (e >= 0).all()
    assert np.abs(rel.mean(axis=0)).max() < 0.01, rel.mean(axis=0)
    assert np.sqrt((rel**2).mean()) < 0.03  # every point, in the mean-square sense
    # A wider cone (k_cone = 2) and the tangent-plane test change nothing on a plane.
    wide = estimate.irradiance(pm, points, normals, 200, np.inf, filter=filter, k_cone=2.0,
                               max_plane_distance=0.0)
    assert np.abs((wide / expected - 1.0).mean(axis=0)).max() < 0.01


def test_photons_from_behind_contribute_nothing(rng):
    positions, flux, directions = uniform_field(rng, side=80)
    points, normals = interior_points(rng, m=100)
    behind = PhotonMap(positions, flux, -directions)
    np.testing.assert_array_equal(estimate.irradiance(behind, points, normals, 50, np.inf), 0.0)
    # Half the photons from each side: the estimate sees the front half's Phi / A only.
    mixed = directions.copy()
    mixed[::2] *= -1.0
    e = estimate.irradiance(PhotonMap(positions, flux, mixed), points, normals, 200, np.inf)
    front = flux[1::2].sum(axis=0) / 4.0
    assert np.abs((e / front - 1.0).mean(axis=0)).max() < 0.03


def test_weights_match_a_hand_computation():
    # Five photons at distances 0.1 .. 0.5 from the origin, gathered with k = 5:
    # r is the 5th photon's distance; cone and Gaussian weights by their formulas.
    d = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    angle = np.arange(5) * 1.3
    positions = np.c_[d * np.cos(angle), d * np.sin(angle), np.zeros(5)].astype(np.float32)
    flux = np.outer([1.0, 2.0, 3.0, 4.0, 5.0], [1.0, 0.5, 0.25])
    pm = PhotonMap(positions, flux, np.tile([0.3, 0.0, 1.0], (5, 1)))
    point, normal = np.zeros((1, 3), np.float32), UP[None]
    d32 = np.sqrt(np.sum(positions.astype(np.float64) ** 2, axis=1))
    r = d32.max()
    a, b = 0.918, 1.953
    gauss = a * (1 - (1 - np.exp(-b * d32**2 / (2 * r**2))) / (1 - np.exp(-b)))
    gauss_mean = a * (1 - (1 - (2 / b) * (1 - np.exp(-b / 2))) / (1 - np.exp(-b)))
    weights = {
        "none": np.ones(5),
        "cone": (1 - d32 / (1.5 * r)) / (1 - 2 / (3 * 1.5)),
        "gaussian": gauss / gauss_mean,
    }
    for name, w in weights.items():
        want = (w[:, None] * flux).sum(axis=0) / (math.pi * r * r)
        got = estimate.irradiance(pm, point, normal, 5, 10.0, filter=name, k_cone=1.5)
        np.testing.assert_allclose(got[0], want, rtol=2e-3, err_msg=name)  # float16 flux
    # Fewer than k photons inside max_radius: the disc is the whole search disc.
    got = estimate.irradiance(pm, point, normal, 50, 0.35)
    want = flux[:3].sum(axis=0) / (math.pi * 0.35**2)
    np.testing.assert_allclose(got[0], want, rtol=2e-3)
    # ... and with no radius limit and fewer than k photons, a finite map has no density.
    np.testing.assert_array_equal(estimate.irradiance(pm, point, normal, 50, np.inf), 0.0)


def test_tangent_plane_test_leaves_out_photons_off_the_plane():
    # Four photons on the plane and one 0.3 m above it, all within r = 0.5.
    positions = np.array([[0.1, 0, 0], [0, 0.2, 0], [-0.3, 0, 0], [0, -0.5, 0],
                          [0.1, 0.1, 0.3]], np.float32)
    flux = np.ones((5, 3))
    pm = PhotonMap(positions, flux, np.tile(UP, (5, 1)))
    point, normal = np.zeros((1, 3), np.float32), UP[None]
    r2 = 0.5**2
    all_ = estimate.irradiance(pm, point, normal, 5, 1.0)
    np.testing.assert_allclose(all_[0], 5 / (math.pi * r2), rtol=1e-3)
    flat = estimate.irradiance(pm, point, normal, 5, 1.0, max_plane_distance=0.5)
    np.testing.assert_allclose(flat[0], 4 / (math.pi * r2), rtol=1e-3)
    keep = estimate.irradiance(pm, point, normal, 5, 1.0, max_plane_distance=0.7)
    np.testing.assert_allclose(keep[0], all_[0])


def test_radiance_albedo_and_brdf_paths_agree(rng):
    positions, flux, directions = uniform_field(rng, side=60)
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng, m=50)
    albedo = rng.random((50, 3)).astype(np.float32)
    e = estimate.irradiance(pm, points, normals, 40, np.inf, filter="cone")
    lambert = estimate.radiance(pm, points, normals, 40, np.inf, albedo=albedo, filter="cone")
    np.testing.assert_allclose(lambert, albedo / np.pi * e, rtol=1e-6)
    as_brdf = estimate.radiance(pm, points, normals, 40, np.inf, filter="cone",
                                brdf=lambda wi, wo: (albedo / np.pi)[:, None, :],
                                outgoing=normals)
    np.testing.assert_allclose(as_brdf, lambert, rtol=1e-5)
    # A BRDF that depends on the incoming direction, against the gathered photons.
    def brdf(wi, wo):
        return np.repeat(np.abs(wi[..., 2:3]), 3, axis=2) * 0.2
    got = estimate.radiance(pm, points, normals, 40, np.inf, brdf=brdf, outgoing=normals)
    idx, dist2 = pm.nearest(points, 40, np.inf)
    wi = pm.directions[idx]
    phi = pm.flux[idx]
    want = (0.2 * np.abs(wi[..., 2:3]) * phi).sum(axis=1) / (np.pi * dist2[:, -1:])
    np.testing.assert_allclose(got, want, rtol=1e-5)


def test_large_k_needs_no_neighbour_arrays(rng):
    """k = 2048 at 4096 points: the estimate keeps O(k) scratch per thread, not (M, k)
    neighbour arrays (100 MB here; 7.9 GB per 65,536 points at the settings' k = 10,000),
    and still equals the brute-force sum over the k nearest."""
    import tracemalloc

    positions, flux, directions = uniform_field(rng, side=140)
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng, m=4096)
    k = 2048
    estimate.irradiance(pm, points[:8], normals[:8], k, np.inf)  # compile outside the trace
    tracemalloc.start()
    try:
        got = estimate.irradiance(pm, points, normals, k, np.inf)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20, f"{peak / 2**20:.1f} MiB traced"
    stored = pm.flux.astype(np.float64)
    for i in range(4):
        d2 = np.sum((pm.positions - points[i]) ** 2, axis=1, dtype=np.float32)
        near = np.argsort(d2, kind="stable")[:k]
        want = stored[near].sum(axis=0) / (math.pi * np.float64(d2[near[-1]]))
        np.testing.assert_allclose(got[i], want, rtol=1e-5)


def test_k_photons_on_the_point_is_an_error():
    positions = np.zeros((10, 3), np.float32)
    pm = PhotonMap(positions, np.ones((10, 3)), np.tile(UP, (10, 1)))
    with pytest.raises(ValueError, match="zero-area"):
        estimate.irradiance(pm, np.zeros((1, 3)), UP[None], 5, 1.0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(filter="box"), "filter"),
    (dict(filter="cone", k_cone=0.5), "k_cone"),
    (dict(max_radius=0.0), "max_radius"),
    (dict(max_radius=-1.0), "max_radius"),
    (dict(normals=np.zeros((1, 3))), "normals"),
    (dict(max_plane_distance=-0.1), "max_plane_distance"),
    (dict(k=0), "k"),
])
def test_bad_arguments_raise_naming_them(kwargs, field, rng):
    pm = PhotonMap(rng.random((20, 3)), np.ones((20, 3)), np.tile(UP, (20, 1)))
    args = dict(photon_map=pm, points=np.zeros((1, 3)), normals=UP[None], k=5, max_radius=1.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=field):
        estimate.irradiance(**args)
    with pytest.raises(ValueError, match="exactly one"):
        estimate.radiance(pm, np.zeros((1, 3)), UP[None], 5, 1.0)


def _closure_hits(rows, m, normals, outgoing):
    from core.materials import closure
    from core.scene import closures as cl
    from core.scene import contract
    mats = contract.Materials.from_list([{"closures": c} for c in rows])
    tab = closure.table(mats)
    n = normals.shape[0]
    return tab, estimate.BsdfHits(tab, np.full(n, m, np.int32), np.ones((n, 3)),
                                  np.asarray(outgoing, np.float64),
                                  np.asarray(normals, np.float64), np.ones(n, bool)), cl


def test_bsdf_estimate_lambert_equals_the_albedo_path(rng):
    """A Lambert material through bsdf= gives albedo / pi E of the fused path (same photons,
    same order)."""
    from core.scene import closures as cl
    positions, flux, directions = uniform_field(rng, side=60)
    directions[::3] *= -1.0  # photons from behind: a reflecting lobe sees none of them
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng, m=50)
    outgoing = np.tile([0.3, 0.1, 0.9], (50, 1)) / np.linalg.norm([0.3, 0.1, 0.9])
    _, hits, _ = _closure_hits([[dict(kind=cl.CLOSURE_DIFFUSE,
                                      params=dict(color=(0.8, 0.5, 0.2), roughness=0.0))]], 0,
                               normals, outgoing)
    albedo = np.tile([0.8, 0.5, 0.2], (50, 1))
    want = estimate.radiance_estimate(pm, points, normals, albedo, 40, np.inf)
    got = estimate.radiance_estimate(pm, points, normals, None, 40, np.inf, bsdf=hits)
    assert want.min() > 0
    np.testing.assert_allclose(got, want, rtol=1e-6)


def test_bsdf_estimate_translucent_sees_the_far_side_only(rng):
    """Translucent: photons arriving from behind give albedo / pi E_back, from the front
    nothing (the lobe transmits); the albedo path would see the front ones only."""
    from core.scene import closures as cl
    positions, flux, directions = uniform_field(rng, side=80, facing=-1.0)
    points, normals = interior_points(rng, m=100)
    outgoing = np.tile([0.0, 0.0, 1.0], (100, 1))
    _, hits, _ = _closure_hits([[dict(kind=cl.CLOSURE_TRANSLUCENT,
                                      params=dict(color=(0.9, 0.6, 0.3)))]], 0, normals, outgoing)
    back = estimate.radiance_estimate(PhotonMap(positions, flux, directions), points, normals,
                                      None, 200, np.inf, filter="none", bsdf=hits)
    expected = np.array([0.9, 0.6, 0.3]) / np.pi * np.array([3.0, 2.0, 1.0]) / 4.0
    assert np.abs((back / expected - 1.0).mean(axis=0)).max() < 0.01
    front = estimate.radiance_estimate(PhotonMap(positions, flux, -directions), points,
                                       normals, None, 200, np.inf, filter="none", bsdf=hits)
    np.testing.assert_array_equal(front, 0.0)


def test_bsdf_estimate_oren_nayar_equals_the_brdf_callback(rng):
    """Oren-Nayar through bsdf= against the generic callback path fed the closure
    evaluator's f (eval_bsdf / cos): the same sum over the same photons."""
    from core.materials import closure
    from core.scene import closures as cl
    positions, flux, directions = uniform_field(rng, side=60)
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng, m=30)
    wo = np.array([0.6, 0.0, 0.8])
    outgoing = np.tile(wo, (30, 1))
    tab, hits, _ = _closure_hits([[dict(kind=cl.CLOSURE_DIFFUSE,
                                        params=dict(color=(0.8, 0.5, 0.2), roughness=0.9))]],
                                 0, normals, outgoing)

    def brdf(wi, _):
        flat = wi.reshape(-1, 3).astype(np.float64)
        ok = np.linalg.norm(flat, axis=1) > 0.5
        f = np.zeros((flat.shape[0], 3))
        ev = closure.eval_many(tab, 0, wo, flat[ok], UP, UP, (1.0, 0.0, 0.0), True)
        f[ok] = ev[:, :3] / np.abs(flat[ok, 2:3])
        return f.reshape(wi.shape)

    want = estimate.radiance(pm, points, normals, 40, np.inf, brdf=brdf, outgoing=outgoing,
                             filter="cone", k_cone=estimate.CONE_K,
                             max_plane_distance=estimate.PLANE_FRACTION)
    got = estimate.radiance_estimate(pm, points, normals, None, 40, np.inf, bsdf=hits)
    lambert = estimate.radiance_estimate(pm, points, normals, np.tile([0.8, 0.5, 0.2], (30, 1)),
                                         40, np.inf)
    np.testing.assert_allclose(got, want, rtol=1e-4)
    assert np.abs(got / lambert - 1.0).max() > 0.02  # Oren-Nayar is not Lambert here


@pytest.mark.parametrize("nm", [450.0, 650.0])
def test_bsdf_estimate_builds_a_dispersive_principled_at_the_path_wavelength(nm, rng):
    """A dispersive Principled BSDF with a diffuse base and Transmission (docs/dispersion.md):
    the BSDF estimate of a camera path that picked wavelength nm (``BsdfHits.wavelength``)
    is the sum over the same photons of the closures built at that wavelength
    (``closure.eval_parts(..., lam=nm)``, its diffuse-like part), and the subsets of hits
    (``take``) keep their wavelengths. The transmission lobe is really built at nm: its pdf
    differs from n_d's; the diffuse base's f does not depend on the transmission's IOR
    (Principled weights it by 1 - Transmission), hence the same estimate at lam 0."""
    from core.materials import closure
    from core.scene import closures as cl
    from core.scene.contract import Materials
    positions, flux, directions = uniform_field(rng, side=60)
    directions[::3] *= -1.0  # photons of both sides: the transmission sees the far side
    pm = PhotonMap(positions, flux, directions)
    points, normals = interior_points(rng, m=30)
    wo = np.array([0.6, 0.0, 0.8])
    outgoing = np.tile(wo, (30, 1))
    mats = Materials.from_list([{"closures": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        color=(0.8, 0.5, 0.2), roughness=0.4, ior=1.5, transmission=0.5))],
        "dispersion": 20.0}])
    tab = closure.table(mats)
    assert closure.dispersive(tab, 0)
    lam = np.full(30, nm)
    hits = estimate.BsdfHits(tab, np.zeros(30, np.int32), np.ones((30, 3)), outgoing, normals,
                             np.ones(30, bool), wavelength=lam)
    assert np.array_equal(hits.take(slice(3, 9)).wavelengths(), lam[3:9])
    assert np.array_equal(estimate.BsdfHits(*hits[:6]).wavelengths(), np.zeros(30))

    def parts(wi, at):
        return np.array([closure.eval_parts(tab, 0, 1.0, 1.0, 1.0, *wo, *w, *UP, *UP,
                                            1.0, 0.0, 0.0, True, True, at) for w in wi])

    def brdf(wi, _):
        flat = wi.reshape(-1, 3).astype(np.float64)
        ok = np.linalg.norm(flat, axis=1) > 0.5
        f = np.zeros((flat.shape[0], 3))
        f[ok] = parts(flat[ok], nm)[:, :3] / np.abs(flat[ok, 2:3])
        return f.reshape(wi.shape)

    probe = np.array([[-0.4, 0.0, -0.92], [-0.5, 0.1, -0.86]])  # near the refraction
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    at_nm, at_nd = parts(probe, nm), parts(probe, 0.0)
    assert np.all(np.abs(at_nm[:, 6] / at_nd[:, 6] - 1.0) > 1e-3)  # the lobe's pdf moves
    want = estimate.radiance(pm, points, normals, 40, np.inf, brdf=brdf, outgoing=outgoing,
                             filter="cone", k_cone=estimate.CONE_K,
                             max_plane_distance=estimate.PLANE_FRACTION)
    got = estimate.radiance_estimate(pm, points, normals, None, 40, np.inf, bsdf=hits)
    assert got.min() > 0
    np.testing.assert_allclose(got, want, rtol=1e-4)
    rgb = estimate.radiance_estimate(pm, points, normals, None, 40, np.inf,
                                     bsdf=hits._replace(wavelength=None))
    np.testing.assert_array_equal(got, rgb)

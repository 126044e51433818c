"""The second pass's photon terms: radiance estimates, final gathering, the preview, the
automatic radius, leaks, and the passes they fill (core/integrators/gather.py, core/integrators/photon_mapping.py).

Hand-built photon maps (photons placed with a known irradiance) test the gathering side on
its own; the tests marked "traced" use core/photons/tracing.py's maps end to end.
"""

import math
import types

import numpy as np
import pytest

from core.photons import estimate
from core.integrators import gather
from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.photons.photon_map import PhotonMap
from core.scene.contract import LIGHT_AREA, Camera, Lights, Materials, Scene
from core.settings import RenderSettings, SettingsError


def inward(part):
    """The part with its winding (and normals) reversed."""
    return shapes.Part(part.corners[:, ::-1].copy(), -part.normals[:, ::-1].copy())


def maps(global_map=None, caustic_map=None):
    """A stand-in for tracing.PhotonMaps."""
    return types.SimpleNamespace(global_map=global_map, caustic_map=caustic_map,
                                 global_emitted=0, caustic_emitted=0, stats={})


def uniform_photons(mesh_corners, normals_in, irradiance, n, rng):
    """n photons uniform over triangles (T, 3, 3) with total irradiance ``irradiance``
    (W/m^2, (3,)), arriving cosine-distributed on the side of ``normals_in`` (T, 3)."""
    c = np.asarray(mesh_corners, np.float64)
    area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    tri = rng.choice(len(c), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    pos = c[tri, 0] + u[:, None] * (c[tri, 1] - c[tri, 0]) + v[:, None] * (c[tri, 2] - c[tri, 0])
    nrm = normals_in[tri]
    # cosine-distributed directions about the normal (toward where photons came from)
    r, phi = np.sqrt(rng.random(n)), 2 * np.pi * rng.random(n)
    a = np.where(np.abs(nrm[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t = np.cross(nrm, a)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(nrm, t)
    d = (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + np.sqrt(1 - r**2)[:, None] * nrm
    flux = np.broadcast_to(np.asarray(irradiance, np.float64) * area.sum() / n, (n, 3))
    return PhotonMap(pos.astype(np.float32), flux, d)


# --- settings -----------------------------------------------------------------------------

def test_photon_settings_are_validated_by_name():
    s = RenderSettings()
    for name, bad in (("global_photons", -1), ("caustic_k", 0), ("global_radius", -0.1),
                      ("caustic_radius", float("nan")), ("final_gather_rays", 0),
                      ("indirect_mode", "gather"), ("filter", "box"), ("caustics", 1),
                      ("photon_max_bounces", 0), ("projection_map", "yes")):
        with pytest.raises(SettingsError, match=name):
            s.with_values(**{name: bad})
    parsed = s.with_strings({"indirect_mode": "preview", "caustics": "off", "global_radius": "0.5"})
    assert (parsed.indirect_mode, parsed.caustics, parsed.global_radius) == ("preview", False, 0.5)
    with pytest.raises(SettingsError, match="caustics"):
        s.with_strings({"caustics": "maybe"})


# --- the radiance estimate ------------------------------------------------------------------

def test_estimate_of_a_uniform_field_and_front_side_only(rng):
    plane = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    pm = uniform_photons(plane.corners, np.array([[0, 0, 1.0]] * 2), [2.0, 1.0, 0.5], 40_000, rng)
    pts = np.column_stack([rng.uniform(-0.5, 0.5, (2000, 2)), np.zeros(2000)])
    up = np.tile([0, 0, 1.0], (2000, 1))
    albedo = np.tile([0.5, 0.5, 0.5], (2000, 1))
    # The irradiance these photons hold where the queries look (their own fluctuation
    # is ~1 % over the region, more than the estimate's bias k / (k - 1)).
    inside = np.all(np.abs(pm.positions[:, :2]) < 0.55, axis=1)
    held = pm.flux[inside].astype(np.float64).sum(axis=0) / 1.1**2
    for filt in ("none", "cone", "gaussian"):
        L = estimate.radiance_estimate(pm, pts, up, albedo, 100, np.inf, filt)
        np.testing.assert_allclose(L.mean(axis=0), 0.5 / np.pi * held, rtol=0.02)
    # Seen from below, the same photons arrive from behind: nothing.
    assert np.all(estimate.radiance_estimate(pm, pts, -up, albedo, 100, np.inf) == 0)


def test_auto_radius_holds_k_photons_and_scales_with_the_scene():
    r = estimate.auto_radius(4.0, 50, 10_000)
    assert math.pi * (r / estimate.RADIUS_FACTOR) ** 2 * 10_000 / 4.0 == pytest.approx(50)
    assert estimate.auto_radius(4.0e6, 50, 10_000) == pytest.approx(1e3 * r)
    assert estimate.auto_radius(4.0, 50, 0) == math.inf


# --- the white furnace ----------------------------------------------------------------------

def furnace(albedo, emission=1.0, res=8, rings=24, segments=48):
    sphere = inward(shapes.uv_sphere([0, 0, 0], 1.0, rings, segments))
    mats = Materials.from_list([{"diffuse": [albedo] * 3, "emission": [emission] * 3}])
    cam = shapes.pinhole([0, 0, 0], [1, 0.2, 0.1], res, res, np.radians(60))
    cam = Camera(to_world=cam.to_world, width=res, height=res, film_size=cam.film_size,
                 clip_start=1e-3, clip_end=10.0)
    return Scene(shapes.assemble([(sphere, 0)]), mats, Lights.empty(), cam), sphere


@pytest.mark.parametrize("albedo", [0.5, 0.8])
def test_white_furnace_with_a_hand_built_global_map(albedo, rng):
    """Camera inside a closed emissive sphere of albedo a: L = L_e / (1 - a). Emission
    L_e, direct a L_e (emissive triangles as lights), final gather a^2 L_e / (1 - a)
    from a map holding the exact irradiance pi L_e / (1 - a)."""
    scene, sphere = furnace(albedo)
    n_in = sphere.normals[:, 0]
    pm = uniform_photons(sphere.corners, n_in, [math.pi / (1 - albedo)] * 3, 60_000, rng)
    st = RenderSettings(samples=4, final_gather_rays=64, caustics=False, global_k=64)
    out = integrator.render(scene, st, photon_maps=maps(global_map=pm))
    p = out.passes
    expected = 1.0 / (1.0 - albedo)
    np.testing.assert_allclose(p["emission"].mean(), 1.0, rtol=1e-3)
    np.testing.assert_allclose(p["direct"].mean(), albedo, rtol=0.02)
    np.testing.assert_allclose(p["indirect"].mean(), albedo**2 / (1 - albedo), rtol=0.03)
    np.testing.assert_allclose(p["combined"].mean(), expected, rtol=0.02)
    assert out.stats["gather_rays_per_sample"] == 16 and out.stats["rays_gather"] > 0
    assert out.stats["skipped"] == {"caustics": "caustics switched off"}


@pytest.mark.parametrize("albedo", [0.5, 0.8])
def test_white_furnace_traced(albedo):
    """The same furnace with photons traced from the emissive triangles (core/photons/tracing.py):
    L_e / (1 - a) within 2 %. 64 photon bounces: at a = 0.8 the default 8 would cut the
    series by a^9 = 13 % of the indirect term."""
    scene, _ = furnace(albedo)
    st = RenderSettings(samples=4, final_gather_rays=64, global_photons=100_000, global_k=64,
                        photon_max_bounces=64)
    out = integrator.render(scene, st)
    assert out.stats["global_photons_stored"] > 0
    assert "caustics" in out.stats["skipped"]  # nothing specular: no caustic map
    assert out.stats["caustic_photons_stored"] == 0
    np.testing.assert_allclose(out.passes["direct"].mean(), albedo, rtol=0.02)
    np.testing.assert_allclose(out.passes["combined"].mean(), 1 / (1 - albedo), rtol=0.02)


def half_metal_furnace(res=8):
    """The furnace sphere (radius 1) with its upper half (z > 0) a white rough mirror
    (Glossy BSDF, colour 1, roughness 0.4, multiscatter GGX: it reflects all it receives)
    and its lower half emissive (L_e = 1) Lambert of albedo 1/2; the camera at the centre
    looks down at the lower half. The radiance is uniform, L = L_e / (1 - 1/2) = 2."""
    from core.scene import closures as cl
    sphere = inward(shapes.uv_sphere([0, 0, 0], 1.0, 24, 48))
    up = sphere.corners[:, :, 2].mean(axis=1) > 0
    metal = shapes.Part(sphere.corners[up], sphere.normals[up])
    lamp = shapes.Part(sphere.corners[~up], sphere.normals[~up])
    mats = Materials.from_list([
        {"diffuse": [0.5] * 3, "emission": [1.0] * 3},
        {"closures": [dict(kind=cl.CLOSURE_GLOSSY, params=dict(color=1.0, roughness=0.4))]}])
    cam = shapes.pinhole([0, 0, 0], [0.05, 0.1, -1.0], res, res, np.radians(60))
    cam = Camera(to_world=cam.to_world, width=res, height=res, film_size=cam.film_size,
                 clip_start=1e-3, clip_end=10.0)
    return Scene(shapes.assemble([(lamp, 0), (metal, 1)]), mats, Lights.empty(), cam)


def test_final_gather_reads_the_light_behind_a_rough_metal():
    """Half the furnace a rough metal (half_metal_furnace): L = 2 everywhere. A gather
    ray that lands on the metal (no diffuse lobe, no estimate there) goes on through one
    BSDF sample to the diffuse half and reads the global map there; were it to stop at the
    metal, the light it reflects from diffuse bounces would be lost (about 1.75)."""
    st = RenderSettings(samples=4, final_gather_rays=64, global_photons=100_000, global_k=64,
                        caustic_photons=100_000, photon_max_bounces=16, max_specular_depth=4)
    out = integrator.render(half_metal_furnace(), st)
    assert out.stats["caustic_photons_stored"] > 0  # emission reflected by the metal
    np.testing.assert_allclose(out.passes["emission"].mean(), 1.0, rtol=1e-3)
    np.testing.assert_allclose(out.passes["combined"].mean(), 2.0, rtol=0.025)


# --- leaks ----------------------------------------------------------------------------------

def thin_wall_scene(side, thickness=1e-3):
    """A 1 m wall made of two back-to-back quads ``thickness`` apart (x = +-thickness/2),
    lit from -x by a point light through a small glass sphere (a caustic on the wall)
    and bouncing off a white panel at x = -0.8 (indirect light on the wall). Nothing
    at all lights the +x face. ``side`` = -1 / +1: an orthographic camera looking at the
    -x (lit) / +x (dark) face."""
    h = thickness / 2
    lit = shapes.quad([-h, 0, 0], [0, 0, 0.5], [0, 0.5, 0])      # normal -x
    dark = shapes.quad([h, 0, 0], [0, 0.5, 0], [0, 0, 0.5])      # normal +x
    panel = shapes.quad([-0.8, 0, 0], [0, 0.5, 0], [0, 0, 0.5])  # normal +x
    glass = shapes.uv_sphere([-0.2, 0.1, 0.1], 0.08, 16, 32)
    mats = Materials.from_list([{"diffuse": [0.8, 0.8, 0.8]},
                                {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([{"kind": 0, "position": [-0.45, 0.2, 0.2], "power": 30.0}])
    eye = np.array([side * 0.05, 0, 0])
    cam = Camera(to_world=shapes.look_at(eye, [0, 0, 0], (0, 0, 1)), width=16, height=16,
                 film_size=np.array([0.9, 0.9]), kind=1, clip_start=1e-3, clip_end=10.0)
    return Scene(shapes.assemble([(lit, 0), (dark, 0), (panel, 0), (glass, 1)]), mats,
                 lights, cam)


def test_thin_wall_does_not_leak():
    st = RenderSettings(samples=4, final_gather_rays=32, global_photons=60_000,
                        caustic_photons=60_000)
    photon_light = {}
    for side in (-1, 1):
        p = integrator.render(thin_wall_scene(side), st).passes
        photon_light[side] = (p["caustics"] + p["indirect"]).mean()
        if side == -1:
            assert p["caustics"].max() > 0 and p["indirect"].mean() > 0
    assert photon_light[1] < 0.01 * photon_light[-1], photon_light


# --- what the scene requires ------------------------------------------------------------------

def test_terms_switched_off_cost_nothing_and_say_why():
    scene, _ = furnace(0.5, res=4)
    out = integrator.render(scene, RenderSettings(samples=1, indirect_mode="off"))
    assert out.stats["skipped"]["indirect"] == "indirect light switched off"
    assert out.stats["global_photons_stored"] == 0 and out.stats["rays_gather"] == 0
    assert not out.stats["traced"]  # nothing specular, indirect off: no photon pass at all
    assert np.all(out.passes["indirect"] == 0) and np.all(out.passes["caustics"] == 0)


def test_preview_mode_shows_the_global_map_directly(rng):
    """Preview: rho / pi * E of the map (built without direct photons) at the first hit,
    no gather rays."""
    scene, sphere = furnace(0.5)
    pm = uniform_photons(sphere.corners, sphere.normals[:, 0], [math.pi * 0.5 / 0.5] * 3,
                         60_000, rng)  # the indirect part: pi * a L_e / (1 - a)
    out = integrator.render(scene, RenderSettings(samples=2, indirect_mode="preview",
                                                  caustics=False), photon_maps=maps(pm))
    assert out.stats["rays_gather"] == 0
    np.testing.assert_allclose(out.passes["indirect"].mean(), 0.5 * 0.5 / 0.5, rtol=0.03)
    np.testing.assert_allclose(out.passes["combined"].mean(), 2.0, rtol=0.03)


@pytest.mark.parametrize("theta", [0.0, 1.05])
def test_photon_terms_take_the_principled_diffuse_albedo_under_its_specular_layer(theta, rng):
    """A default Principled plane (base 0.8, roughness 0.5, IOR 1.5) under a hand-built
    global map of irradiance pi (preview mode): the indirect pass is the diffuse lobe's
    albedo toward the camera, base x (1 - the specular layer's albedo), as Cycles layers it
    (the closure evaluator's diffuse part, 0.770 at normal view, 0.745 at 60 deg), not the
    constant 0.8 of Materials.diffuse (4 to 7 % too bright before)."""
    from core.materials import closure
    from core.scene import closures as cl
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"diffuse": [0.8] * 3, "closures": [dict(
        kind=cl.CLOSURE_PRINCIPLED, params=dict(color=0.8, roughness=0.5, ior=1.5))]}])
    eye = np.array([np.sin(theta), 0.0, np.cos(theta)])
    cam = Camera(to_world=shapes.look_at(eye, [0, 0, 0], up=(0, 1, 0)), width=8, height=8,
                 film_size=np.array([0.4, 0.4]), kind=1, clip_start=1e-3, clip_end=10.0)
    scene = Scene(shapes.assemble([(plane, 0)]), mats, Lights.empty(), cam)
    pm = uniform_photons(plane.corners, np.array([[0, 0, 1.0]] * 2), [math.pi] * 3,
                         200_000, rng)
    out = integrator.render(scene, RenderSettings(samples=2, indirect_mode="preview",
                                                  caustics=False, global_k=200),
                            photon_maps=maps(pm))
    expected = closure.albedo_at(closure.table(mats), 0, eye, [0, 0, 1.0])[0]
    assert expected < 0.8 * 0.97
    np.testing.assert_allclose(out.passes["indirect"].mean(), expected, rtol=0.02)


@pytest.mark.parametrize("cache", [True, False])
def test_final_gather_reads_the_light_a_principled_specular_layer_reflects(cache, monkeypatch,
                                                                          rng):
    """The furnace sphere (camera at its centre) in white default Principled (base 1,
    roughness 0.5, IOR 1.5), with a hand-built global map of irradiance pi arriving
    cosine-distributed (uniform incident radiance 1). Its total albedo is 1 at every angle
    (Cycles layers the base under the specular layer by 1 - that layer's albedo; sampled
    0.991-1.000 from 0 to 85 deg), and by reciprocity the albedo is what a surface reflects
    of uniform light: every gather ray must find radiance 1, and the indirect pass is the
    camera hit's diffuse albedo at normal view (0.963) times the white Lambert sphere's with
    the same map (which is 1), with and without the radiance cache. A gather hit that read
    the wall's diffuse part only, base x (1 - the specular layer's albedo), lost the light
    its specular layer reflects (about 5 %: the artist scene's walls, issue 13); the gather
    rays now also follow that glossy lobe."""
    from core.materials import closure
    from core.scene import closures as cl
    if not cache:  # the full estimate at each gather hit
        monkeypatch.setattr(gather, "build_radiance_cache",
                            lambda terms, prepared, settings, **kw: None)
    _, sphere = furnace(1.0)
    pm = uniform_photons(sphere.corners, sphere.normals[:, 0], [math.pi] * 3, 60_000, rng)
    st = RenderSettings(samples=4, final_gather_rays=64, caustics=False, global_k=64)

    def indirect(material):
        scene, _ = furnace(1.0, emission=0.0)
        scene = Scene(scene.mesh, Materials.from_list([material]), scene.lights, scene.camera)
        return integrator.render(scene, st, photon_maps=maps(pm)).passes["indirect"].mean()

    lambert = indirect({"diffuse": [1.0] * 3})
    np.testing.assert_allclose(lambert, 1.0, rtol=0.03)
    principled = {"diffuse": [1.0] * 3, "closures": [dict(
        kind=cl.CLOSURE_PRINCIPLED, params=dict(color=1.0, roughness=0.5, ior=1.5))]}
    tab = closure.table(Materials.from_list([principled]))
    rho = closure.albedo_at(tab, 0, [0, 0, 1.0], [0, 0, 1.0])[0]  # diffuse part, normal view
    assert 0.95 < rho < 0.97
    np.testing.assert_allclose(indirect(principled) / lambert, rho, rtol=0.01)


# --- a caustic against a ray-traced oracle ----------------------------------------------------

def _fresnel(cos_i, n1, n2):
    """Unpolarised Fresnel reflectance and cos of the refracted angle (no TIR here)."""
    sin_t2 = (n1 / n2) ** 2 * (1 - cos_i**2)
    cos_t = np.sqrt(np.maximum(0.0, 1 - sin_t2))
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return np.where(sin_t2 >= 1, 1.0, (rs**2 + rp**2) / 2), cos_t


def sphere_caustic_oracle(light, centre, radius, ior, power, n, rng, inner_bounces=6):
    """Where the flux of an isotropic point light that hits an ideal glass sphere lands on
    the floor z = 0: (M, 2) landing points and (M,) watts, by deterministic Fresnel
    splitting on the exact sphere (independent of the renderer's code)."""
    light, centre = np.asarray(light, float), np.asarray(centre, float)
    axis = centre - light
    dist = np.linalg.norm(axis)
    axis /= dist
    cos_max = math.sqrt(1 - (radius / dist) ** 2)
    cos = 1 - rng.random(n) * (1 - cos_max)
    phi = 2 * np.pi * rng.random(n)
    t = np.cross(axis, [0, 0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0, 0])
    t /= np.linalg.norm(t)
    b = np.cross(axis, t)
    sin = np.sqrt(1 - cos**2)
    d = cos[:, None] * axis + sin[:, None] * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    w = np.full(n, power / (4 * np.pi) * 2 * np.pi * (1 - cos_max) / n)
    o = np.broadcast_to(light, (n, 3))

    def hit(o, d, far):
        oc = o - centre
        bb = np.einsum("ij,ij->i", oc, d)
        disc = np.maximum(bb**2 - (np.einsum("ij,ij->i", oc, oc) - radius**2), 0.0)
        return -bb + np.sqrt(disc) if far else -bb - np.sqrt(disc)

    out_o, out_d, out_w = [], [], []
    p = o + hit(o, d, False)[:, None] * d
    nrm = (p - centre) / radius
    cos_i = -np.einsum("ij,ij->i", d, nrm)
    f, cos_t = _fresnel(cos_i, 1.0, ior)
    out_o.append(p), out_d.append(d + 2 * cos_i[:, None] * nrm), out_w.append(w * f)
    eta = 1.0 / ior
    d = eta * d + (eta * cos_i - cos_t)[:, None] * nrm
    w = w * (1 - f)
    o = p
    for _ in range(inner_bounces):
        p = o + hit(o, d, True)[:, None] * d
        nrm = -(p - centre) / radius  # facing the ray, inside
        cos_i = -np.einsum("ij,ij->i", d, nrm)
        f, cos_t = _fresnel(cos_i, ior, 1.0)
        out_o.append(p), out_d.append(ior * d + (ior * cos_i - cos_t)[:, None] * nrm)
        out_w.append(w * (1 - f))
        d = d + 2 * cos_i[:, None] * nrm
        w = w * f
        o = p
    o, d, w = np.concatenate(out_o), np.concatenate(out_d), np.concatenate(out_w)
    down = d[:, 2] < 0
    o, d, w = o[down], d[down], w[down]
    land = o + (-o[:, 2] / d[:, 2])[:, None] * d
    return land[:, :2], w


def test_glass_sphere_caustic_matches_the_oracle():
    """A glass sphere above a floor under a point light: the caustics pass is non-zero
    only where the oracle's light lands (within the gather radius), and its integral
    (L_c pi / rho x pixel area) matches the flux the oracle delivers there within 10 %."""
    centre, radius, light, power, rho = (0.0, 0.0, 0.5), 0.3, (-2.0, 0.0, 2.0), 100.0, 0.8
    floor = shapes.quad([0, 0, 0], [3, 0, 0], [0, 3, 0])
    sphere = shapes.uv_sphere(centre, radius, 48, 96)
    mats = Materials.from_list([{"diffuse": [rho] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    res, size, look = 48, 1.6, np.array([0.7, 0.0, 0.0])
    cam = Camera(to_world=shapes.look_at(look + [0, 0, 3], look, (0, 1, 0)), width=res,
                 height=res, film_size=np.array([size, size]), kind=1, clip_start=1e-3,
                 clip_end=10.0)
    scene = Scene(shapes.assemble([(floor, 0), (sphere, 1)]), mats,
                  Lights.from_list([{"kind": 0, "position": light, "power": power}]), cam)
    out = integrator.render(scene, RenderSettings(samples=4, caustic_photons=200_000,
                                                  indirect_mode="off", caustic_k=40))
    caustic = out.passes["caustics"].mean(axis=2)[::-1]  # row 0 at -y, like hist below
    pixel = size / res
    # Where the floor is hidden from the camera by the sphere, the pass holds nothing.
    xs = look[0] - size / 2 + (np.arange(res) + 0.5) * pixel
    ys = look[1] - size / 2 + (np.arange(res) + 0.5) * pixel
    gx, gy = np.meshgrid(xs, ys)
    visible = (gx - centre[0]) ** 2 + (gy - centre[1]) ** 2 > (radius + pixel) ** 2
    land, w = sphere_caustic_oracle(light, centre, radius, 1.5, power, 400_000,
                                    np.random.default_rng(7))
    ix = np.floor((land[:, 0] - (look[0] - size / 2)) / pixel).astype(int)
    iy = np.floor((land[:, 1] - (look[1] - size / 2)) / pixel).astype(int)
    inside = (ix >= 0) & (ix < res) & (iy >= 0) & (iy < res)
    hist = np.zeros((res, res))
    np.add.at(hist, (iy[inside], ix[inside]), w[inside])
    expected = hist[visible].sum()
    rendered = caustic[visible].sum() * math.pi / rho * pixel**2
    print(f"\ncaustic: rendered {rendered:.4f} W, oracle {expected:.4f} W "
          f"({100 * (rendered / expected - 1):+.1f} %), radius {out.stats['caustic_radius']:.4f} m")
    assert rendered == pytest.approx(expected, rel=0.10)
    # Non-zero only where the oracle's light lands, dilated by the gather radius; and
    # the focus (the pixels holding 90 % of the oracle's flux, grown by 2 pixels) holds
    # as much of the caustic: the faint spread of light reflected off the sphere is the
    # rest.
    from scipy.ndimage import binary_dilation
    grow = int(math.ceil(out.stats["caustic_radius"] / pixel)) + 1
    assert np.all(caustic[visible & ~binary_dilation(hist > 0, iterations=grow)] == 0)
    order = np.sort(hist[visible])[::-1]
    level = order[np.searchsorted(np.cumsum(order), 0.90 * order.sum())]
    focus = binary_dilation(hist >= level, iterations=2) & visible
    share = caustic[focus].sum() / caustic[visible].sum()
    print(f"focus: {100 * focus.sum() / visible.sum():.1f} % of the floor, "
          f"{100 * share:.1f} % of the caustic")
    assert focus.sum() < 0.5 * visible.sum() and share > 0.88
    # Its shape: flux per 8 x 8-pixel block against the oracle's, where the oracle's block
    # holds at least 10 % of the brightest block.
    vis_hist = np.where(visible, hist, 0.0)
    vis_caustic = np.where(visible, caustic * math.pi / rho * pixel**2, 0.0)
    hb = vis_hist.reshape(6, 8, 6, 8).sum(axis=(1, 3))
    cb = vis_caustic.reshape(6, 8, 6, 8).sum(axis=(1, 3))
    bright = hb > 0.1 * hb.max()
    worst = np.max(np.abs(cb[bright] / hb[bright] - 1))
    print(f"caustic blocks: {bright.sum()} bright, worst {100 * worst:.1f} %")
    assert worst < 0.15


def test_gathering_in_batches_changes_no_bit(monkeypatch, rng):
    """Final gathering splits big tiles into batches of rays; the image must not notice."""
    scene, sphere = furnace(0.5, res=6)
    pm = uniform_photons(sphere.corners, sphere.normals[:, 0], [math.pi] * 3, 20_000, rng)
    st = RenderSettings(samples=2, final_gather_rays=16, caustics=False)
    whole = integrator.render(scene, st, photon_maps=maps(pm)).passes
    monkeypatch.setattr(gather, "GATHER_BATCH", 24)
    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 16)
    split = integrator.render(scene, st, photon_maps=maps(pm)).passes
    for name, image in whole.items():
        np.testing.assert_array_equal(split[name], image, err_msg=name)


def test_preview_and_final_gather_agree_on_the_cornell_box():
    """Both modes estimate the same indirect light (one from the map without direct
    photons seen directly, the other gathered from the map with them): their image means
    agree within 5 % per channel (the preview is blotchy, not biased)."""
    from tests.core.integrators.test_photon_mapping import cornell

    means = {}
    for mode in ("final_gather", "preview"):
        out = integrator.render(cornell(res=24), RenderSettings(
            samples=8, seed=3, indirect_mode=mode, caustics=False, final_gather_rays=256))
        assert out.stats["photon_maps"]["include_direct"] == (mode == "final_gather")
        means[mode] = out.passes["indirect"].mean(axis=(0, 1))
    np.testing.assert_allclose(means["preview"], means["final_gather"], rtol=0.05)


def test_radiance_cache_count_follows_the_gather_disc():
    """12 points per gather disc, capped at a quarter of the stored photons: with the
    automatic radius (twice the k-nearest radius) that is 3 N / k from k = 12 on."""
    area, stored = 7.0, 200_000
    for k, expected in ((10, stored // 4), (12, stored // 4), (50, 3 * stored // 50),
                        (100, 3 * stored // 100), (200, 3 * stored // 200)):
        r = estimate.auto_radius(area, k, stored)
        assert abs(gather.cache_point_count(stored, area, r) - expected) <= 1, k
    assert gather.cache_point_count(stored, area, 1e-9) == stored // 4  # tiny hand-set radius
    assert gather.cache_point_count(stored, area, 1e9) == 1             # huge: one point
    assert gather.cache_point_count(0, area, math.inf) == 1


@pytest.mark.parametrize("k", [50, 150])
def test_radiance_cache_matches_the_full_estimate(k, monkeypatch):
    """The cache is a shortcut, not an approximation the image can see: final gathering
    through it gives the indirect light of a k-nearest estimate at every gather hit
    (means per channel within 1.5 %, 4 x 4 blocks within 6 %), also at a k where it holds
    fewer points than photons / 4."""
    from tests.core.integrators.test_photon_mapping import cornell

    settings = RenderSettings(samples=4, seed=5, caustics=False, global_photons=40_000,
                              global_k=k, final_gather_rays=256)
    cached = integrator.render(cornell(res=16), settings)
    monkeypatch.setattr(gather, "build_radiance_cache", lambda terms, prepared, settings, **kw: None)
    full = integrator.render(cornell(res=16), settings)
    a, b = cached.passes["indirect"], full.passes["indirect"]
    assert b.min() >= 0 and b.mean() > 0
    np.testing.assert_allclose(a.mean(axis=(0, 1)), b.mean(axis=(0, 1)), rtol=0.015)
    blocks = lambda img: img.reshape(4, 4, 4, 4, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(blocks(a), blocks(b), rtol=0.06)


@pytest.mark.parametrize("kind, back", [("lambert", 0.0), ("translucent", 0.5),
                                        ("sheen", 0.0), ("oren_nayar", 0.0)])
def test_bsdf_gather_ray_weights_average_to_the_diffuse_albedo(kind, back):
    """Final gathering at a non-Lambert diffuse lobe weights each ray by f_d |cos| / pdf:
    a Lambert lobe's weight is its albedo exactly, and for every lobe the mean weight is
    the lobe's directional albedo (against the mean of f |cos| over uniformly distributed
    directions, another estimator of it); Translucent's rays go to the far side."""
    from core.materials import closure
    from core.scene import closures as cl
    rows = {"lambert": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=(0.8, 0.5, 0.2),
                                                                 roughness=0.0)),
            "translucent": dict(kind=cl.CLOSURE_TRANSLUCENT, params=dict(color=(0.8, 0.5, 0.2))),
            "sheen": dict(kind=cl.CLOSURE_SHEEN, params=dict(color=1.0, roughness=0.5)),
            "oren_nayar": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=0.9, roughness=1.0))}
    tab = closure.table(Materials.from_list([{"closures": [rows[kind]]}]))
    g = 40_000
    rng = np.random.default_rng(5)
    wo = np.array([[0.5, 0.0, np.sqrt(0.75)]])
    up = np.array([[0.0, 0.0, 1.0]])
    o, d, weight, ok = np.empty((g, 3)), np.empty((g, 3)), np.empty((g, 3)), np.empty(g, bool)
    gather._bsdf_gather_rays_kernel(tab, np.zeros(1, np.int32), np.ones((1, 3)), wo,
                                    closure.default_tangents(1), np.ones(1, bool),
                                    np.zeros(1), np.zeros((1, 3)), up, up, np.full(1, 1e-4),
                                    np.full(1, back), g, rng.random(g), rng.random(g), o, d,
                                    weight, ok)
    assert np.isfinite(weight).all() and (weight >= 0).all()
    below = d[:, 2] < 0
    if kind == "translucent":
        assert not ok[~below].any() and ok[below].all()
        assert (o[below, 2] < 0).all()
    else:
        assert not below.any()
    if kind == "lambert":
        np.testing.assert_allclose(weight[ok], np.tile([0.8, 0.5, 0.2], (ok.sum(), 1)),
                                   rtol=1e-6)  # the colour is stored as float32
    uniform = rng.normal(size=(200_000, 3))
    uniform /= np.linalg.norm(uniform, axis=1, keepdims=True)
    want = 4.0 * np.pi * closure.eval_many(tab, 0, wo[0], uniform, up[0], up[0],
                                           (1.0, 0.0, 0.0), True)[:, :3].mean(axis=0)
    np.testing.assert_allclose(weight.mean(axis=0), want, rtol=0.02)


def test_gather_rays_keep_the_camera_path_wavelength(rng):
    """docs/dispersion.md: a path stays at its wavelength once picked, its final-gather
    rays included. Diffuse points under a dispersive glass slab (parallel faces: every
    wavelength crosses it undeviated) inside a grey-lit grey sphere: gather rays of a path
    at 550 nm cross the slab at that wavelength, so the gathered light is grey (no
    wavelength weight); rays of RGB paths pick their own wavelengths at the slab, each
    weighted by its RGB weight (mean 1): tinted per point, the same light on average."""
    from core.prepared import prepare
    sphere = inward(shapes.uv_sphere([0, 0, 0], 5.0, 24, 48))
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [0.5, 0, 0], [0, 0.5, 0]), 0),
                            (shapes.box([-3, -3, 0.2], [3, 3, 0.25]), 1), (sphere, 0)])
    mats = Materials.from_list([{"diffuse": [0.5] * 3},
                                {"transmission": [1, 1, 1], "ior": 1.5, "dispersion": 20.0}])
    cam = shapes.pinhole([0, -2, 1], [0, 0, 0], 8, 8, 0.9)
    scene = Scene(mesh, mats, Lights.empty(), cam).validate()
    prepared = prepare(scene, 2, 0)
    pm = uniform_photons(sphere.corners, sphere.normals[:, 0], [1.0] * 3, 40_000, rng)
    terms = gather.PhotonTerms(caustic_map=None, global_map=pm, caustic_k=1, global_k=64,
                               caustic_radius=1.0, global_radius=1.0, filter="cone",
                               mode="final_gather", gather_rays=64)
    st = RenderSettings(samples=1, final_gather_rays=64, caustics=False)
    n = 24
    pos = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.zeros(n)])
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    args = (terms, prepared, st, pos, up, up, np.full(n, 1e-4), np.arange(n), np.zeros(n, int), 1)
    kept = gather.final_gather(*args, lam=np.full(n, 550.0))
    own = gather.final_gather(*args)
    assert np.isfinite(own).all() and kept.min() > 0 and own.min() >= 0
    np.testing.assert_allclose(kept[:, 0], kept[:, 2], rtol=1e-12)
    np.testing.assert_allclose(kept[:, 0], kept[:, 1], rtol=1e-12)
    assert np.abs(own[:, 0] / own[:, 2] - 1.0).max() > 0.05
    np.testing.assert_allclose(own.mean(axis=0), kept.mean(), rtol=0.1)

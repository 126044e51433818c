"""Media inside closed meshes through the renderer (core/media/regions.py and the terms of
core/integrators/volume.py, direct.py, gather.py, core/photons/medium_flight.py): exact
transmittance of camera and shadow segments through a box medium (camera outside and
inside it), the stretches of nested media, Volume Direct of a box against the
single-scattering integral, and a closed albedo-1 medium in a white furnace."""

import dataclasses

import numpy as np
import pytest

from core import sampling
from core.integrators import photon_mapping
from core.lights import kernels as light_kernels
from core.lights.light_set import LightSet
from core.media import regions
from core.media.single_scatter import inscatter_rays
from core.scene import camera as camera_mod
from core.scene import shapes
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, LIGHT_AREA, LIGHT_POINT, Camera, Lights,
                                 Materials, Mesh, Scene, SceneError, World)
from core.scene.media import Media
from core.settings import RenderSettings

pytestmark = pytest.mark.core

CAM_HEIGHT = 5.0
FAST = dict(samples=1, caustics=False, indirect_mode="off", threads=2)


def _box_medium(lo, hi, name="Box", **coefficients):
    return {"bounds": 0, "name": name, "boundary": shapes.box(lo, hi).corners, **coefficients}


def _floor_scene(material, lights=None, media=(), res=8, size=1.0, height=CAM_HEIGHT):
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0]), 0)],
                           names=("Floor",))
    cam = Camera(to_world=shapes.look_at([0, 0, height], [0, 0, 0], (0, 1, 0)), width=res,
                 height=res, film_size=np.array([size, size]), kind=CAMERA_ORTHOGRAPHIC)
    return Scene(mesh, Materials.from_list([material]), lights or Lights.empty(), cam,
                 media=Media.from_list(list(media))).validate()


@pytest.mark.parametrize("top", [2.0, 8.0], ids=["camera outside", "camera inside"])
def test_camera_segments_through_a_box_take_exp_minus_sigma_t_d_exactly(top):
    """An emissive floor seen straight down through an absorbing box medium (no surface:
    its faces are null interfaces) from z = 1 to ``top``: Emission = E exp(-sigma_t d), d
    the rays' length inside the box (1 m; with the camera inside the box, from the rays'
    start at the clip start down to z = 1)."""
    emission = np.array([1.0, 2.0, 3.0])
    sigma = np.array([0.05, 0.2, 0.6])
    mat = {"diffuse": [0, 0, 0], "emission": emission}
    scene = _floor_scene(mat, media=[_box_medium([-3, -3, 1], [3, 3, top], sigma_a=sigma)])
    out = photon_mapping.render(scene, RenderSettings(**FAST)).passes
    d = min(top, CAM_HEIGHT - scene.camera.clip_start) - 1.0
    want = emission * np.exp(-sigma * d)
    np.testing.assert_allclose(out["emission"], np.broadcast_to(want, (8, 8, 3)), rtol=1e-5)


def test_shadow_rays_through_a_slab_take_exp_minus_sigma_t_r_exactly():
    """A diffuse floor under a point light 1 m above it, an absorbing slab from z = 0.3 to
    0.6 between them (wider than every shadow ray's reach): Direct / the clear render's =
    exp(-sigma_t (0.3 + 0.3 r / 1)) for the very point each pixel's sample hit (the camera
    ray crosses 0.3 m of slab straight down, the shadow ray 0.3 m / cos)."""
    sigma = np.array([0.3, 0.9, 2.0])
    light_pos = np.array([0.2, -0.1, 1.0])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": light_pos, "power": 100.0}])
    mat = {"diffuse": [0.8, 0.8, 0.8]}
    st = RenderSettings(**FAST)
    slab = _box_medium([-20, -20, 0.3], [20, 20, 0.6], sigma_a=sigma)
    clear = _floor_scene(mat, lights)
    a = photon_mapping.render(clear, st).passes
    b = photon_mapping.render(_floor_scene(mat, lights, [slab]), st).passes
    pixel = np.arange(64, dtype=np.int64)
    jitter = np.stack(sampling.stratified2(st.seed, pixel, np.zeros(64, np.int64), 1,
                                           sampling.stream(sampling.PIXEL_JITTER)), axis=1)
    rays = camera_mod.generate_rays(clear.camera, pixel, jitter)
    t = -rays.origins[:, 2] / rays.directions[:, 2]
    hit = rays.origins + t[:, None] * rays.directions
    r = np.linalg.norm(hit - light_pos, axis=1)
    want = np.exp(-sigma[None, :] * (0.3 + 0.3 * r / 1.0)[:, None]).reshape(8, 8, 3)
    np.testing.assert_allclose(b["direct"] / a["direct"], want, rtol=2e-5)


def test_nested_and_overlapping_media_add_their_coefficients():
    """The stretches of rays through a World medium, a box and a smaller box inside it
    (Cycles' stack: every medium entered is active): the optical depths add per stretch,
    from outside and from a start inside both boxes."""
    media = Media.from_list([
        {"sigma_a": [0.1, 0.1, 0.1], "name": "Fog"},
        {"sigma_a": [1.0, 0.0, 0.0], "sigma_s": [0.0, 2.0, 0.0], "anisotropy": 0.5,
         "bounds": 0, "name": "Outer", "boundary": shapes.box([-2, -2, -2], [2, 2, 2]).corners},
        {"sigma_a": [0.0, 0.0, 3.0], "bounds": 0, "name": "Inner",
         "boundary": shapes.box([-1, -1, -1], [1, 1, 1]).corners}]).validate(1)
    m = regions.renderable(media, 4.0)
    o = np.array([[-5.0, 0.1, 0.2], [0.0, 0.1, 0.2]])
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    st = m.stretches(o, d, np.array([10.0, np.inf]))
    assert list(st.start) == [0, 5, 8]
    np.testing.assert_allclose(st.t0[:5], [0, 3, 4, 6, 7], atol=1e-5)
    np.testing.assert_allclose(st.t0[5:], [0, 1, 2], atol=1e-5)
    fog, outer, both = [0.1] * 3, [1.1, 2.1, 0.1], [1.1, 2.1, 3.1]
    np.testing.assert_allclose(st.sigma_t, [fog, outer, both, outer, fog, both, outer, fog],
                               atol=1e-6)
    # the phase: the sigma_s-weighted g (only Outer scatters)
    assert st.g[2] == pytest.approx(0.5) and st.g[0] == 0.0
    tau0 = 0.1 * 10 + np.array([1, 2, 0]) * 4 + np.array([0, 0, 3]) * 2
    np.testing.assert_allclose(st.through[0], np.exp(-tau0), rtol=1e-5)
    assert np.all(st.through[1] == 0)  # escaping into World fog
    m.close()


def test_a_medium_boundary_is_validated_by_name():
    with pytest.raises(SceneError, match="'Smoke'.*no boundary triangles"):
        Media.from_list([{"sigma_s": [1, 1, 1], "bounds": 0, "name": "Smoke"}]).validate(1)
    tri = shapes.box([0, 0, 0], [1, 1, 1]).corners
    with pytest.raises(SceneError, match="World's medium 'Fog' has no boundary"):
        Media.from_list([{"sigma_s": [1, 1, 1], "name": "Fog", "boundary": tri}]).validate(1)
    bad = tri.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(SceneError, match="media.boundary.*non-finite"):
        Media.from_list([{"bounds": 0, "name": "B", "boundary": bad}]).validate(1)


def test_volume_direct_of_a_box_matches_the_single_scattering_integral():
    """A point light inside a scattering box medium (vacuum outside, no World medium),
    camera rays crossing the box: Volume Direct = the equiangular reference integral of
    core/media/single_scatter.py over each ray's stretch inside the box (the shadow
    segments lie inside the convex box) within 1 %; rays that miss the box get 0."""
    sa, ss, g = np.array([0.05, 0.1, 0.2]), np.array([0.3, 0.2, 0.1]), 0.3
    lo, hi = np.array([-0.5, -1.0, -1.0]), np.array([3.0, 3.0, 5.0])
    light_pos = np.array([1.0, 0.5, 4.6])  # in the box, above the view: no ray passes near
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": light_pos, "power": 50.0,
                                "soft_falloff": False}])
    mesh = shapes.assemble([(shapes.quad([0, 0, -50], [1, 0, 0], [0, 1, 0]), 0)],
                           names=("Far",))
    cam = shapes.pinhole([0, -4, 2], [0, 0, 2], 8, 8, 0.7)
    box = _box_medium(lo, hi, sigma_a=sa, sigma_s=ss, anisotropy=g)
    scene = Scene(mesh, Materials.from_list([{"diffuse": [0, 0, 0]}]), lights, cam,
                  media=Media.from_list([box])).validate()
    st = RenderSettings(samples=16, light_samples=2, caustics=False, indirect_mode="off",
                        threads=2)
    out = photon_mapping.render(scene, st).passes
    vd = out["volume_direct"].astype(np.float64)
    assert np.all(np.isfinite(vd)) and vd.min() >= 0
    ls = LightSet.from_lights(lights)
    _, _, _, dist, l0, l1, l2, _, ok = light_kernels.sample_light(
        ls.params[0], *(light_pos + [0, 0, -1.0]), 0.5, 0.5)
    intensity = np.array([l0, l1, l2])
    pixel = np.repeat(np.arange(64, dtype=np.int64), 16)
    sample = np.tile(np.arange(16, dtype=np.int64), 64)
    jitter = np.stack(sampling.stratified2(st.seed, pixel, sample, 16,
                                           sampling.stream(sampling.PIXEL_JITTER)), axis=1)
    rays = camera_mod.generate_rays(cam, pixel, jitter)
    o, d = rays.origins.astype(np.float64), rays.directions.astype(np.float64)
    with np.errstate(divide="ignore"):  # slab method: the rays' entry and exit of the box
        ta, tb = (lo - o) / d, (hi - o) / d
    t_in = np.maximum(np.minimum(ta, tb).max(axis=1), 0.0)
    t_out = np.maximum(ta, tb).min(axis=1)
    inside = t_out > t_in
    assert 0.3 < inside.mean() < 0.9  # the left rays miss the box
    ref = np.zeros((pixel.shape[0], 3))
    ent = np.ascontiguousarray(o + t_in[:, None] * d)
    inscatter_rays(ent, d, np.where(inside, t_out - t_in, 0.0), light_pos, intensity, sa, ss,
                   g, 256, 3, ref)
    ref = ref.reshape(64, 16, 3).mean(axis=1).reshape(8, 8, 3)
    got = vd
    np.testing.assert_allclose(got.reshape(-1, 3).mean(axis=0), ref.reshape(-1, 3).mean(axis=0),
                               rtol=0.01)
    missed = ~inside.reshape(64, 16).any(axis=1).reshape(8, 8)
    assert np.all(got[missed] == 0)


def test_a_closed_albedo_one_medium_in_a_white_furnace_conserves_energy():
    """A scattering, non-absorbing box medium (sigma_s 1.5/m, 2 m deep, g = 0.3) under a
    uniform white World (radiance 1), nothing else: every camera ray, through the box or
    not, must see radiance 1 (what the box takes from the background it scatters back in
    from everywhere else). The image mean of Combined within 2 % of 1 per channel; the
    box's own pixels' Environment (background through it) is exp(-3) of it."""
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    box = _box_medium(lo, hi, sigma_s=[1.5, 1.5, 1.5], anisotropy=0.3)
    cam = Camera(to_world=shapes.look_at([0, -5, 0], [0, 0, 0], (0, 0, 1)), width=12,
                 height=12, film_size=np.array([1.6, 1.6]), kind=CAMERA_ORTHOGRAPHIC)
    mesh = dataclasses.replace(Mesh.empty(), object_names=("Box",))  # no surface at all
    scene = Scene(mesh, Materials.from_list([{"diffuse": [0, 0, 0]}]), Lights.empty(),
                  cam, world=World(radiance=np.ones(3, np.float32)),
                  media=Media.from_list([box])).validate()
    st = RenderSettings(samples=4, caustics=False, indirect_mode="preview",
                        global_photons=200_000, photon_max_bounces=256, threads=2, seed=5)
    out = photon_mapping.render(scene, st).passes
    comb = out["combined"].astype(np.float64)
    assert np.all(np.isfinite(comb)) and comb.min() >= 0
    np.testing.assert_allclose(comb.reshape(-1, 3).mean(axis=0), 1.0, rtol=0.02)
    np.testing.assert_allclose(out["environment"], np.exp(-3.0), rtol=1e-4)


@pytest.mark.parametrize("where", ["world fog", "fog box"])
def test_a_light_seen_through_fog_is_attenuated_to_the_light(where):
    """An area light (4 m x 4 m, facing down) seen from below through absorbing fog, with
    nothing behind it (the ray escapes): Emission = L exp(-sigma_t d), d the distance from
    the rays' start to the light (World fog) or the 1 m of a fog box in front of the light
    (it goes on 2 m behind it): not the transmittance to the escaping ray's end (0 in World
    fog, exp(-3 sigma_t) through the box) as before."""
    sigma = np.array([0.05, 0.2, 0.6])
    power, size = 100.0, 4.0
    lights = Lights.from_list([{"kind": LIGHT_AREA, "position": [0.0, 0.0, 0.0],
                                "power": power, "size": [size, size],
                                "visible_to_camera": True}])
    if where == "world fog":
        media = Media.from_list([{"sigma_a": sigma, "name": "Fog"}])
    else:
        # from 1 m in front of the light to 2 m behind it: only the first metre counts
        media = Media.from_list([_box_medium([-3, -3, -1], [3, 3, 2], sigma_a=sigma)])
    cam = Camera(to_world=shapes.look_at([0, 0, -CAM_HEIGHT], [0, 0, 0], (0, 1, 0)), width=8,
                 height=8, film_size=np.array([1.0, 1.0]), kind=CAMERA_ORTHOGRAPHIC)
    mesh = dataclasses.replace(Mesh.empty(), object_names=("Box",))
    scene = Scene(mesh, Materials.from_list([{"diffuse": [0, 0, 0]}]), lights, cam,
                  media=media).validate()
    out = photon_mapping.render(scene, RenderSettings(**FAST)).passes
    d = CAM_HEIGHT - scene.camera.clip_start if where == "world fog" else 1.0
    radiance = power / (np.pi * size * size)
    np.testing.assert_allclose(out["emission"], np.broadcast_to(radiance * np.exp(-sigma * d),
                                                                (8, 8, 3)), rtol=1e-5)


def test_stretches_know_where_the_scattering_ends():
    """bound0 / bound1: |cos| of the plane where a scattering medium ends at a stretch's
    start / end (a box face with nothing beyond, or the opaque surface end_cos names), NaN
    where a scattering medium goes on (World fog around the box) or nothing is given."""
    box = Media.from_list([{"sigma_s": [1.0, 1.0, 1.0], "bounds": 0, "name": "Box",
                            "boundary": shapes.box([-1, -1, -1], [1, 1, 1]).corners}])
    m = regions.renderable(box.validate(1), 4.0)
    slant = np.array([0.6, 0.0, 0.8])  # leaves through z = 1 at |cos| 0.8
    o = np.array([[-5.0, 0.1, 0.2], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    d = np.array([[1.0, 0.0, 0.0], slant, [0.0, 0.0, -1.0]])
    st = m.stretches(o, d, np.array([10.0, np.inf, 0.5]), np.array([0.3, 0.3, 0.7]))
    assert list(st.start) == [0, 3, 5, 6]
    # through the box: it scatters on the middle stretch, bounded by the faces x = -1, 1
    np.testing.assert_allclose([st.bound0[1], st.bound1[1]], 1.0)
    assert np.isnan(st.bound0[0])  # the segment's start: nothing known
    np.testing.assert_allclose(st.bound1[2], 0.3)  # the opaque end past the box
    # from inside, out through the top face at |cos| 0.8, escaping after it
    assert np.isnan(st.bound0[3])
    np.testing.assert_allclose(st.bound1[3], 0.8, rtol=1e-6)
    # ending on an opaque surface inside the box
    np.testing.assert_allclose(st.bound1[5], 0.7)
    m.close()
    world = Media.from_list([
        {"sigma_s": [0.1, 0.1, 0.1], "name": "Fog"},
        {"sigma_s": [1.0, 1.0, 1.0], "bounds": 0, "name": "Box",
         "boundary": shapes.box([-1, -1, -1], [1, 1, 1]).corners}]).validate(1)
    m = regions.renderable(world, 4.0)
    st = m.stretches(o[:1], d[:1], np.array([10.0]))
    assert np.all(np.isnan(st.bound0)) and np.all(np.isnan(st.bound1))  # fog goes on
    m.close()

"""The camera pass end to end: mirrors, glass, passes, scale invariance, determinism,
cancelling and degenerate scenes."""

import numpy as np
import pytest

from core.materials import bsdf
from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, Camera,
                        Lights, Materials, Mesh, Scene, SceneError, World)
from core.settings import RenderSettings, SettingsError


def ortho_camera(eye, target, size, res=16, up=(0, 0, 1)):
    return Camera(to_world=shapes.look_at(eye, target, up), width=res, height=res,
                  film_size=np.array([size, size]), kind=CAMERA_ORTHOGRAPHIC)


def facing(part, normal):
    """Flip a part so its winding normal points along ``normal``."""
    if np.dot(part.normals[0, 0], normal) >= 0:
        return part
    return shapes.Part(part.corners[:, ::-1], -part.normals)


# --- mirrors ------------------------------------------------------------------------------

def test_mirror_plane_shows_the_red_wall_with_its_tint():
    # Camera looks along +Y at a mirror tilted 45 degrees; the reflection goes up (+Z) to a
    # red emitter. The mirror fills the view.
    mirror = shapes.quad([0, 2, 0], [1, 0, 0], [0, 1, 1])  # normal (0, -1, 1)/sqrt2
    mirror = facing(mirror, [0, -1, 1])
    red = facing(shapes.quad([0, 2, 3], [3, 0, 0], [0, 3, 0]), [0, 0, -1])
    mats = Materials.from_list([{"specular": [0.9, 0.8, 0.7]}, {"emission": [2.0, 0.1, 0.0]}])
    scene = Scene(shapes.assemble([(mirror, 0), (red, 1)]), mats, Lights.empty(),
                  ortho_camera([0, -1, 0], [0, 2, 0], 0.5))
    out = integrator.render(scene, RenderSettings(samples=2, max_specular_depth=1))
    exp = np.array([0.9, 0.8, 0.7]) * [2.0, 0.1, 0.0]
    np.testing.assert_allclose(out.passes["specular"], np.broadcast_to(exp, (16, 16, 3)), rtol=1e-6)
    assert np.all(out.passes["direct"] == 0) and np.all(out.passes["emission"] == 0)
    # With no specular bounces allowed the mirror is black.
    out0 = integrator.render(scene, RenderSettings(samples=2, max_specular_depth=0))
    assert np.all(out0.passes["combined"] == 0)


def test_mirror_sphere_centre_reflects_what_is_behind_the_camera():
    sphere = shapes.uv_sphere([0, 0, 0], 1.0, rings=48, segments=96)
    behind = facing(shapes.quad([0, -6, 0], [4, 0, 0], [0, 0, 4]), [0, 1, 0])
    mats = Materials.from_list([{"specular": [0.8, 0.8, 0.8]}, {"emission": [1.0, 0.0, 0.0]}])
    cam = shapes.pinhole([0, -4, 0], [0, 0, 0], 9, 9, np.radians(10))
    scene = Scene(shapes.assemble([(sphere, 0), (behind, 1)]), mats, Lights.empty(), cam)
    img = integrator.render(scene, RenderSettings(samples=4)).passes["specular"]
    np.testing.assert_allclose(img[4, 4], [0.8, 0.0, 0.0], rtol=1e-5)


def test_area_light_seen_in_a_mirror_follows_its_glossy_visibility():
    mirror = facing(shapes.quad([0, 2, 0], [1, 0, 0], [0, 1, 1]), [0, -1, 1])
    light = {"kind": LIGHT_AREA, "position": [0, 2, 3], "power": 10.0, "size": [4.0, 4.0]}
    cam = ortho_camera([0, -1, 0], [0, 2, 0], 0.5)
    mats = Materials.from_list([{"specular": [0.5, 0.5, 0.5]}])
    mesh = shapes.assemble([(mirror, 0)])
    seen = integrator.render(Scene(mesh, mats, Lights.from_list([light]), cam), RenderSettings(samples=1))
    np.testing.assert_allclose(seen.passes["specular"], 0.5 * 10.0 / (np.pi * 16.0), rtol=1e-6)
    hidden = Lights.from_list([{**light, "visible_to_glossy": False}])
    out = integrator.render(Scene(mesh, mats, hidden, cam), RenderSettings(samples=1))
    assert np.all(out.passes["combined"] == 0)


# --- glass --------------------------------------------------------------------------------

def glass_slab_scene(ior):
    slab = shapes.box([-2, -0.1, -2], [2, 0.1, 2])  # closed, normals outward
    backdrop = facing(shapes.quad([0, 3, 0], [5, 0, 0], [0, 0, 5]), [0, -1, 0])
    mats = Materials.from_list([{"transmission": [1, 1, 1], "ior": ior}, {"emission": [1, 1, 1]}])
    return Scene(shapes.assemble([(slab, 0), (backdrop, 1)]), mats, Lights.empty(),
                 ortho_camera([0, -2, 0], [0, 0, 0], 1.0))


@pytest.mark.parametrize("depth", [2, 4, 20])
def test_glass_slab_at_normal_incidence(depth):
    """Transmitted paths bounce 2 + 2k times and carry (1 - F)^2 F^(2k): with depth 2 the
    slab passes exactly (1 - F)^2; with many bounces (1 - F)^2 / (1 - F^2)."""
    n = 2.4  # diamond: F = 0.17, so the internal reflections are visible in the sum
    f = ((n - 1) / (n + 1)) ** 2
    kmax = (depth - 2) // 2
    exact = (1 - f) ** 2 * sum(f ** (2 * k) for k in range(kmax + 1))
    out = integrator.render(glass_slab_scene(n), RenderSettings(samples=64, max_specular_depth=depth))
    img = out.passes["specular"]
    assert img.mean() == pytest.approx(exact, rel=0.005)
    assert np.all(out.passes["direct"] == 0)
    if depth == 2:
        assert exact == pytest.approx((1 - f) ** 2)
        assert not img.mean() == pytest.approx((1 - f) ** 2 / (1 - f * f), rel=0.005)


def test_glass_sphere_total_internal_reflection_keeps_energy_bounded():
    sphere = shapes.uv_sphere([0, 0, 0], 1.0, rings=32, segments=64)
    mats = Materials.from_list([{"transmission": [1, 1, 1], "ior": 1.5}])
    world = World(radiance=np.array([1.0, 1.0, 1.0], np.float32), visible_to_camera=True)
    cam = shapes.pinhole([0, -4, 0], [0, 0, 0], 16, 16, np.radians(35))
    out = integrator.render(Scene(shapes.assemble([(sphere, 0)]), mats, Lights.empty(), cam, world),
                            RenderSettings(samples=16, max_specular_depth=12))
    # A lossless dielectric in a uniform white world: every path ends in the world (or is
    # cut by the depth limit), so the expected radiance is at most 1.
    img = out.passes["combined"]
    assert np.all(np.isfinite(img)) and np.all(img >= 0)
    # (Single samples may exceed 1: refraction picked with probability 7/8 < 1 - F.)
    assert 0.97 < img.mean() < 1.005


# --- the passes on a small Cornell box -----------------------------------------------------

def cornell(scale=1.0, offset=(0.0, 0.0, 0.0), res=24, world=0.0):
    """A 2 m room open at the front with red and green walls, a mirror sphere, a glass sphere, a diffuse
    cube, an area light, a sphere light, a spot light and an emissive panel."""
    s = float(scale)
    o = np.asarray(offset, np.float64)
    room = shapes.box([-1, -1, 0], [1, 1, 2], inward=True)
    c = room.corners
    left = np.all(np.isclose(c[:, :, 0], -1), axis=1)
    right = np.all(np.isclose(c[:, :, 0], 1), axis=1)
    front = np.all(np.isclose(c[:, :, 1], -1), axis=1)  # open towards the camera
    rest = ~(left | right | front)
    white = shapes.Part(c[rest], room.normals[rest])
    red = shapes.Part(c[left], room.normals[left])
    green = shapes.Part(c[right], room.normals[right])
    mirror = shapes.uv_sphere([-0.45, 0.3, 0.4], 0.4, 16, 32)
    glass = shapes.uv_sphere([0.45, -0.2, 0.4], 0.4, 16, 32)
    cube = shapes.box([-0.2, -0.7, 0.0], [0.2, -0.3, 0.3])
    panel = facing(shapes.quad([0.7, 0.7, 1.99], [0.1, 0, 0], [0, 0.1, 0]), [0, 0, -1])
    parts = [(white, 0), (red, 1), (green, 2), (mirror, 3), (glass, 4), (cube, 0), (panel, 5)]
    parts = [(shapes.transform(p, s, o), m) for p, m in parts]
    mats = Materials.from_list([
        {"diffuse": [0.75, 0.75, 0.75]}, {"diffuse": [0.75, 0.1, 0.1]}, {"diffuse": [0.1, 0.75, 0.1]},
        {"specular": [0.95, 0.95, 0.95]}, {"transmission": [1, 1, 1], "ior": 1.5},
        {"emission": [4.0, 3.0, 2.0]}])
    p2 = s * s  # powers scale with area to keep irradiance
    lit = Lights.from_list([
        {"kind": LIGHT_AREA, "position": o + s * np.array([0, 0, 1.98]), "power": 20.0 * p2, "size": [0.5 * s, 0.5 * s]},
        {"kind": LIGHT_POINT, "position": o + s * np.array([-0.5, -0.5, 1.6]), "power": 5.0 * p2,
         "radius": 0.15 * s, "soft_falloff": False},
        {"kind": LIGHT_SPOT, "to_world": _spot_matrix(o + s * np.array([0.8, -0.8, 1.5]), o + s * np.array([0, 0, 0])),
         "power": 10.0 * p2, "spot_size": np.radians(50), "radius": 0.02 * s},
    ])
    cam = shapes.pinhole(o + s * np.array([0, -3.4, 1.0]), o + s * np.array([0, 0, 1.0]), res, res, np.radians(40))
    cam = Camera(to_world=cam.to_world, width=res, height=res, film_size=cam.film_size,
                 clip_start=0.01 * s, clip_end=100.0 * s)
    return Scene(shapes.assemble([(p, m) for p, m in parts]), mats, lit, cam,
                 World(radiance=np.full(3, world, np.float32)))


def _spot_matrix(pos, target):
    return shapes.look_at(pos, target)


@pytest.fixture(scope="module")
def cornell_render():
    return integrator.render(cornell(), RenderSettings(samples=8, seed=3))


def test_passes_sum_to_combined_exactly(cornell_render):
    p = cornell_render.passes
    assert set(integrator.PASSES) | {"combined"} == set(p)
    total = sum(p[k].astype(np.float64) for k in integrator.PASSES).astype(np.float32)
    np.testing.assert_array_equal(p["combined"], total)
    for k, v in p.items():
        assert v.shape == (24, 24, 3) and v.dtype == np.float32, k
        assert np.all(np.isfinite(v)) and np.all(v >= 0), k
    # Every term shows up in this scene.
    assert p["direct"].mean() > 0 and p["specular"].mean() > 0 and p["emission"].max() > 0
    assert p["caustics"].mean() > 0 and p["indirect"].mean() > 0
    stats = cornell_render.stats
    assert stats["caustic_photons_stored"] > 0 and stats["global_photons_stored"] > 0
    assert stats["skipped"] == {} and stats["rays_gather"] > 0
    assert cornell_render.stats["rays_shadow"] > 0 and cornell_render.stats["rays_specular"] > 0
    assert not cornell_render.cancelled


def test_deterministic_for_a_seed_whatever_the_tiling_and_threads(cornell_render, monkeypatch):
    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 40)
    again = integrator.render(cornell(), RenderSettings(samples=8, seed=3, threads=1))
    assert again.stats["tiles"] > 5
    for k, v in cornell_render.passes.items():
        np.testing.assert_array_equal(again.passes[k], v, err_msg=k)
    other = integrator.render(cornell(), RenderSettings(samples=8, seed=4))
    assert not np.array_equal(other.passes["combined"], cornell_render.passes["combined"])


def _blocks(x):
    h = x.shape[0] // 8 * 8
    return x[:h, :h].reshape(h // 8, 8, h // 8, 8, 3).mean(axis=(1, 3))


@pytest.fixture(scope="module")
def cornell_noise(cornell_render):
    """How much the reference differs from itself with another seed: the noise level."""
    a = cornell_render.passes["combined"]
    b = integrator.render(cornell(), RenderSettings(samples=8, seed=103)).passes["combined"]
    return {"mean": np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))).max(),
            "block": np.abs(_blocks(a) - _blocks(b)).max(),
            "rms": np.sqrt(np.mean((a - b) ** 2))}


def _within_noise(image, reference, noise):
    """Differences (same seed) no larger than the seed-to-seed noise of the reference."""
    assert np.abs(image.mean(axis=(0, 1)) - reference.mean(axis=(0, 1))).max() <= noise["mean"]
    assert np.abs(_blocks(image) - _blocks(reference)).max() <= noise["block"]
    assert np.sqrt(np.mean((image - reference) ** 2)) <= noise["rms"]


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_scale_invariance(cornell_render, cornell_noise, scale):
    ref = cornell_render.passes["combined"]
    out = integrator.render(cornell(scale=scale), RenderSettings(samples=8, seed=3))
    _within_noise(out.passes["combined"], ref, cornell_noise)
    # The offsets scale with the scene: the very same camera paths are traced, and the
    # automatic gather radii scale with it.
    base = cornell_render
    for name in ("emission", "environment", "direct"):
        np.testing.assert_allclose(out.passes[name].mean(axis=(0, 1)),
                                   base.passes[name].mean(axis=(0, 1)), rtol=1e-4, atol=1e-9)
    for key in ("caustic_radius", "global_radius"):
        assert out.stats[key] == pytest.approx(scale * base.stats[key], rel=1e-4), key
    # The photon maps are the same but for a handful of photons whose float32 paths
    # round differently at another magnitude (1 of 380,000 at 1e-3).
    assert abs(out.stats["global_photons_stored"] - base.stats["global_photons_stored"]) <= 10
    np.testing.assert_allclose(out.passes["combined"].mean(axis=(0, 1)), ref.mean(axis=(0, 1)),
                               rtol=5e-4)


def test_translation_invariance(cornell_render, cornell_noise):
    # Photons at 1e3 m: float32 resolves 0.06 mm there and the ray offsets are 1 mm.
    out = integrator.render(cornell(offset=(1e3, 1e3, 1e3)), RenderSettings(samples=8, seed=3))
    _within_noise(out.passes["combined"], cornell_render.passes["combined"], cornell_noise)


def test_translation_invariance_of_the_camera_pass():
    # float32 resolves 1 mm at 1e4 m: the geometry itself moves by that much, so
    # only "within noise" can hold (bright lights seen through glass shift by a pixel).
    # The photon terms are left out at 1e4 m: the ray offsets (1 cm there) exceed the
    # gap between the glass sphere and the floor through which its caustic leaves, so
    # ~8 % of the caustic photons are lost; at 1e3 m (above) the offsets are 1 mm.
    camera_only = dict(samples=8, seed=3, caustics=False, indirect_mode="off")
    out = integrator.render(cornell(offset=(1e4, 1e4, 1e4)), RenderSettings(**camera_only))
    ref = integrator.render(cornell(), RenderSettings(**camera_only)).passes["combined"]
    # The noise of the camera pass alone (the photon terms add their own).
    other = integrator.render(cornell(), RenderSettings(**{**camera_only, "seed": 103}))
    b = other.passes["combined"]
    noise = {"mean": np.abs(ref.mean(axis=(0, 1)) - b.mean(axis=(0, 1))).max(),
             "block": np.abs(_blocks(ref) - _blocks(b)).max(), "rms": np.sqrt(np.mean((ref - b) ** 2))}
    assert out.stats["skipped"].keys() == {"caustics", "indirect"}
    _within_noise(out.passes["combined"], ref, noise)


# --- progress and cancelling ----------------------------------------------------------------

def test_progress_is_reported_and_cancel_stops_early(monkeypatch):
    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 64)
    calls = []

    def progress(fraction, message):
        calls.append((fraction, message))

    def stop():
        # Cancel at the second tile of the camera pass (the photon pass reports first).
        return sum(m.startswith("Gathering") for _, m in calls) >= 2

    out = integrator.render(cornell(res=16), RenderSettings(samples=4), on_progress=progress,
                            should_stop=stop)
    tiles = [f for f, m in calls if m.startswith("Gathering")]
    photons = [f for f, m in calls if not m.startswith("Gathering")]
    assert out.cancelled and len(tiles) == 2
    assert photons and all(0 < f <= integrator.PHOTON_SHARE for f in photons)
    assert integrator.PHOTON_SHARE < tiles[0] < tiles[1] < 1
    assert "tile 1 of" in calls[len(photons)][1]
    done = out.stats["pixels"]
    assert 0 < done < 256
    flat = out.passes["combined"].reshape(-1, 3)
    assert np.all(flat[done:] == 0) and flat[:done].max() > 0
    full = []
    out = integrator.render(cornell(res=16), RenderSettings(samples=4),
                            on_progress=lambda f, m: full.append(f),
                            should_stop=lambda: False)
    assert not out.cancelled and full[-1] == 1.0 and full == sorted(full)


def test_cancel_during_the_photon_pass_renders_nothing():
    calls = []
    out = integrator.render(cornell(res=16), RenderSettings(samples=4),
                            on_progress=lambda f, m: calls.append(m), should_stop=lambda: True)
    assert out.cancelled and len(calls) == 1 and out.stats["pixels"] == 0
    assert all(np.all(v == 0) for v in out.passes.values())


# --- degenerate scenes ------------------------------------------------------------------------

def test_empty_scene_shows_the_background_or_black():
    cam = ortho_camera([0, -1, 0], [0, 0, 0], 1.0, res=4)
    empty = Scene(Mesh.empty(), Materials.from_list([]), Lights.empty(), cam)
    out = integrator.render(empty, RenderSettings(samples=2))
    assert all(np.all(v == 0) for v in out.passes.values())
    sky = Scene(Mesh.empty(), Materials.from_list([]), Lights.empty(), cam,
                World(radiance=np.array([0.1, 0.2, 0.3], np.float32)))
    out = integrator.render(sky, RenderSettings(samples=2))
    np.testing.assert_allclose(out.passes["environment"], np.broadcast_to([0.1, 0.2, 0.3], (4, 4, 3)), rtol=1e-6)
    hidden = Scene(Mesh.empty(), Materials.from_list([]), Lights.empty(), cam,
                   World(radiance=np.array([0.1, 0.2, 0.3], np.float32), visible_to_camera=False))
    assert np.all(integrator.render(hidden, RenderSettings(samples=1)).passes["combined"] == 0)


def test_no_lights_gives_a_black_image():
    scene = cornell(res=8)
    mats = Materials(**{**scene.materials.__dict__, "emission": np.zeros_like(scene.materials.emission)})
    out = integrator.render(Scene(scene.mesh, mats, Lights.empty(), scene.camera, scene.world),
                            RenderSettings(samples=2))
    assert all(np.all(v == 0) for v in out.passes.values())
    # The emissive panel alone still lights the room (emissive triangles are lights too).
    panel_only = Scene(scene.mesh, scene.materials, Lights.empty(), scene.camera, scene.world)
    assert integrator.render(panel_only, RenderSettings(samples=2)).passes["direct"].mean() > 0


def test_zero_area_triangles_render_without_nan():
    good = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    corners = np.concatenate([good.corners, np.zeros((3, 3, 3)), np.array([[[0, 0, 0.1], [0.5, 0.5, 0.1], [1, 1, 0.1]]])])
    normals = np.concatenate([good.normals, np.zeros((4, 3, 3))])
    mesh = shapes.assemble([(shapes.Part(corners, normals), 0)])
    li = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.2, 0.1, 1.0], "power": 10.0}])
    scene = Scene(mesh, Materials.from_list([{"diffuse": [0.5, 0.5, 0.5], "specular": [0.2, 0.2, 0.2], "roughness": 0.3}]),
                  li, ortho_camera([0, 0, 2], [0, 0, 0], 2.2, res=8, up=(0, 1, 0)))
    out = integrator.render(scene, RenderSettings(samples=4))
    for v in out.passes.values():
        assert np.all(np.isfinite(v)) and np.all(v >= 0)
    assert out.passes["direct"].max() > 0


def test_bad_input_raises_clear_errors():
    scene = cornell(res=4)
    with pytest.raises(SettingsError, match='"samples"'):
        integrator.render(scene, RenderSettings(samples=0))
    bad = scene.lights.to_world.copy()
    bad[1, 0, 3] = np.nan
    lights = Lights(**{**scene.lights.__dict__, "to_world": bad})
    with pytest.raises(SceneError, match="lights.to_world"):
        integrator.render(Scene(scene.mesh, scene.materials, lights, scene.camera), RenderSettings(samples=1))


# --- glossy and emissive direct light, checked by hand --------------------------------------

def test_glossy_lobe_under_a_point_light():
    """Centre pixel of a plane with a GGX lobe: f * cos * I / r^2 with f = spec * GGX."""
    alpha = 0.3
    plane = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"specular": [0.6, 0.6, 0.6], "roughness": np.sqrt(alpha)}])
    light = np.array([0.6, 0.0, 1.0])
    eye = np.array([-0.6, 0.0, 1.0])
    cam = Camera(to_world=shapes.look_at(eye, [0, 0, 0]), width=1, height=1,
                 film_size=np.array([1e-4, 1e-4]), kind=CAMERA_ORTHOGRAPHIC)
    scene = Scene(shapes.assemble([(plane, 0)]), mats,
                  Lights.from_list([{"kind": LIGHT_POINT, "position": light, "power": 40.0}]), cam)
    img = integrator.render(scene, RenderSettings(samples=1)).passes["direct"][0, 0]
    wi = light / np.linalg.norm(light)
    wo = eye / np.linalg.norm(eye)
    f = bsdf.ggx_brdf(alpha, np.array([[0, 0, 1.0]]), wo[None], wi[None])[0]
    # Mirror configuration: h = n, D = 1 / (pi alpha^2).
    d = 1 / (np.pi * alpha ** 2)
    lam = 0.5 * (np.sqrt(1 + alpha ** 2 * (1 - wi[2] ** 2) / wi[2] ** 2) - 1)
    assert f == pytest.approx(d / (4 * wi[2] * wo[2] * (1 + 2 * lam)), rel=1e-9)
    exp = 0.6 * f * wi[2] * 40.0 / (4 * np.pi) / np.dot(light, light)
    np.testing.assert_allclose(img, exp, rtol=1e-4)


def test_emissive_panel_is_seen_and_lights_the_floor():
    panel = facing(shapes.quad([0, 0, 1], [0.25, 0, 0], [0, 0.25, 0]), [0, 0, -1])
    floor = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
    mats = Materials.from_list([{"emission": [3.0, 2.0, 1.0]}, {"diffuse": [0.5, 0.5, 0.5]}])
    cam = Camera(to_world=shapes.look_at([0, 0, 0.5], [0, 0, 0], up=(0, 1, 0)), width=1, height=1,
                 film_size=np.array([1e-3, 1e-3]), kind=CAMERA_ORTHOGRAPHIC)
    scene = Scene(shapes.assemble([(panel, 0), (floor, 1)]), mats, Lights.empty(), cam)
    out = integrator.render(scene, RenderSettings(samples=64, light_samples=4))
    # Below the centre of a 0.5 x 0.5 square at height 1 (closed form of the form factor).
    x = 0.25
    ff = 4 * (x / np.sqrt(1 + x * x) * np.arctan(x / np.sqrt(1 + x * x))) * 2 / (2 * np.pi)
    exp = 0.5 * np.array([3.0, 2.0, 1.0]) * ff  # albedo * L * pi * F / pi
    np.testing.assert_allclose(out.passes["direct"][0, 0], exp, rtol=0.01)
    up = Camera(to_world=shapes.look_at([0, 0, 0.5], [0, 0, 1], up=(0, 1, 0)), width=2, height=2,
                film_size=np.array([0.1, 0.1]), kind=CAMERA_ORTHOGRAPHIC)
    seen = integrator.render(Scene(scene.mesh, mats, Lights.empty(), up), RenderSettings(samples=1))
    np.testing.assert_allclose(seen.passes["emission"], np.broadcast_to([3.0, 2.0, 1.0], (2, 2, 3)))


# --- pass selection and partial images (issue 6) -----------------------------------------------

def test_switched_off_passes_are_neither_kept_nor_returned_but_stay_in_combined(cornell_render):
    """Same seed, some passes off: the kept passes and combined are the very same images
    (every term still reaches combined), the others are absent, and the tile loop kept
    one accumulator for all of them instead of one each."""
    off = ("emission", "specular", "indirect")
    out = integrator.render(cornell(), RenderSettings(samples=8, seed=3).with_values(
        **{f"pass_{name}": False for name in off}))
    assert set(out.passes) == {"combined", "environment", "direct", "caustics"}
    assert out.stats["passes_produced"] == ("environment", "direct", "caustics")
    assert out.stats["pass_buffers"] == 4 and cornell_render.stats["pass_buffers"] == 6
    for name in out.passes:
        np.testing.assert_allclose(out.passes[name], cornell_render.passes[name],
                                   rtol=1e-6, atol=1e-7, err_msg=name)
    # Combined minus the kept passes is the sum of the switched-off ones.
    rest = out.passes["combined"].astype(np.float64) - sum(
        out.passes[k].astype(np.float64) for k in ("environment", "direct", "caustics"))
    expected = sum(cornell_render.passes[k].astype(np.float64) for k in off)
    np.testing.assert_allclose(rest, expected, rtol=1e-5, atol=1e-6)
    assert "photons" not in out.passes and "time_overlay" not in out.stats


def test_all_light_passes_off_keeps_only_combined():
    scene = cornell(res=8)
    base = RenderSettings(samples=2, seed=1, global_photons=2000, caustic_photons=2000,
                          final_gather_rays=4)
    none = integrator.render(scene, base.with_values(**{f"pass_{p}": False
                                                        for p in integrator.PASSES}))
    full = integrator.render(scene, base)
    assert set(none.passes) == {"combined"} and none.stats["pass_buffers"] == 1
    np.testing.assert_allclose(none.passes["combined"], full.passes["combined"], rtol=1e-6,
                               atol=1e-7)


def test_pass_switches_are_validated_by_name():
    assert RenderSettings().passes() == integrator.LIGHT_PASSES
    with pytest.raises(SettingsError, match='"pass_direct"'):
        RenderSettings().with_values(pass_direct=1)
    assert RenderSettings().with_strings({"pass_caustics": "off"}).passes() == (
        "emission", "environment", "direct", "specular", "indirect", "volume_direct",
        "volume_indirect")


def test_on_tile_shows_the_image_filling_in(monkeypatch):
    """Partial images: the rows done are the final pixels, the rest still 0; throttled
    to one call per UPDATE_SECONDS and by the calls' cost (neither here: every tile but
    the last)."""
    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 64)
    monkeypatch.setattr(integrator, "UPDATE_SECONDS", 0.0)
    monkeypatch.setattr(integrator, "UPDATE_SHARE", float("inf"))  # no cost-based wait
    scene = cornell(res=16)
    settings = RenderSettings(samples=4, seed=2, global_photons=4000, caustic_photons=4000,
                              final_gather_rays=8, pass_specular=False)
    updates = []
    out = integrator.render(scene, settings,
                            on_tile=lambda done, passes: updates.append((done, passes)))
    assert len(updates) == out.stats["tiles"] - 1 >= 2
    assert [d for d, _ in updates] == sorted(d for d, _ in updates)
    for done, passes in updates:
        assert set(passes) == set(out.passes)
        for name, image in passes.items():
            flat, final = image.reshape(-1, 3), out.passes[name].reshape(-1, 3)
            np.testing.assert_array_equal(flat[:done], final[:done], err_msg=name)
            assert np.all(flat[done:] == 0), name
    # Throttled by time: a long interval, no call in a quick render.
    monkeypatch.setattr(integrator, "UPDATE_SECONDS", 3600.0)
    few = []
    integrator.render(scene, settings, on_tile=lambda d, p: few.append(d))
    assert few == []
    # ... and by cost: a callback taking 50 ms with a 50% share waits >= 100 ms after each.
    # On a clock of the test's own (each reading 1 ms later, ~10 ms a tile; the
    # callback 50 ms more), so the gaps do not depend on how fast this machine renders.
    # Unthrottled by cost, a gap would be one callback and one tile: well under 100 ms.
    class Clock:
        now = 0.0

        def perf_counter(self):
            self.now += 1e-3
            return self.now

    clock = Clock()
    monkeypatch.setattr(integrator, "time", clock)
    monkeypatch.setattr(integrator, "UPDATE_SECONDS", 0.0)
    monkeypatch.setattr(integrator, "UPDATE_SHARE", 0.5)
    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 8)  # tiles of <= 8 pixels: many
    stamps = []

    def slow_callback(done, passes):
        stamps.append(clock.perf_counter())
        clock.now += 0.05

    out = integrator.render(scene, settings, on_tile=slow_callback)
    gaps = np.diff(stamps)
    assert len(stamps) >= 2 and gaps.min() >= 0.1, gaps
    # ... and not a second wait longer.
    assert gaps.max() < 0.2, gaps


def test_progressive_settings_are_validated_by_name():
    s = RenderSettings()
    assert (s.integrator, s.time_budget) == ("photon_map", 0.0)
    for name, bad in (("integrator", "sppm"), ("progressive_passes", 0),
                      ("photons_per_pass", 1 << 27), ("time_budget", -1.0),
                      ("time_budget", float("nan")), ("time_budget", True)):
        with pytest.raises(SettingsError, match=f'"{name}"'):
            s.with_values(**{name: bad})
    assert s.with_strings({"integrator": "progressive", "time_budget": "2.5"}).time_budget == 2.5


# --- the Render Region (issue 11 part 3) ------------------------------------------------------

@pytest.mark.parametrize("integrator_name", ["photon_map", "progressive"])
def test_a_region_is_exactly_those_pixels_of_the_whole_render(integrator_name):
    """Every pass of a region render equals the same pixels of the whole frame, bit for
    bit (each pixel is traced from its frame index with the same random numbers), and
    only the region's pixels are rendered (photon_map)."""
    import dataclasses
    from core import render
    from tests.core.test_extremes import box_scene
    scene = box_scene()
    cam = dataclasses.replace(scene.camera, width=20, height=14)
    whole = dataclasses.replace(scene, camera=cam)
    part = dataclasses.replace(scene, camera=dataclasses.replace(cam, region=(3, 5, 11, 9)))
    st = RenderSettings(seed=3, samples=2, global_photons=3000, caustic_photons=2000,
                        final_gather_rays=8, photon_debug_pass=True, integrator=integrator_name,
                        progressive_passes=3, photons_per_pass=2000)
    full = render(whole, st)
    cut = render(part, st)
    assert set(cut.passes) == set(full.passes)
    for name, image in cut.passes.items():
        assert image.shape[:2] == (4, 8), name
        np.testing.assert_array_equal(image, full.passes[name][5:9, 3:11], err_msg=name)
    if integrator_name == "photon_map":
        assert cut.stats["pixels"] == 32 and full.stats["pixels"] == 280
        assert cut.stats["rays_camera"] < full.stats["rays_camera"] / 4
    else:  # visible points of the region's pixels only
        assert max(cut.stats["visible_points"]) <= 32 < min(full.stats["visible_points"])


# --- lights are not occluders ---------------------------------------------------------------

def test_area_light_does_not_hide_the_ceiling_behind_it():
    # Cycles' lights are transparent to rays: a camera looking up at an area light (facing
    # down, 0.1 below an emissive ceiling) sees the light's radiance plus the ceiling's.
    ceiling = facing(shapes.quad([0, 0, 2], [3, 0, 0], [0, 3, 0]), [0, 0, -1])
    mats = Materials.from_list([{"emission": [0.25, 0.5, 1.0]}])
    light = {"kind": LIGHT_AREA, "position": [0, 0, 1.9], "power": 40.0, "size": [2.0, 2.0],
             "visible_to_camera": True}
    cam = ortho_camera([0, 0, 0], [0, 0, 2], 0.5, res=4, up=(0, 1, 0))
    scene = Scene(shapes.assemble([(ceiling, 0)]), mats, Lights.from_list([light]), cam)
    out = integrator.render(scene, RenderSettings(samples=1, indirect_mode="off", caustics=False))
    radiance = 40.0 / (np.pi * 4.0)
    np.testing.assert_allclose(out.passes["emission"],
                               np.broadcast_to(radiance + np.array([0.25, 0.5, 1.0]), (4, 4, 3)),
                               rtol=1e-6)

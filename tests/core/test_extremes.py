"""Stability at the numerical extremes (issue 7, point 4): scale and distance from the origin,
the photon and gather settings at their limits, degenerate geometry, light trapped in glass,
index of refraction 1 and 3, black and white furnaces, and 10^7 photons (marked slow).

Every render here is tiny (16 x 12 pixels, a few thousand photons); the comparisons are
against the seed-to-seed noise of the same scene at scale 1, or against closed forms.
"""


import numpy as np
import pytest

from core.scene import geometry
from core.integrators import photon_mapping as integrator
from core.integrators import sppm
from core.scene import shapes
from core.scene.contract import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, Camera, Lights,
                        Materials, Scene, SceneError)
from core.settings import MAX_RADIUS, RenderSettings

W, H = 16, 12
PHOTONS = dict(global_photons=6000, caustic_photons=6000, final_gather_rays=16, samples=4,
               global_k=20, caustic_k=20)


def finite_nonnegative(out):
    for name, v in out.passes.items():
        assert np.all(np.isfinite(v)), name
        assert np.all(v >= 0), name


def facing(part, normal):
    """The part with its winding flipped where its normal points away from ``normal``."""
    n = part.normals[:, 0]
    flip = n @ np.asarray(normal, float) < 0
    corners, normals = part.corners.copy(), part.normals.copy()
    corners[flip] = corners[flip][:, ::-1]
    normals[flip] = -normals[flip][:, ::-1]
    return shapes.Part(corners, normals)


def box_scene(scale=1.0, offset=(0.0, 0.0, 0.0), glass_ior=1.5, glass=True, sun=True):
    """A 2 m room open at the front (red and green walls), a glass sphere on the floor, an
    area, a point and a spot light (powers x scale^2: the same irradiance) and a sun through
    the opening (strength unchanged: W/m^2 does not scale)."""
    s, o = float(scale), np.asarray(offset, np.float64)
    room = shapes.box([-1, -1, 0], [1, 1, 2], inward=True)
    c = room.corners
    left = np.all(np.isclose(c[:, :, 0], -1), axis=1)
    right = np.all(np.isclose(c[:, :, 0], 1), axis=1)
    front = np.all(np.isclose(c[:, :, 1], -1), axis=1)
    rest = ~(left | right | front)
    parts = [(shapes.Part(c[rest], room.normals[rest]), 0),
             (shapes.Part(c[left], room.normals[left]), 1),
             (shapes.Part(c[right], room.normals[right]), 2)]
    if glass:
        parts.append((shapes.uv_sphere([0.3, 0.0, 0.4], 0.4, 12, 24), 3))
    parts = [(shapes.transform(p, s, o), m) for p, m in parts]
    mats = Materials.from_list([
        {"diffuse": [0.75, 0.75, 0.75]}, {"diffuse": [0.75, 0.1, 0.1]},
        {"diffuse": [0.1, 0.75, 0.1]}, {"transmission": [1, 1, 1], "ior": glass_ior}])
    p2 = s * s
    rows = [
        {"kind": LIGHT_AREA, "position": o + s * np.array([0, 0, 1.98]), "power": 30.0 * p2,
         "size": [0.5 * s, 0.5 * s]},
        {"kind": LIGHT_POINT, "position": o + s * np.array([-0.5, -0.3, 1.5]), "power": 10.0 * p2,
         "radius": 0.05 * s},
        {"kind": LIGHT_SPOT, "to_world": shapes.look_at(o + s * np.array([0.7, -0.7, 1.6]), o),
         "power": 20.0 * p2, "spot_size": np.radians(60), "radius": 0.02 * s},
    ]
    if sun:
        rows.append({"kind": LIGHT_SUN, "to_world": shapes.look_at([0, -3, 3], [0, 0, 0]),
                     "power": 1.0, "angle": np.radians(2)})
    cam = shapes.pinhole(o + s * np.array([0, -3.4, 1.0]), o + s * np.array([0, 0, 1.0]), W, H,
                         np.radians(45))
    cam = Camera(to_world=cam.to_world, width=W, height=H, film_size=cam.film_size,
                 clip_start=0.01 * s, clip_end=100.0 * s)
    return Scene(shapes.assemble(parts), mats, Lights.from_list(rows), cam)


def _blocks(x):
    return x.reshape(H // 4, 4, W // 4, 4, 3).mean(axis=(1, 3))


def noise_between(a, b):
    return {"mean": np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))).max(),
            "block": np.abs(_blocks(a) - _blocks(b)).max(),
            "rms": float(np.sqrt(np.mean((a - b) ** 2)))}


def assert_within_noise(image, reference, noise):
    got = noise_between(image, reference)
    for key, level in noise.items():
        assert got[key] <= level, (key, got[key], level)


@pytest.fixture(scope="module")
def box_reference():
    """The box at scale 1 (seed 3) and its noise level against seed 103."""
    st = RenderSettings(seed=3, **PHOTONS)
    ref = integrator.render(box_scene(), st)
    other = integrator.render(box_scene(), st.with_values(seed=103))
    finite_nonnegative(ref)
    p = ref.passes
    assert p["caustics"].max() > 0 and p["indirect"].mean() > 0 and p["direct"].mean() > 0
    noise = noise_between(p["combined"], other.passes["combined"])
    # Each photon term's own seed-to-seed noise: a lost caustic (half of it at 1e5 m)
    # hides in the noise of the combined image.
    for term in PHOTON_TERMS:
        noise[term] = abs(p[term].mean() - other.passes[term].mean())
    return ref, noise


PHOTON_TERMS = ("caustics", "indirect")


def assert_same_image(out, ref, noise):
    finite_nonnegative(out)
    assert_within_noise(out.passes["combined"], ref.passes["combined"],
                        {k: noise[k] for k in ("mean", "block", "rms")})
    for term in PHOTON_TERMS:
        a, b = out.passes[term].mean(), ref.passes[term].mean()
        assert abs(a - b) <= noise[term], (term, a, b, noise[term])


# --- scale and translation ------------------------------------------------------------------

@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1e2, 1e4])
def test_the_box_renders_the_same_at_every_scale(box_reference, scale):
    ref, noise = box_reference
    out = integrator.render(box_scene(scale=scale), RenderSettings(seed=3, **PHOTONS))
    assert_same_image(out, ref, noise)
    for key in ("caustic_radius", "global_radius"):
        assert out.stats[key] == pytest.approx(scale * ref.stats[key], rel=1e-4), key


def test_far_from_the_origin_matches_or_is_refused(box_reference):
    """At 1e5 m float32 resolves 7.8 mm: the 2 m box is either rendered as at the origin
    or refused with an error that says float32 cannot hold it, never silently wrong."""
    ref, noise = box_reference
    scene = box_scene(offset=(1e5, 1e5, 1e5))
    try:
        out = integrator.render(scene, RenderSettings(seed=3, **PHOTONS))
    except SceneError as e:
        assert "float32 precision" in str(e) and "mm" in str(e), str(e)
        return
    assert_same_image(out, ref, noise)


def test_the_precision_check_accepts_what_renders(box_reference):
    """The check refuses only what float32 cannot hold: at 3e3 m the box renders as at
    the origin (caustics within 1 %), and the check accepts it; at 1e4 m 5 % of the
    caustic is lost to the ray offsets (1 cm there), and it refuses."""
    ref, noise = box_reference
    near = box_scene(offset=(3e3, 3e3, 3e3))
    geometry.check_float32_precision(near)
    assert_same_image(integrator.render(near, RenderSettings(seed=3, **PHOTONS)), ref, noise)
    with pytest.raises(SceneError, match="float32 precision"):
        geometry.check_float32_precision(box_scene(offset=(1e4, 1e4, 1e4)))
    # Scaled up, the same distance is fine again.
    geometry.check_float32_precision(box_scene(scale=10.0, offset=(1e4, 1e4, 1e4)))


def test_the_precision_check_names_the_resolution():
    with pytest.raises(SceneError, match="float32 precision") as e:
        geometry.check_float32_precision(box_scene(scale=1e-2, offset=(1e4, 0.0, 0.0)))
    assert "mm" in str(e.value) or " m" in str(e.value)


@pytest.mark.parametrize("scale", [1e-8, 1e13])
def test_scenes_beyond_the_size_float32_holds_are_refused(scale):
    """Measured: the box at 1e-8 renders caustics 29 % too bright, at 1e-12 the estimate
    raises on k photons at one point, at 1e13 the image is black: refused, naming the size."""
    with pytest.raises(SceneError, match="scene size .* outside"):
        integrator.render(box_scene(scale=scale), RenderSettings(seed=3, **PHOTONS))


# --- photon and gather settings at their limits ---------------------------------------------

@pytest.mark.parametrize("values", [
    dict(global_photons=1, caustic_photons=1),
    dict(global_k=1, caustic_k=1),
    dict(global_k=10_000, caustic_k=10_000, global_photons=500, caustic_photons=500),
    dict(global_radius=1e-9, caustic_radius=1e-9),
    dict(global_radius=MAX_RADIUS, caustic_radius=MAX_RADIUS, global_photons=2000,
         caustic_photons=2000),
], ids=["one_photon", "k1", "k_above_map", "radius_tiny", "radius_huge"])
@pytest.mark.parametrize("mode", ["final_gather", "preview"])
def test_photon_settings_at_their_limits(values, mode):
    st = RenderSettings(seed=1, **{**PHOTONS, **values, "indirect_mode": mode})
    out = integrator.render(box_scene(sun=False), st)
    finite_nonnegative(out)
    p = out.passes
    if "global_radius" in values and values["global_radius"] == 1e-9:
        # A nanometre disc holds no photon: the photon terms vanish, the rest stays.
        assert np.all(p["caustics"] == 0) and np.all(p["indirect"] == 0)
    assert p["direct"].mean() > 0


def test_k_above_the_map_uses_the_whole_map():
    """k larger than the map with the largest radius: every estimate takes every photon,
    exactly what k = the map's size does (with a radius far beyond the scene)."""
    base = dict(seed=1, **{**PHOTONS, "global_photons": 400, "caustic_photons": 400,
                           "indirect_mode": "preview"})
    base = {k: v for k, v in base.items() if not k.endswith("_k")}
    big = integrator.render(box_scene(sun=False), RenderSettings(
        **base, global_k=10_000, caustic_k=10_000, global_radius=MAX_RADIUS,
        caustic_radius=MAX_RADIUS))
    finite_nonnegative(big)
    n_g, n_c = big.stats["global_photons_stored"], big.stats["caustic_photons_stored"]
    assert 0 < n_g < 10_000 and 0 < n_c < 10_000
    exact = integrator.render(box_scene(sun=False), RenderSettings(
        **base, global_k=n_g, caustic_k=n_c, global_radius=1e3, caustic_radius=1e3))
    for term in PHOTON_TERMS:
        assert big.passes[term].max() > 0, term
        np.testing.assert_array_equal(big.passes[term], exact.passes[term], err_msg=term)


# --- degenerate geometry --------------------------------------------------------------------

def floor_and_light(extra_parts=(), mats_extra=(), res=(W, H)):
    floor = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    mats = Materials.from_list([{"diffuse": [0.6, 0.6, 0.6]}, *mats_extra])
    parts = [(floor, 0), *extra_parts]
    cam = Camera(to_world=shapes.look_at([0, 0, 3], [0, 0, 0], (0, 1, 0)), width=res[0],
                 height=res[1], film_size=np.array([2.2, 2.2 * res[1] / res[0]]), kind=1,
                 clip_start=1e-3, clip_end=10.0)
    return parts, mats, cam


def test_zero_area_and_sliver_triangles_with_photons():
    """Degenerate (three equal corners, collinear corners) and sliver (1e-7 m wide)
    triangles, specular and diffuse, in the photon pass and the final gather."""
    sliver = np.array([[[-0.5, 0, 0.2], [0.5, 0, 0.2], [0.5, 1e-7, 0.2]],
                       [[0, -0.5, 0.3], [0, 0.5, 0.3], [1e-7, 0.5, 0.3]]])
    degenerate = np.array([[[0.1, 0.1, 0.5]] * 3, [[0, 0, 0.4], [0.2, 0.2, 0.4], [0.4, 0.4, 0.4]]])
    corners = np.concatenate([sliver, degenerate])
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0.0)
    part = shapes.Part(corners, np.repeat(n[:, None], 3, axis=1))
    parts, mats, cam = floor_and_light(
        [(part, 1), (shapes.Part(corners + [0, 0, 0.05], part.normals), 2)],
        [{"transmission": [1, 1, 1], "ior": 1.5}, {"diffuse": [0.5, 0.5, 0.5]}])
    scene = Scene(shapes.assemble(parts), mats,
                  Lights.from_list([{"kind": LIGHT_POINT, "position": [0.1, 0.2, 1.0], "power": 20.0}]),
                  cam)
    out = integrator.render(scene, RenderSettings(seed=2, **PHOTONS))
    finite_nonnegative(out)
    assert out.passes["direct"].mean() > 0


def test_coincident_faces_render_finite():
    """Two identical quads (one red, one white) on the floor: z-fighting picks either,
    the result stays finite, non-negative and between the two albedos' images."""
    parts, mats, cam = floor_and_light()
    twin = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    wall = facing(shapes.quad([0, 0.9, 0.5], [1, 0, 0], [0, 0, 0.5]), [0, -1, 0])
    mats = Materials.from_list([{"diffuse": [0.6, 0.6, 0.6]}, {"diffuse": [0.6, 0.1, 0.1]},
                                {"specular": [0.9, 0.9, 0.9]}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.1, 0.2, 1.0], "power": 20.0}])
    both = Scene(shapes.assemble([(parts[0][0], 0), (twin, 1), (twin, 2), (wall, 0)]), mats,
                 lights, cam)
    out = integrator.render(both, RenderSettings(seed=2, **PHOTONS))
    finite_nonnegative(out)
    white = integrator.render(Scene(shapes.assemble([(parts[0][0], 0), (wall, 0)]), mats, lights,
                                    cam), RenderSettings(seed=2, **PHOTONS))
    # Whichever face wins, the floor reflects at most what the white one alone does.
    assert out.passes["direct"].mean() <= white.passes["direct"].mean() * 1.001


# --- light and glass ------------------------------------------------------------------------

def test_point_light_inside_a_closed_glass_sphere_lights_the_floor():
    """A point light at the centre of a glass sphere: every ray meets the glass at normal
    incidence and leaves undeviated (what Fresnel reflects crosses the centre and leaves
    on the other side), so the floor sees what the bare light gives it. Shadow rays are
    stopped by the glass: the light arrives as caustic photons (and, under the sphere,
    seen through it), and the image matches the bare light's direct image within 3 %."""
    parts, mats, cam = floor_and_light(
        [(shapes.uv_sphere([0, 0, 0.5], 0.3, 16, 32), 1)], [{"transmission": [1, 1, 1], "ior": 1.5}])
    light = Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 0.5], "power": 50.0}])
    st = RenderSettings(seed=2, photon_max_bounces=64, **PHOTONS)
    out = integrator.render(Scene(shapes.assemble(parts), mats, light, cam), st)
    finite_nonnegative(out)
    assert out.stats["caustic_photons_stored"] > 0
    assert np.all(out.passes["direct"] == 0) and out.passes["caustics"].mean() > 0
    bare = integrator.render(Scene(shapes.assemble(parts[:1]), mats, light, cam), st)
    expected = bare.passes["direct"].mean()
    assert out.passes["combined"].mean() == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize("shape", ["slab", "sphere"])
def test_total_internal_reflection_loops_terminate(shape):
    """Light trapped by total internal reflection (ior 3: critical angle 19.5 degrees)
    with 1024 photon bounces and camera depth: the render ends, finite."""
    if shape == "slab":
        part = shapes.box([-0.6, -0.6, 0.1], [0.6, 0.6, 0.2])
    else:
        part = shapes.uv_sphere([0, 0, 0.4], 0.3, 12, 24)
    parts, mats, cam = floor_and_light([(part, 1)], [{"transmission": [1, 1, 1], "ior": 3.0}])
    scene = Scene(shapes.assemble(parts), mats,
                  Lights.from_list([{"kind": LIGHT_POINT, "position": [0.2, 0.1, 1.2], "power": 20.0}]),
                  cam)
    out = integrator.render(scene, RenderSettings(seed=2, photon_max_bounces=1024,
                                                  max_specular_depth=1024, **PHOTONS))
    finite_nonnegative(out)
    assert out.passes["caustics"].max() > 0


def test_glass_of_ior_1_is_invisible():
    """A transmission-only sphere with ior 1 bends and reflects nothing: the image equals
    the scene without it within noise. The light behind it comes by other paths (seen
    through it: specular; shadow rays stopped by it: caustic photons instead of direct
    light), so the noise is that of both images, each measured from three seeds (the
    largest difference between two of them: one pair alone can be close by chance)."""
    st = RenderSettings(seed=3, **PHOTONS)
    renders = {}
    for glass in (False, True):
        scene = box_scene(glass_ior=1.0, glass=glass)
        renders[glass] = [integrator.render(scene, st.with_values(seed=s)) for s in (3, 103, 203)]
        for out in renders[glass]:
            finite_nonnegative(out)
    without, with_glass = ([r.passes["combined"] for r in renders[g]] for g in (False, True))

    def noise(images):
        pairs = [noise_between(images[i], images[j]) for i, j in ((0, 1), (0, 2), (1, 2))]
        return {k: max(p[k] for p in pairs) for k in pairs[0]}
    n0, n1 = noise(without), noise(with_glass)
    assert renders[True][0].passes["caustics"].max() > 0  # the photons did go through it
    assert_within_noise(with_glass[0], without[0], {k: n0[k] + n1[k] for k in n0})


def test_glass_of_ior_3_is_finite_and_focuses():
    out = integrator.render(box_scene(glass_ior=3.0), RenderSettings(seed=3, **PHOTONS))
    finite_nonnegative(out)
    assert out.passes["caustics"].max() > 0


# --- black and white furnaces ---------------------------------------------------------------

def inward(part):
    return shapes.Part(part.corners[:, ::-1].copy(), -part.normals[:, ::-1].copy())


def closed_box_scene(albedo, emission=0.0, light=True, glass=True):
    room = shapes.box([-1, -1, -1], [1, 1, 1], inward=True)
    parts = [(room, 0)]
    if glass:
        parts.append((shapes.uv_sphere([0.3, 0.2, -0.5], 0.3, 12, 24), 1))
    mats = Materials.from_list([{"diffuse": [albedo] * 3, "emission": [emission] * 3},
                                {"transmission": [1, 1, 1], "ior": 1.5}])
    rows = [{"kind": LIGHT_POINT, "position": [-0.3, -0.2, 0.5], "power": 20.0}] if light else []
    cam = shapes.pinhole([0, -0.8, 0], [0, 1, 0], W, H, np.radians(80))
    return Scene(shapes.assemble(parts), mats, Lights.from_list(rows), cam)


def test_black_box_has_exactly_no_photon_light():
    """Albedo 0 inside a closed box: nothing is reflected diffusely, so the caustics and
    the indirect light are exactly 0 (the glass still refracts the light's direct image)."""
    out = integrator.render(closed_box_scene(0.0), RenderSettings(seed=1, photon_max_bounces=64, **PHOTONS))
    finite_nonnegative(out)
    assert np.all(out.passes["caustics"] == 0)
    assert np.all(out.passes["indirect"] == 0)
    assert np.all(out.passes["direct"] == 0)


@pytest.mark.parametrize("albedo", [0.999, 1.0])
def test_white_furnace_stays_bounded(albedo):
    """Camera in a closed emissive box of albedo a (no other light): the exact answer
    L = L_e / (1 - a) is 1000 L_e at a = 0.999 and infinite at a = 1. Photons that
    bounce at most B = 128 times cut the series: emission, direct light and the gathered
    map (a^2 ... a^(B+1): final-gather rays read photons of at most B - 1 bounces, issue
    13) give sum_{i <= B+1} a^i, finite at a = 1 too; the render holds that within 3 %
    (the noise of 4 samples, the gather's k / (k - 1) bias). Emission is two-sided (as in
    Cycles): half the photons leave the box at once."""
    bounces = 128
    scene = closed_box_scene(albedo, emission=1.0, light=False, glass=False)
    st = RenderSettings(seed=1, photon_max_bounces=bounces, caustics=False,
                        **{**PHOTONS, "global_photons": 3000, "global_k": 64})
    out = integrator.render(scene, st)
    finite_nonnegative(out)
    L = float(out.passes["combined"].mean())
    series = lambda n: sum(albedo**i for i in range(n + 1))  # noqa: E731
    assert 0.97 * series(bounces + 1) <= L <= 1.03 * series(bounces + 1), (L, series(bounces + 1))
    if albedo < 1:
        assert L <= 1.0 / (1.0 - albedo)


FURNACE_ALBEDO = 0.8


@pytest.mark.parametrize("bounces", [1, 3])
@pytest.mark.parametrize("how", ["final_gather", "preview", "progressive"])
def test_emissive_box_reflects_as_often_as_cycles_max_bounces(how, bounces):
    """Issue 13. Camera in a closed emissive box (L_e = 1 on the inner faces, albedo
    a = 0.8, no light): Cycles with Max Bounces B sees L_e sum_{i <= B+1} a^i (the
    emission, then the light of 1 .. B + 1 reflections: the light sampled at the path's
    (B + 1)-th vertex). photon_max_bounces P = B gives the same sum whoever reads the
    photons: final gathering (x, the gather hit y, then the global map's photons of at
    most P - 1 bounces), the preview (the map without direct photons read at x, photons
    of 1 .. P bounces) and SPPM (photons of 1 .. P bounces at the visible point). One
    reflection more (final gathering before the fix: the sum to P + 2) is 21 % / 10 % high
    at P = 1 / 3, one less 26 % / 12 % low; the renders hold the sum within 4 %."""
    a = FURNACE_ALBEDO
    scene = closed_box_scene(a, emission=1.0, light=False, glass=False)
    st = RenderSettings(seed=1, photon_max_bounces=bounces, caustics=False,
                        **{**PHOTONS, "global_photons": 12000, "global_k": 40})
    if how == "progressive":
        out = sppm.render(scene, st.with_values(progressive_passes=8, photons_per_pass=6000))
    else:
        out = integrator.render(scene, st.with_values(indirect_mode=how))
    finite_nonnegative(out)
    L = float(out.passes["combined"].mean())
    want = sum(a ** i for i in range(bounces + 2))
    print(f"{how} P = {bounces}: {L:.4f} for {want:.4f} ({L / want - 1:+.2%})")
    assert abs(L / want - 1) <= 0.04, (L, want)


# --- 10^7 photons -----------------------------------------------------------------------------

MEASURE = """
import json, resource, sys, time
sys.path.insert(0, {root!r})
from core.integrators import photon_mapping as integrator
from core.photons import tracing
from core.settings import RenderSettings
from tests.core.test_extremes import box_scene
scene = box_scene(glass=False)
small = RenderSettings(seed=1, samples=1, global_photons=10_000, caustics=False, final_gather_rays=4)
integrator.render(scene, small)  # load the kernels before the baseline
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
st = small.with_values(global_photons={n})
t0 = time.perf_counter()
if {what!r} == "photon_pass":
    stored = len(trace(scene, st).global_map)
else:
    stored = integrator.render(scene, st).stats["global_photons_stored"]
print(json.dumps({{"seconds": time.perf_counter() - t0, "stored": stored,
                  "peak_mib": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024}}))
"""

README_MIB_PER_MILLION_STORED = 175


def measure(what, n):
    """Seconds, stored photons and the peak memory above the baseline (MiB, ru_maxrss) of
    tracing ``n`` global photons in the box ("photon_pass") or rendering it ("render"),
    in a fresh process: ru_maxrss is the high-water mark of the whole process."""
    import json
    import pathlib
    import subprocess
    import sys

    root = str(pathlib.Path(__file__).resolve().parents[2])
    code = MEASURE.format(root=root, n=n, what=what)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=root)
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("what", ["photon_pass", "render"])
def test_ten_million_photons_within_the_stated_memory(what):
    """README: about 175 MiB per million photons stored at the peak (the photon pass's
    per-bounce arrays, their concatenation and PhotonMap construction scale with photons
    stored; final gathering stores ~1.85 per emitted photon in this white box). 10^7
    global photons stay within it (+10 %). CI runs the same code at 6000 photons in every
    test above."""
    got = measure(what, 10_000_000)
    print(f"\n10^7 photons, {what}: {got}")
    assert got["stored"] > 10_000_000
    assert got["peak_mib"] <= 1.1 * README_MIB_PER_MILLION_STORED * got["stored"] / 1e6, got

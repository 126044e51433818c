"""Fuzzed scenes (issue 7, point 4), with hypothesis: scenes built from random arrays
either are refused with a SceneError / SettingsError naming the field, or render with
every pass finite and non-negative; corrupted inputs are refused, naming the field.

The examples are derandomized (the same every run) and tiny (4 x 3 pixels, a few hundred
photons), so the file runs in seconds. To hunt longer with fresh random examples:
``FUZZ_EXAMPLES=500 .venv/bin/python -m pytest tests/core/test_fuzz.py``.
"""

import dataclasses
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, CAMERA_PERSPECTIVE, LIGHT_AREA, LIGHT_POINT,
                        LIGHT_SPOT, LIGHT_SUN, Camera, Lights, Materials, Mesh, Scene,
                        SceneError, World)
from core.settings import FILTERS, INDIRECT_MODES, RenderSettings, SettingsError

_HUNT = os.environ.get("FUZZ_EXAMPLES")
FUZZ = settings(max_examples=int(_HUNT or 25), deadline=None, derandomize=not _HUNT, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def floats(lo, hi, shape):
    return hnp.arrays(np.float32, shape, elements=st.floats(lo, hi, width=32))


def unit_normals(corners):
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0.0)
    return np.repeat(n[:, None], 3, axis=1).astype(np.float32)


@st.composite
def meshes(draw, n_materials):
    """A floor (so something is always diffuse and lit), 1..6 random triangles, some of
    them degenerate, and maybe a room around them, with random material indices."""
    t = draw(st.integers(1, 6))
    corners = draw(floats(-1.5, 1.5, (t, 3, 3)))
    if draw(st.booleans()):  # a degenerate one: two equal corners
        corners[0, 1] = corners[0, 0]
    floor = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0]).corners.astype(np.float32)
    corners = np.concatenate([floor, corners])
    if draw(st.booleans()):  # a closed room around it all, so that photons bounce
        room = shapes.box([-4, -4, -0.5], [4, 4, 6], inward=True).corners.astype(np.float32)
        corners = np.concatenate([room, corners])
    t = corners.shape[0]
    mat = draw(hnp.arrays(np.int32, (t,), elements=st.integers(0, n_materials - 1)))
    return Mesh(vertices=corners.reshape(-1, 3).copy(),
                triangles=np.arange(3 * t, dtype=np.int32).reshape(t, 3),
                normals=unit_normals(corners.astype(np.float64)),
                uvs=np.zeros((t, 3, 2), np.float32), material_index=mat,
                object_index=np.zeros(t, np.int32), object_names=("Fuzz",))


@st.composite
def materials(draw):
    m = draw(st.integers(1, 3))
    lobes = {key: draw(floats(0.0, 1.0, (m, 3))) for key in ("diffuse", "specular", "transmission")}
    return Materials(**lobes, roughness=draw(floats(0.0, 1.0, (m,))),
                     ior=draw(floats(1.0, 3.0, (m,))),
                     emission=draw(floats(0.0, 5.0, (m, 3))) * draw(st.sampled_from([0.0, 1.0])),
                     names=tuple(f"Mat{i}" for i in range(m)))


def _direction(draw):
    v = draw(floats(-1.0, 1.0, (3,))).astype(np.float64)
    return v if np.linalg.norm(v) > 1e-3 else np.array([0.0, 0.0, -1.0])


@st.composite
def lights(draw):
    n = draw(st.integers(0, 4))
    rows = []
    for _ in range(n):
        pos = draw(floats(-2.0, 2.0, (3,))).astype(np.float64) + [0, 0, 2.5]
        target = pos + _direction(draw)
        rows.append({
            "kind": draw(st.sampled_from([LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, LIGHT_AREA])),
            "to_world": shapes.look_at(pos, target, up=(0.3, 0.4, 0.9)),
            "color": draw(floats(0.0, 1.0, (3,))),
            "power": draw(st.one_of(st.just(0.0), st.floats(1.0, 200.0), st.floats(1.0, 200.0))),
            "radius": draw(st.sampled_from([0.0, 1e-6, 0.05, 0.5])),
            "angle": draw(st.floats(0.0, 3.0)),
            "spot_size": draw(st.floats(0.0, np.pi)),
            "spot_blend": draw(st.floats(0.0, 1.0)),
            "shape": draw(st.sampled_from([0, 1])),
            "size": draw(floats(0.0, 2.0, (2,))),
            "visible_to_camera": draw(st.booleans()),
            "cast_shadow": draw(st.booleans()),
            "soft_falloff": draw(st.booleans()),
        })
    return Lights.from_list(rows)


@st.composite
def cameras(draw):
    eye = draw(floats(-3.0, 3.0, (3,))).astype(np.float64) * [1, 1, 0.5] + [0, 0, 2.0]
    target = draw(floats(-1.0, 1.0, (3,))).astype(np.float64)
    if np.linalg.norm(target - eye) < 1e-2:
        target = eye + [0.0, 0.0, -1.0]
    kind = draw(st.sampled_from([CAMERA_PERSPECTIVE, CAMERA_ORTHOGRAPHIC]))
    film = draw(st.floats(0.05, 4.0))
    return Camera(to_world=shapes.look_at(eye, target, up=(0.1, 0.2, 1.0)), width=4, height=3,
                  film_size=np.array([film, 0.75 * film]), kind=kind,
                  film_shift=np.array([draw(st.floats(-0.5, 0.5)), 0.0]),
                  clip_start=1e-3, clip_end=draw(st.sampled_from([1.0, 100.0, 100.0])))


def scaled(scene, s):
    """The scene with every length times s (lights keep their power)."""
    if s == 1.0:
        return scene
    m, li, c = scene.mesh, scene.lights, scene.camera
    to_world = li.to_world.copy()
    to_world[:, :3, 3] *= s
    cam_world = c.to_world.copy()
    cam_world[:3, 3] *= s
    film = c.film_size * (s if c.kind == CAMERA_ORTHOGRAPHIC else 1.0)
    return Scene(dataclasses.replace(m, vertices=(m.vertices * np.float32(s)).astype(np.float32)),
                 scene.materials,
                 dataclasses.replace(li, to_world=to_world,
                                     radius=(li.radius * s).astype(np.float32),
                                     size=(li.size * s).astype(np.float32)),
                 dataclasses.replace(c, to_world=cam_world, film_size=film,
                                     film_shift=c.film_shift * (s if c.kind == CAMERA_ORTHOGRAPHIC else 1.0),
                                     clip_start=c.clip_start * s, clip_end=c.clip_end * s),
                 scene.world)


@st.composite
def scenes(draw):
    mats = draw(materials())
    world = World(radiance=draw(floats(0.0, 1.0, (3,))) * draw(st.sampled_from([0.0, 1.0])),
                  visible_to_camera=draw(st.booleans()))
    scene = Scene(draw(meshes(mats.count)), mats, draw(lights()), draw(cameras()), world)
    return scaled(scene, draw(st.sampled_from([1.0, 1.0, 1e-4, 1e4])))


@st.composite
def render_settings(draw):
    return RenderSettings(
        samples=draw(st.integers(1, 2)), seed=draw(st.integers(0, 1000)),
        max_specular_depth=draw(st.integers(0, 12)),
        global_photons=draw(st.sampled_from([0, 1, 100, 300])),
        caustic_photons=draw(st.sampled_from([0, 1, 100, 300])),
        photon_max_bounces=draw(st.integers(1, 32)),
        global_k=draw(st.integers(1, 400)), caustic_k=draw(st.integers(1, 400)),
        global_radius=draw(st.sampled_from([0.0, 1e-9, 0.1, 1e9])),
        caustic_radius=draw(st.sampled_from([0.0, 1e-9, 0.1, 1e9])),
        filter=draw(st.sampled_from(FILTERS)), indirect_mode=draw(st.sampled_from(INDIRECT_MODES)),
        final_gather_rays=draw(st.integers(1, 8)), projection_map=draw(st.booleans()))


@FUZZ
@given(scene=scenes(), rs=render_settings())
def test_random_scenes_render_finite_and_non_negative(scene, rs):
    scene.validate()
    out = integrator.render(scene, rs.validated())
    for name, image in out.passes.items():
        assert image.shape[:2] == (3, 4), name
        assert np.all(np.isfinite(image)), name
        assert np.all(image >= 0), name


# --- rejected inputs --------------------------------------------------------------------------

def base_scene():
    mats = Materials.from_list([{"diffuse": [0.5, 0.5, 0.5]}, {"transmission": [1, 1, 1]}])
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0),
                            (shapes.uv_sphere([0, 0, 0.5], 0.3, 4, 8), 1)])
    li = Lights.from_list([{"kind": k, "position": [0, 0, 2.0], "power": 10.0} for k in range(4)])
    cam = shapes.pinhole([0, -3, 1], [0, 0, 0], 4, 3, 0.8)
    return Scene(mesh, mats, li, cam)


def _replace(obj, **kw):
    return dataclasses.replace(obj, **kw)


def corrupt_array(a, how, draw):
    a = np.array(a, copy=True)
    if how == "nan":
        if a.dtype.kind != "f":
            a = a.astype(np.float32)
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    elif how == "negative":
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = -draw(st.floats(1e-6, 1e6))
    elif how == "shape":
        a = a.reshape(-1)[: max(1, a.size - 1)]
    elif how == "above":  # a reflectance, roughness or blend above 1
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = draw(st.floats(1.0001, 1e6))
    elif how == "huge":  # finite, but float32 sums of it overflow
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = draw(st.sampled_from([-1, 1])) * draw(
            st.floats(1.1e30, 3e38))
    elif how == "dtype":
        a = a.astype(np.float64 if a.dtype != np.float64 else np.int64)
    return a


# (owner, field, corruptions, text the message must contain)
CORRUPTIONS = [
    ("mesh", "vertices", ("nan", "shape", "dtype", "huge"), "mesh.vertices"),
    ("mesh", "triangles", ("shape", "dtype", "range"), "mesh.triangles"),
    ("mesh", "normals", ("nan", "shape"), "mesh.normals"),
    ("mesh", "uvs", ("nan", "shape"), "mesh.uvs"),
    ("mesh", "material_index", ("shape", "range"), "mesh.material_index"),
    ("materials", "diffuse", ("nan", "negative", "shape", "above"), "materials.diffuse"),
    ("materials", "specular", ("nan", "negative", "above"), "materials.specular"),
    ("materials", "transmission", ("nan", "negative", "above"), "materials.transmission"),
    ("materials", "emission", ("nan", "negative", "huge"), "materials.emission"),
    ("materials", "roughness", ("nan", "negative", "shape", "above"), "materials.roughness"),
    ("materials", "ior", ("nan", "negative", "zero"), "materials.ior"),
    ("lights", "power", ("nan", "negative", "shape", "huge"), "lights.power"),
    ("lights", "color", ("nan", "negative"), "lights.color"),
    ("lights", "radius", ("nan", "negative"), "lights.radius"),
    ("lights", "angle", ("nan", "negative"), "lights.angle"),
    ("lights", "spot_size", ("nan", "negative"), "lights.spot_size"),
    ("lights", "spot_blend", ("nan", "negative", "above"), "lights.spot_blend"),
    ("lights", "size", ("nan", "negative"), "lights.size"),
    ("lights", "to_world", ("nan", "shape"), "lights.to_world"),
    ("lights", "kind", ("range", "dtype"), "lights.kind"),
    ("camera", "to_world", ("nan", "shape"), "camera.to_world"),
    ("camera", "film_size", ("nan", "negative", "zero"), "film_size"),
    ("world", "radiance", ("nan", "negative", "shape", "huge"), "world.radiance"),
]


@st.composite
def corrupted_scenes(draw):
    owner, name, ways, expected = draw(st.sampled_from(CORRUPTIONS))
    how = draw(st.sampled_from(ways))
    scene = base_scene()
    part = getattr(scene, owner)
    a = getattr(part, name)
    if how == "range":
        a = np.array(a, copy=True)
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = draw(
            st.sampled_from([-1, 10_000, 2**31 - 1, -(2**31)]))
    elif how == "zero":
        a = np.array(a, copy=True)
        a.reshape(-1)[draw(st.integers(0, a.size - 1))] = 0.0
    else:
        a = corrupt_array(a, how, draw)
    return _replace(scene, **{owner: _replace(part, **{name: a})}), expected, f"{owner}.{name} {how}"


@FUZZ
@given(case=corrupted_scenes())
def test_corrupted_scenes_are_refused_naming_the_field(case):
    scene, expected, what = case
    with pytest.raises(SceneError) as e:
        integrator.render(scene, RenderSettings(samples=1, global_photons=10, caustic_photons=10))
    assert expected in str(e.value), (what, str(e.value))


SETTINGS_BAD = st.one_of(
    st.tuples(st.sampled_from(["samples", "global_photons", "caustic_photons", "global_k",
                               "caustic_k", "photon_max_bounces", "final_gather_rays",
                               "max_specular_depth", "seed", "light_samples",
                               "volume_light_samples", "threads"]),
              st.one_of(st.integers(-2**40, -1), st.integers(2**31, 2**62), st.floats(),
                        st.booleans(), st.text(max_size=3))),
    st.tuples(st.sampled_from(["global_radius", "caustic_radius", "overlay_dot_radius"]),
              st.one_of(st.floats(max_value=-1e-30), st.floats(min_value=1e10),
                        st.just(float("nan")), st.just(float("inf")), st.booleans(),
                        st.text(max_size=3))),
    st.tuples(st.sampled_from(["indirect_mode", "filter", "overlay_map"]),
              st.one_of(st.text(max_size=5), st.integers(), st.none())),
    st.tuples(st.sampled_from(["caustics", "projection_map", "photon_debug_pass"]),
              st.one_of(st.integers(), st.text(max_size=3), st.none())),
)


@FUZZ
@given(bad=SETTINGS_BAD)
def test_bad_settings_are_refused_naming_the_setting(bad):
    name, value = bad
    rs = dataclasses.replace(RenderSettings(), **{name: value})
    if name in ("indirect_mode", "filter", "overlay_map") and value in (
            INDIRECT_MODES + FILTERS + ("global", "caustic", "both")):
        return  # drew a valid value
    with pytest.raises(SettingsError) as e:
        rs.validated()
    assert f'"{name}"' in str(e.value), str(e.value)

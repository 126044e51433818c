"""Emissive media as photon sources (core/photons/medium_emission.py): a closed box of
Lambert walls filled with an emissive, absorbing medium; the photons' first hits on a
wall give its irradiance, compared with the integral over the hemisphere of what the
medium sends there."""

import numpy as np
import pytest

from core.photons import medium_emission, tracing
from core.prepared import prepare
from core.scene import shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, Camera, Lights, Materials, Scene
from core.scene.media import Media
from core.settings import RenderSettings

pytestmark = pytest.mark.core

HALF = 1.0                                  # the box is [-1, 1]^3 m
EPS = np.array([0.5, 1.0, 2.0])             # W/(m^3 sr)
SIGMA_A = np.array([0.2, 0.5, 1.0])         # 1/m
PATCH = 0.5                                 # the floor patch [-0.5, 0.5]^2 at z = -1


def _box_scene():
    box = shapes.box([-HALF] * 3, [HALF] * 3)
    mesh = shapes.assemble([(box, 0)], names=("Room",))
    cam = Camera(to_world=shapes.look_at([0, 0, 0.5], [0, 0, -1], (0, 1, 0)), width=4,
                 height=4, film_size=np.array([1.0, 1.0]), kind=CAMERA_ORTHOGRAPHIC)
    media = Media.from_list([{"bounds": 0, "name": "Glow", "boundary": box.corners,
                              "sigma_a": SIGMA_A, "emission": EPS}])
    return Scene(mesh, Materials.from_list([{"diffuse": [0.5, 0.5, 0.5]}]), Lights.empty(),
                 cam, media=media).validate()


def _exit_distance(p, d):
    """Distance from points p (N, 3) inside the box along unit d (N, 3) to its wall."""
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (HALF - p) / d, np.where(d < 0, (-HALF - p) / d, np.inf))
    return t.min(axis=1)


def _hemisphere_irradiance(x, chord, eps, sigma_a, n_mu=400, n_phi=400):
    """E at floor points x (P, 3), averaged: the integral over the upper hemisphere of
    eps (1 - exp(-sigma_a l(w))) / sigma_a cos dw, l = chord(p, directions) the length of
    the emitting medium along each direction from p (midpoint rule in cos and azimuth:
    smooth integrand)."""
    mu = (np.arange(n_mu) + 0.5) / n_mu
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    mu, phi = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - mu ** 2)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=-1).reshape(-1, 3)
    w = (mu.reshape(-1) / n_mu) * (2 * np.pi / n_phi)
    out = [eps * (w[:, None] * (1 - np.exp(-sigma_a * chord(p, d)[:, None]))).sum(0) / sigma_a
           for p in x]
    return np.mean(out, axis=0)


def _irradiance(x):
    """E at floor points x (P, 3) from the box's medium, l the chord to the far wall."""
    return _hemisphere_irradiance(
        x, lambda p, d: _exit_distance(np.broadcast_to(p + [0, 0, 1e-12], d.shape), d),
        EPS, SIGMA_A)


def test_volume_of_a_closed_mesh():
    assert medium_emission.volume(shapes.box([0, 0, 0], [1, 2, 3]).corners) == pytest.approx(6.0)


def test_an_emissive_medium_lights_the_walls_of_its_box():
    """Photons of the medium only (no light), their first hits only (0 bounces): the
    patch's irradiance (stored flux / area) = the hemisphere integral within 1.5 %, per
    channel; the source's power is 4 pi epsilon V; nothing is dropped."""
    st = RenderSettings(global_photons=1_000_000, photon_max_bounces=0, caustics=False,
                        indirect_mode="preview", threads=2, seed=3)
    with prepare(_box_scene(), 2) as pr:
        sources = tracing.photon_sources(pr)
        assert len(sources) == 1 and medium_emission.is_medium(sources[0].index)
        np.testing.assert_allclose(sources[0].power, 4 * np.pi * EPS * 8.0, rtol=1e-6)
        maps = tracing.trace_photons(pr, st, include_direct=False)
    assert not any("dropped" in line for line in maps.stats["decisions"])
    pos = np.asarray(maps.global_map.positions, np.float64)
    flux = np.asarray(maps.global_map.flux, np.float64)
    on = (np.abs(pos[:, 2] + HALF) < 1e-4) & np.all(np.abs(pos[:, :2]) < PATCH, axis=1)
    got = flux[on].sum(0) / (2 * PATCH) ** 2
    g = (np.arange(6) + 0.5) / 6 * 2 * PATCH - PATCH
    gx, gy = np.meshgrid(g, g)
    want = _irradiance(np.stack([gx.ravel(), gy.ravel(), np.full(36, -HALF)], axis=1))
    print("patch irradiance", got, "integral", want, "rel", got / want - 1)
    np.testing.assert_allclose(got, want, rtol=0.015)


# The World's volume emission (docs/volumes.md, "World volume emission"): a 4 x 4 m floor
# in an emissive, absorbing World medium; its photons start in the scene's bounding sphere.
FLOOR = 2.0                                  # the floor is [-2, 2]^2 at z = 0
W_EPS = np.array([0.3, 0.6, 1.2])            # W/(m^3 sr)
W_SIGMA_A = np.array([0.25, 0.5, 1.5])       # 1/m
W_PATCH = 1.5                                # the floor patch [-1.5, 1.5]^2


def _floor_scene():
    floor = shapes.quad([0, 0, 0], [FLOOR, 0, 0], [0, FLOOR, 0])
    mesh = shapes.assemble([(floor, 0)], names=("Floor",))
    cam = Camera(to_world=shapes.look_at([0, 0, 1], [0, 0, 0], (0, 1, 0)), width=4,
                 height=4, film_size=np.array([1.0, 1.0]), kind=CAMERA_ORTHOGRAPHIC)
    media = Media.from_list([{"name": "Glowing air", "sigma_a": W_SIGMA_A,
                              "emission": W_EPS}])
    return Scene(mesh, Materials.from_list([{"diffuse": [0.5, 0.5, 0.5]}]), Lights.empty(),
                 cam, media=media).validate()


def _sphere_irradiance(x, centre, radius, n_mu=400, n_phi=400):
    """E at floor points x (P, 3) from the World medium inside the sphere (centre, radius),
    l the chord from the point to the sphere."""
    def chord(p, d):
        q = p - centre
        b = d @ q
        return -b + np.sqrt(b * b - (q @ q - radius ** 2))
    return _hemisphere_irradiance(x, chord, W_EPS, W_SIGMA_A, n_mu, n_phi)


def test_the_world_volume_emission_lights_the_floor_from_the_scene_sphere():
    """The World's emission as a source: power 4 pi epsilon (4/3 pi R^3) over the scene's
    bounding sphere; the floor patch's irradiance from above (the photons' first hits,
    0 bounces) = the hemisphere integral over chords to that sphere within 1.5 % (about
    70k photons land there from above: 0.4 % noise)."""
    st = RenderSettings(global_photons=2_000_000, photon_max_bounces=0, caustics=False,
                        indirect_mode="preview", threads=2, seed=5)
    with prepare(_floor_scene(), 2) as pr:
        centre, radius = np.asarray(pr.centre, np.float64), float(pr.radius)
        assert radius == pytest.approx(FLOOR * np.sqrt(2) * 1.01)
        sources = tracing.photon_sources(pr)
        assert len(sources) == 1 and medium_emission.is_medium(sources[0].index)
        np.testing.assert_allclose(sources[0].power,
                                   4 * np.pi * W_EPS * 4 / 3 * np.pi * radius ** 3, rtol=1e-6)
        maps = tracing.trace_photons(pr, st, include_direct=False)
    assert any("World volume emission of 'Glowing air': photons from the scene's bounding "
               "sphere" in line for line in maps.stats["decisions"])
    pos = np.asarray(maps.global_map.positions, np.float64)
    flux = np.asarray(maps.global_map.flux, np.float64)
    from_above = np.asarray(maps.global_map.directions)[:, 2] > 0
    on = (np.abs(pos[:, 2]) < 1e-4) & np.all(np.abs(pos[:, :2]) < W_PATCH, axis=1) & from_above
    got = flux[on].sum(0) / (2 * W_PATCH) ** 2
    g = (np.arange(12) + 0.5) / 12 * 2 * W_PATCH - W_PATCH
    gx, gy = np.meshgrid(g, g)
    want = _sphere_irradiance(np.stack([gx.ravel(), gy.ravel(), np.zeros(144)], axis=1),
                              centre, radius, 200, 200)
    print("world patch irradiance", got, "integral", want, "rel", got / want - 1)
    np.testing.assert_allclose(got, want, rtol=0.015)

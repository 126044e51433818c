"""Which photons are traced (core/photons/importance.py, core/photons/tracing.py, core/integrators/photon_terms.py):
photons shared by power x visual importance, unbiased, the decisions in the log."""

import numpy as np
import pytest

from tests.core.maps import trace
from core.photons import importance
from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.scene.contract import LIGHT_AREA, LIGHT_POINT, LIGHT_SUN, Lights, Materials, Scene
from core.settings import RenderSettings

W = H = 16


def _settings(**kw):
    base = dict(global_photons=20_000, caustic_photons=10_000, photon_max_bounces=6, threads=2)
    base.update(kw)
    return RenderSettings().with_values(**base)


def two_rooms(glass=False, power_b=100.0):
    """Two closed 2 m rooms 1 m apart (A at x in [-1, 1], B at x in [2, 4]), a 100 W point
    light in each, the camera inside A looking at its back wall; optionally a glass sphere
    in each room."""
    parts = [(shapes.box([-1, -1, 0], [1, 1, 2], inward=True), 0),
             (shapes.box([2, -1, 0], [4, 1, 2], inward=True), 0)]
    if glass:
        parts += [(shapes.uv_sphere([0.2, 0.2, 0.4], 0.3, 8, 16), 1),
                  (shapes.uv_sphere([3.2, 0.2, 0.4], 0.3, 8, 16), 1)]
    mats = Materials.from_list([{"diffuse": [0.6] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
    lights = Lights.from_list([
        {"kind": LIGHT_POINT, "position": (0.0, 0.0, 1.5), "power": 100.0, "name": "LampA"},
        {"kind": LIGHT_POINT, "position": (3.0, 0.0, 1.5), "power": power_b, "name": "LampB"}])
    cam = shapes.pinhole([0, -0.9, 1.2], [0.2, 0.4, 0.2], W, H, np.radians(70))
    return Scene(shapes.assemble(parts), mats, lights, cam).validate()


def _in_room_a(pm):
    return int(np.sum(pm.global_map.positions[:, 0] < 1.5))


def test_light_in_the_other_room_gets_the_floor_share():
    scene = two_rooms()
    on = trace(scene, _settings())
    off = trace(scene, _settings(photon_importance=False))
    src = {s["name"]: s for s in on.stats["per_source"]}
    assert src["LampA"]["global_importance"] == 1.0
    assert src["LampB"]["global_fraction"] == 0.0
    # Equal powers: B keeps FLOOR / (1 + FLOOR) of the photons, A the rest.
    n = 20_000
    assert abs(src["LampB"]["global_photons"] - n * importance.FLOOR / (1 + importance.FLOOR)) <= 1
    assert src["LampA"]["global_photons"] + src["LampB"]["global_photons"] == n
    off_src = {s["name"]: s for s in off.stats["per_source"]}
    assert off_src["LampA"]["global_photons"] == off_src["LampB"]["global_photons"] == n // 2
    # The photons stored in the room the camera sees grow accordingly (same bounces per
    # photon in both rooms: the count scales with the photons emitted there).
    ratio = _in_room_a(on) / _in_room_a(off)
    expected = (n / (1 + importance.FLOOR)) / (n / 2)
    assert abs(ratio / expected - 1) < 0.03, (ratio, expected)
    # Room B is still traced (the floor): its photons are there, and they carry more flux.
    assert np.sum(on.global_map.positions[:, 0] > 1.5) > 0


def test_the_emitted_flux_of_every_source_is_unchanged_by_the_allocation():
    # Point, area and sun emission give every photon exactly P / n: the sum over a
    # source's photons is its power whatever n the allocation picks.
    scene = two_rooms()
    rows = [
        {"kind": LIGHT_POINT, "position": (0.0, 0.0, 1.5), "power": 100.0, "name": "LampA"},
        {"kind": LIGHT_AREA, "position": (3.0, 0.0, 1.9), "power": 50.0, "size": [0.5, 0.5],
         "color": [1.0, 0.5, 0.25], "name": "Panel"},
        {"kind": LIGHT_SUN, "position": (0.0, 0.0, 5.0), "power": 2.0, "name": "Sun"}]
    scene = Scene(scene.mesh, scene.materials, Lights.from_list(rows), scene.camera).validate()
    on = trace(scene, _settings())
    off = trace(scene, _settings(photon_importance=False))
    counts_on = [s["global_photons"] for s in on.stats["per_source"]]
    counts_off = [s["global_photons"] for s in off.stats["per_source"]]
    assert counts_on != counts_off
    for a, b in zip(on.stats["per_source"], off.stats["per_source"]):
        np.testing.assert_allclose(a["global_flux"], a["power"], rtol=1e-9)
        np.testing.assert_allclose(b["global_flux"], b["power"], rtol=1e-9)


def test_allocation_rule():
    w = importance.weights([100.0, 100.0, 1.0], [1.0, 0.0, 0.5])
    np.testing.assert_allclose(w, [100.0, 5.0, 0.525])
    n = importance.allocate(w, 1000)
    assert n.sum() == 1000 and n.min() >= 1
    # A tiny weight still gets its photon; a zero weight none.
    assert list(importance.allocate(np.array([1.0, 1e-9, 0.0]), 10)) == [9, 1, 0]
    np.testing.assert_allclose(importance.importance_of([0.2, 0.1, 0.0]), [1.0, 0.5, 0.0])
    np.testing.assert_allclose(importance.importance_of([0.0, 0.0]), [1.0, 1.0])
    assert importance.prepass_resolution(1920, 1080) == (85, 48)
    assert importance.prepass_resolution(16, 16) == (16, 16)


def test_one_source_has_no_prepass():
    scene = two_rooms()
    one = Scene(scene.mesh, scene.materials, Lights.from_list([
        {"kind": LIGHT_POINT, "position": (0.0, 0.0, 1.5), "power": 100.0, "name": "LampA"}]),
        scene.camera).validate()
    pm = trace(one, _settings())
    assert pm.stats["importance"]["prepass"] is False
    assert pm.stats["importance"]["camera_rays"] == 0
    assert pm.stats["importance"]["pilot_rays"] == 0
    assert any("nothing to allocate" in d for d in pm.stats["decisions"])


def test_decisions_name_each_source():
    pm = trace(two_rooms(glass=True), _settings())
    d = pm.stats["decisions"]
    assert any(s.startswith("global map: 20,000 photons for final gathering") for s in d)
    assert any(s.startswith("caustic map: 10,000 photons aimed at 2 specular object") for s in d)
    a = [s for s in d if s.startswith("light 'LampA' (point, 100 W): global importance 1.00")]
    b = [s for s in d if s.startswith("light 'LampB' (point, 100 W): global importance 0.00 "
                                      "(none of its pilot photons reach the view)")]
    assert len(a) == 1 and len(b) == 1, d
    assert "caustic importance 1.00" in a[0] and "(floor)" in b[0] and "caustic" in b[0]
    assert any(s.startswith("photon importance: camera pre-pass") for s in d)
    # The caustic map too: LampB's glass sphere is in the other room.
    src = {s["name"]: s for s in pm.stats["per_source"]}
    assert src["LampB"]["caustic_fraction"] == 0.0
    assert src["LampB"]["caustic_photons"] < 0.06 * 10_000


def test_a_glossy_coat_on_a_diffuse_base_traces_caustic_photons():
    """A glossy coat on a diffuse base (a Principled wall's specular layer): the light its
    glossy lobe reflects from the lamp onto diffuse surfaces (light -> glossy -> diffuse) is
    the caustic map's (gather rays that meet a light count nothing), so the map is built
    (issue 13: the room of Principled walls was 1.3 % dark without it,
    docs/tradeoff.md "The artist scene"); a Lambert-only scene builds none."""
    scene = two_rooms()
    mats = Materials.from_list([{"diffuse": [0.6] * 3, "specular": [0.2] * 3, "roughness": 0.5},
                                {"transmission": [1, 1, 1], "ior": 1.5}])
    glossy = Scene(scene.mesh, mats, scene.lights, scene.camera).validate()
    out = integrator.render(glossy, _settings(samples=1, final_gather_rays=4))
    st = out.stats["photon_maps"]
    assert st["caustic_emitted"] > 0 and st["caustic_stored"] > 0
    assert "caustics" not in out.stats["skipped"]
    lambert = Scene(scene.mesh, Materials.from_list([{"diffuse": [0.6] * 3}] * 2),
                    scene.lights, scene.camera).validate()
    out = integrator.render(lambert, _settings(samples=1, final_gather_rays=4))
    st = out.stats["photon_maps"]
    assert st["caustic_emitted"] == 0 and st["caustic_stored"] == 0
    assert "caustics" in out.stats["skipped"]
    assert any(s.startswith("caustic map: skipped, no mirror, glass or glossy surface")
               for s in st["decisions"])


def _photon_terms(scene, **kw):
    st = RenderSettings(samples=2, final_gather_rays=16, global_k=30, caustic_k=30, threads=2,
                        global_photons=20_000, caustic_photons=20_000).with_values(**kw)
    p = integrator.render(scene, st).passes
    return p["indirect"].astype(np.float64), p["caustics"].astype(np.float64)


@pytest.mark.parametrize("term", [0, 1], ids=["indirect", "caustics"])
def test_importance_does_not_bias_the_image(term):
    # Room B's light at 10x the power: importance moves most photons to room A's light.
    # Image with importance on vs off: the difference must be within the seed-to-seed
    # noise of the off image (mean over the image, RMS over 4x4 pixel blocks). A flux
    # per photon not divided by its own source's count would shift the mean by ~90 %.
    scene = two_rooms(glass=True, power_b=1000.0)
    on = _photon_terms(scene, seed=1)[term]
    off = _photon_terms(scene, seed=1, photon_importance=False)[term]
    off2 = _photon_terms(scene, seed=2, photon_importance=False)[term]
    assert on.mean() > 0

    def block_rms(a, b):
        d = (a - b).reshape(H // 4, 4, W // 4, 4, 3).mean(axis=(1, 3))
        return float(np.sqrt(np.mean(d * d)))

    noise_mean = abs(off.mean() - off2.mean())
    assert abs(on.mean() - off.mean()) <= max(2 * noise_mean, 0.02 * off.mean())
    assert block_rms(on, off) <= 2 * block_rms(off, off2)


def test_view_grid_matches_brute_force():
    # The hash-grid neighbour test against all pairs: within the radius and on the
    # visible side of at least one visible point.
    rng = np.random.default_rng(5)
    vp = rng.uniform(-1, 1, (400, 3))
    ng = rng.normal(size=(400, 3))
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    ph = rng.uniform(-1.2, 1.2, (3000, 3))
    wd = rng.normal(size=(3000, 3))
    wd /= np.linalg.norm(wd, axis=1, keepdims=True)
    r = 0.15
    grid = importance.ViewGrid(importance.VisibleView(vp, ng, 400, 0.0), r)
    got = grid.near(ph, wd)
    d2 = np.sum((ph[:, None, :] - vp[None, :, :]) ** 2, axis=2)
    front = wd @ ng.T > 0
    want = np.any((d2 <= r * r) & front, axis=1)
    assert want.sum() > 100 and (~want).sum() > 100
    np.testing.assert_array_equal(got, want)

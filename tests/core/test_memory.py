"""The memory a render needs (core/memory.py): the estimate against the peak measured in a
fresh process, the limit (PHOTON_MAP_MEMORY_LIMIT, cgroups, physical memory) and the
refusal before any work, for both integrators and the distributed one."""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from core import memory, progressive, render
from core.integrators import direct, distributed
from core.prepared import prepare
from core.scene import contract
from core.settings import RenderSettings, SettingsError
from tests.core.scenes import caustic_scene
from tests.core.test_extremes import closed_box_scene

ROOT = pathlib.Path(__file__).resolve().parents[2]

MEASURE = r"""
import dataclasses, json, sys
sys.path.insert(0, sys.argv[1])
from core import memory, render
from core.settings import RenderSettings
from tests.core.test_extremes import closed_box_scene

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024

values = json.loads(sys.argv[2])
w, h = values.pop("resolution")
scene = closed_box_scene(0.5)
scene = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width=w, height=h))
small = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width=8, height=6))
settings = RenderSettings(seed=1).with_values(**values)
# Load (or compile) every kernel the measured render runs before the baseline.
render(small, settings.with_values(global_photons=2000, caustic_photons=1000))
before = status("VmRSS")
open("/proc/self/clear_refs", "w").write("5")  # VmHWM := VmRSS
out = render(scene, settings)
print(json.dumps({"peak": status("VmHWM") - before,
                  "estimate": memory.estimate(scene, settings).total,
                  "stored": out.stats["global_photons_stored"]}))
"""


def measure(**values):
    """{"peak": bytes above the baseline (VmHWM: numba's allocations count), "estimate",
    "stored"} of one render of the closed box in a fresh process."""
    done = subprocess.run([sys.executable, "-c", MEASURE, str(ROOT), json.dumps(values)],
                          capture_output=True, text=True, cwd=str(ROOT), timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not pathlib.Path("/proc/self/clear_refs").exists(),
                    reason="the RSS high-water mark is read from Linux's /proc")
@pytest.mark.parametrize("photons", [200_000, 400_000, 800_000])
def test_the_estimate_is_within_30_percent_of_the_measured_peak(photons):
    got = measure(resolution=[32, 24], samples=1, final_gather_rays=4,
                  global_photons=photons, caustic_photons=photons // 8)
    print(f"\n{photons} global photons: {got}, estimate / peak {got['estimate'] / got['peak']:.2f}")
    assert 0.7 * got["peak"] <= got["estimate"] <= 1.3 * got["peak"], got


def test_stored_photons_are_the_albedo_series_in_a_closed_box():
    """Each photon is stored at every hit until absorbed: sum_{b < B} a^b per emitted
    photon (a glass sphere of albedo 1 raises the box's 0.5 a little)."""
    scene = closed_box_scene(0.5)
    a = memory.mean_albedo(scene)
    assert 0.5 < a < 0.56
    assert memory.stored_per_emitted(scene, 8) == pytest.approx((1 - a**8) / (1 - a))
    assert memory.stored_per_emitted(scene, 8, first_stored=False) == pytest.approx(
        (1 - a**8) / (1 - a) - 1)


# --- the limit --------------------------------------------------------------------------------

@pytest.mark.parametrize("text, value", [("12345", 12345), ("512M", 512 << 20),
                                         ("8 GiB", 8 << 30), ("16GB", 16 * 10**9),
                                         ("1.5e9", 1_500_000_000), ("2k", 2048)])
def test_the_limit_takes_bytes_or_a_unit(text, value):
    assert memory.parse_bytes(text) == value


@pytest.mark.parametrize("text", ["", "lots", "12 parsecs", "-5G", "0"])
def test_a_bad_limit_names_the_variable(text):
    with pytest.raises(SettingsError, match="PHOTON_MAP_MEMORY_LIMIT"):
        memory.parse_bytes(text)


def test_the_variable_replaces_the_detected_limit(monkeypatch):
    monkeypatch.setenv(memory.ENV_LIMIT, "3G")
    assert memory.memory_limit() == (3 << 30, memory.ENV_LIMIT)
    monkeypatch.delenv(memory.ENV_LIMIT)
    limit, source = memory.memory_limit()
    assert source in ("the cgroup limit", "physical memory")
    assert 0 < limit <= memory.physical_memory()


# --- the refusal ----------------------------------------------------------------------------

def test_a_tiny_limit_refuses_a_render_before_any_work(monkeypatch):
    monkeypatch.setenv(memory.ENV_LIMIT, "10M")
    scene = closed_box_scene(0.5)
    settings = RenderSettings(global_photons=1_000_000)
    need = memory.estimate(scene, settings)
    with pytest.raises(memory.MemoryLimitError) as refused:
        render(scene, settings, on_progress=lambda *a: pytest.fail("work was done"))
    assert str(refused.value) == (
        f'this render needs about {need.total / 2**20:.0f} MiB of memory, more than the '
        f'10 MiB available (PHOTON_MAP_MEMORY_LIMIT: 10 MiB); lower "Global Photons" '
        f'(the largest part, {need.parts["photons"] / 2**20:.0f} MiB), or set '
        f'PHOTON_MAP_MEMORY_LIMIT to raise the limit')
    # A SettingsError: Blender reports it (photon_engine/render.py) and keeps its state.
    assert isinstance(refused.value, SettingsError)
    # Raising the limit lets it through (a small render, the same estimate path).
    monkeypatch.setenv(memory.ENV_LIMIT, "64G")
    out = render(scene, RenderSettings(samples=1, global_photons=2000, caustic_photons=500,
                                       final_gather_rays=4))
    assert np.all(np.isfinite(out.passes["combined"]))


def test_a_large_resolution_names_resolution(monkeypatch):
    import dataclasses
    monkeypatch.setenv(memory.ENV_LIMIT, "100M")
    scene = closed_box_scene(0.5)
    scene = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width=7000,
                                                                   height=4000))
    with pytest.raises(memory.MemoryLimitError, match='lower "Resolution"'):
        render(scene, RenderSettings(samples=1, global_photons=1000))


def test_the_progressive_integrator_is_refused_naming_photons_per_pass(monkeypatch):
    monkeypatch.setenv(memory.ENV_LIMIT, "10M")
    settings = RenderSettings(integrator="progressive", photons_per_pass=1_000_000)
    with pytest.raises(memory.MemoryLimitError, match='lower "Photons per Pass"'):
        render(closed_box_scene(0.5), settings)
    with pytest.raises(memory.MemoryLimitError, match='lower "Photons per Pass"'):
        progressive(closed_box_scene(0.5), settings)


def test_the_distributed_estimate_is_the_same_function():
    scene = closed_box_scene(0.5)
    settings = RenderSettings(integrator="progressive", photons_per_pass=300_000)
    assert distributed.memory_estimate(scene, settings) == memory.estimate(scene, settings).total
    more = settings.with_values(photons_per_pass=600_000)
    assert distributed.memory_estimate(scene, more) > distributed.memory_estimate(scene, settings)


@pytest.mark.parametrize("points", [1000, 300_000, 3_000_000])
@pytest.mark.parametrize("light_samples", [1, 4, 64])
def test_the_estimate_holds_direct_lights_slots(points, light_samples):
    """direct.shade allocates its (point, light sample) slots per kernel call: as many of
    the (source, light sample) pairs as SHADE_SLOTS allows, at least one. The estimate's
    count bounds that for any sources the scene can have (its lights, the emissive
    triangles, the world)."""
    assert memory.SHADE_SLOTS == direct.SHADE_SLOTS
    scene = closed_box_scene(0.5)
    st = RenderSettings(light_samples=light_samples)
    bound = memory.shade_slots(scene, st, points)
    for sources in range(1, scene.lights.count + 3):
        pairs = sources * light_samples
        per_call = max(1, min(pairs, direct.SHADE_SLOTS // points))  # as direct.shade
        assert per_call * points <= bound
    # and the bound is no looser than the cap or one slot a point
    assert bound == max(points, min(memory.SHADE_SLOTS,
                                    points * (scene.lights.count + 2) * light_samples))
    # a render's estimate grows by those bytes with the light samples where the camera
    # pass's tile is its peak (256 x 256 x 16 samples: SAMPLES_PER_TILE in flight)
    import dataclasses
    wide = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width=256,
                                                                  height=256))
    est = {k: memory.estimate(wide, RenderSettings(samples=16, global_photons=1000,
                                                   caustic_photons=100, light_samples=k))
           for k in (1, 64)}
    assert "tile" in est[1].parts
    tile = memory.SAMPLES_PER_TILE
    assert est[64].total - est[1].total == memory.BYTES_PER_SHADE_SLOT * (
        memory.shade_slots(wide, RenderSettings(light_samples=64), tile)
        - memory.shade_slots(wide, RenderSettings(light_samples=1), tile)) > 0


def test_the_cache_fraction_is_the_caches_point_count():
    """memory.cache_fraction mirrors gather.cache_point_count (memory.py does not import
    the integrators): with the automatic radius, for several k; the cap for a small
    hand-set radius."""
    from core.integrators import gather
    from core.photons import estimate

    assert memory.CACHE_FRACTION == gather.CACHE_FRACTION
    assert memory.CACHE_POINTS_PER_DISC == gather.CACHE_POINTS_PER_DISC
    assert memory.RADIUS_FACTOR == estimate.RADIUS_FACTOR
    area, stored = 7.0, 400_000
    for k in (10, 50, 100, 150):
        r = estimate.auto_radius(area, k, stored)
        want = gather.cache_point_count(stored, area, r) / stored
        got = memory.cache_fraction(RenderSettings(global_k=k))
        assert got == pytest.approx(want, abs=2 / stored), k
    assert memory.cache_fraction(RenderSettings(global_radius=1e-3)) == gather.CACHE_FRACTION


@pytest.mark.parametrize("rows", [
    [dict(kind=0, params=dict(color=0.8))],                            # Diffuse
    [dict(kind=5, params=dict(color=0.8, roughness=0.5))],             # Sheen
    [dict(kind=7)],                                                    # default Principled
    [dict(kind=0, params=dict(color=0.8)), dict(kind=1, weight=0.3)],  # Diffuse + Glossy
])
def test_the_estimate_counts_the_caustic_map_where_the_render_builds_one(rows):
    """memory.py (which reads the scene contract only) and the renderer
    (photon_terms: a material with a glossy, mirror or glass lobe, ``specular_material``)
    agree on whether a caustic map is built: a Principled wall's specular layer counts."""
    base = caustic_scene()
    mats = contract.Materials.from_list([{"closures": rows}] * base.materials.count)
    scene = contract.Scene(base.mesh, mats, base.lights, base.camera).validate()
    with prepare(scene) as prepared:
        built = bool(np.any(prepared.used_materials & prepared.specular_material))
    assert memory.has_specular(scene) == built

"""The memory a render needs, estimated before any work, and the memory there is.

``estimate(scene, settings)`` adds up what a render holds at its peak, for either
integrator (the progressive one on one machine or on a Dask worker:
core/integrators/distributed.py asks the same function):

- the scene: the prepared tables and Embree's tree per triangle, the textures;
- the photon pass: photons stored x bytes per stored photon at the peak (the tracer's
  per-bounce pieces, PhotonMap construction, the radiance cache of final gathering), plus
  one chunk of photons in flight (``tracing.CHUNK``);
- the camera pass: the per-pixel accumulators x resolution, the camera samples in flight
  (a tile), the final-gather rays traced together (``gather.GATHER_BATCH``) and direct
  light's (point, light sample) slots of one kernel call (``direct.SHADE_SLOTS``).

Photons stored are not known before tracing: a photon is stored at each diffuse hit until
Russian roulette absorbs it, so the global map is estimated at sum_{b < B} a^b per emitted
photon, with a the scene's mean albedo (area-weighted over triangles, luminance of all
lobes) and B the bounce limit: exact for a closed scene, an upper bound for an open one
(photons that leave it are not stored).

``check(scene, settings)`` refuses (``MemoryLimitError``, a SettingsError: Blender reports
it and keeps its state) a render whose estimate, with what the process already holds, is
above the memory available: ``PHOTON_MAP_MEMORY_LIMIT`` when set (bytes, or a number with
a unit: 512M, 8 GiB, 1.5e9), else the cgroup v2 / v1 limit of this process where there is
one, else the physical memory. The message gives both figures and the setting to lower,
in the UI's words.

The byte constants were measured (RSS high-water of a render in a fresh process, after
the kernels were loaded) in tests/core/test_memory.py (``measure``), which holds the estimate within 30 % of the measured peak at three
sizes.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from .color import LUMINANCE
from .scene.closures import CLOSURE_DIFFUSE, CLOSURE_SHEEN, CLOSURE_TRANSLUCENT
from .scene.contract import Scene
from .settings import RenderSettings, SettingsError

ENV_LIMIT = "PHOTON_MAP_MEMORY_LIMIT"
"""Environment variable replacing the detected limit (bytes, or with a unit)."""

# Measured constants (bytes): tests/core/test_memory.py ``measure`` (the closed box: 103 B
# per stored photon between 0.4 and 1.6 million stored, 53 MB at 200 000 emitted).
BASE = 16 << 20
"""What any render allocates whatever its size (small tables, numba's working memory)."""
BYTES_PER_TRIANGLE = 400
"""The prepared scene's per-triangle tables and Embree's tree."""
TEXTURE_FACTOR = 2.0
"""Texture memory held during a render per byte of the scene's texels."""
BYTES_PER_STORED_PHOTON = 40
"""Peak of the photon pass per global photon stored with final gathering, its radiance
cache apart (BYTES_PER_CACHE_POINT): fitted with BYTES_PER_PHOTON_IN_FLIGHT to the peaks
tests/core/test_memory.py measures (2026-12-05: 62.9 / 82.3 / 125.3 MB above the baseline
for 0.40 / 0.79 / 1.59 M stored, 200k / 400k / 800k emitted; the map of final gathering
holds the direct photons, about twice the stored photons of the same emission)."""
BYTES_PER_CACHE_POINT = 180
"""A radiance-cache point at its build (its k-NN rows, both sides' estimates, the tree):
what the peaks fell by when the cache went from 0.25 to 0.06 points per photon."""
BYTES_PER_STORED_PHOTON_NO_CACHE = 75
"""The same for a map without the radiance cache (caustic map, preview)."""
BYTES_PER_MAP_PHOTON = 40
"""A photon of a built map kept through the camera pass (23 B encoded, the tree, its cache
share)."""
BYTES_PER_PHOTON_IN_FLIGHT = 120
"""A photon of the tracer's chunk (tracing.CHUNK photons at most); fitted with
BYTES_PER_STORED_PHOTON (200 until 2026-12-05, when the preview map's estimate read
1.4-1.5x its measured peak)."""
BYTES_PER_SAMPLE_IN_FLIGHT = 80
"""A camera sample of a tile being shaded (rays, hits, throughput, the terms)."""
BYTES_PER_GATHER_RAY = 40
"""A final-gather ray of a batch (origin, direction, hit, radiance, indices)."""
BYTES_PER_VISIBLE_POINT = 400
"""An SPPM visible point with its statistics and the pass's gather."""
BYTES_PER_PASS_PHOTON = 120
"""A photon stored in an SPPM pass (float64 copies, the hash grid)."""

CHUNK = 1 << 18
"""Photons traced together (core/photons/tracing.py CHUNK)."""
SAMPLES_PER_TILE = 4 << 16
"""Most camera samples of a tile (photon_mapping: TILE_GROWTH x TARGET_SAMPLES_PER_TILE)."""
GATHER_BATCH = 1 << 20
"""Most final-gather rays traced together (core/integrators/gather.py GATHER_BATCH)."""
SHADE_SLOTS = 1 << 20
"""Most (point, light sample) slots of one direct-light kernel call, unless one point per
slot is more (core/integrators/direct.py SHADE_SLOTS)."""
BYTES_PER_SHADE_SLOT = 53
"""A slot's contribution (3 float64) and shadow ray (7 float32 and a bool)."""
CACHE_FRACTION = 0.25
"""Most radiance-cache points per stored global photon (core/integrators/gather.py)."""
CACHE_POINTS_PER_DISC = 12.0
"""Radiance-cache points per disc of the global radius (core/integrators/gather.py)."""
RADIUS_FACTOR = 2.0
"""The automatic radius over the k-nearest one (core/photons/estimate.py)."""


def cache_fraction(settings: RenderSettings) -> float:
    """Radiance-cache points per stored global photon: ``gather.cache_point_count`` with
    the automatic radius (a disc of RADIUS_FACTOR^2 k photons), CACHE_FRACTION for a
    hand-set radius (which may be small)."""
    if settings.global_radius > 0.0:
        return CACHE_FRACTION
    return min(CACHE_FRACTION, CACHE_POINTS_PER_DISC / (RADIUS_FACTOR ** 2 * settings.global_k))

UNITS = {"": 1, "b": 1, "k": 1 << 10, "kib": 1 << 10, "kb": 10**3, "m": 1 << 20,
         "mib": 1 << 20, "mb": 10**6, "g": 1 << 30, "gib": 1 << 30, "gb": 10**9,
         "t": 1 << 40, "tib": 1 << 40, "tb": 10**12}
"""Units of ENV_LIMIT: K/M/G/T and KiB... are powers of 1024, KB/MB/GB/TB of 1000."""


class MemoryLimitError(SettingsError):
    """A render refused before any work: it needs more memory than there is."""


@dataclass(frozen=True)
class MemoryEstimate:
    """``parts``: {what: bytes} at the render's peak; ``settings``: {what: the UI setting
    that lowers it}; ``total`` their sum, bytes."""

    parts: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    @property
    def total(self) -> int:
        return int(sum(self.parts.values()))

    def largest(self) -> str:
        """The part a setting lowers that needs the most."""
        return max((p for p in self.parts if self.settings.get(p)), key=self.parts.get)


def mean_albedo(scene: Scene) -> float:
    """The scene's mean surface albedo in [0, 1]: the luminance of each material's lobes
    summed (diffuse, glossy, transmission), weighted by the area of its triangles."""
    mesh, mats = scene.mesh, scene.materials
    if mesh.triangle_count == 0 or mats.count == 0:
        return 0.0
    v = mesh.vertices[mesh.triangles].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    lum = np.asarray(LUMINANCE, np.float64)
    lobes = (np.asarray(mats.diffuse, np.float64) + np.asarray(mats.specular, np.float64)
             + np.asarray(mats.transmission, np.float64))
    albedo = np.clip(lobes @ lum, 0.0, 1.0)
    total = float(area.sum())
    if not np.isfinite(total) or total <= 0.0:
        return 0.0
    return float(np.dot(area, albedo[mesh.material_index]) / total)


def stored_per_emitted(scene: Scene, max_bounces: int, first_stored: bool = True) -> float:
    """Photons stored per emitted photon in the global map: sum_{b < B} a^b (module doc),
    without the first hit's term when the first hit is not stored (the preview's map)."""
    a = mean_albedo(scene)
    b = int(max_bounces)
    series = float(b) if a >= 1.0 else (1.0 - a**b) / (1.0 - a)
    return max(0.0, series - (0.0 if first_stored else 1.0))


def has_specular(scene: Scene) -> bool:
    """A material with a glossy, mirror or glass lobe (the caustic map is built): the legacy
    lobes' specular or transmission, or a closure other than Diffuse, Translucent and Sheen (a
    Principled BSDF's specular layer counts, core/integrators/photon_terms.py)."""
    mats = scene.materials
    if mats.closure_kind is not None and np.any(~np.isin(
            np.asarray(mats.closure_kind), (CLOSURE_DIFFUSE, CLOSURE_TRANSLUCENT, CLOSURE_SHEEN))):
        return True
    return bool(np.any(np.asarray(mats.specular) > 0) or np.any(np.asarray(mats.transmission) > 0))


def shade_slots(scene: Scene, settings: RenderSettings, points: int) -> int:
    """Direct light's slots at ``points`` shading points at once (``direct.shade``: as many
    (source, light sample) pairs a call as SHADE_SLOTS allows, at least one), with every
    light, the emissive triangles and the world counted as sources (an upper bound)."""
    pairs = (scene.lights.count + 2) * max(1, int(settings.light_samples))
    return max(points, min(SHADE_SLOTS, points * pairs))


def estimate(scene: Scene, settings: RenderSettings) -> MemoryEstimate:
    """Bytes at the peak of rendering ``scene`` with ``settings`` (module doc), by part."""
    st = settings
    cam = scene.camera
    pixels = int(cam.width) * int(cam.height)
    parts = {"base": BASE,
             "scene": BYTES_PER_TRIANGLE * scene.mesh.triangle_count
             + int(TEXTURE_FACTOR * np.asarray(scene.textures.pixels).nbytes)}
    names = {"base": "", "scene": "the scene's geometry and image textures"}
    if st.integrator == "progressive":
        stored = st.photons_per_pass * stored_per_emitted(scene, st.photon_max_bounces)
        parts["photons"] = int(BYTES_PER_PASS_PHOTON * stored
                               + BYTES_PER_PHOTON_IN_FLIGHT * min(st.photons_per_pass, CHUNK))
        names["photons"] = '"Photons per Pass"'
        # The visible points, the image sums (float64 total and pass, float32 result),
        # direct light's slots at the visible points.
        parts["pixels"] = int(pixels * (BYTES_PER_VISIBLE_POINT + 2 * 24 + 12)
                              + BYTES_PER_SHADE_SLOT * shade_slots(scene, st, pixels))
        names["pixels"] = '"Resolution"'
        return MemoryEstimate(parts, names)
    gather = st.indirect_mode == "final_gather"
    n_global = 0.0
    if st.indirect_mode != "off" and st.global_photons:
        n_global = st.global_photons * stored_per_emitted(scene, st.photon_max_bounces,
                                                          first_stored=gather)
    n_caustic = 0.0
    if st.caustics and st.caustic_photons and has_specular(scene):
        n_caustic = float(st.caustic_photons)  # at most one store per photon
    per_global = (BYTES_PER_STORED_PHOTON + BYTES_PER_CACHE_POINT * cache_fraction(st)
                  if gather else BYTES_PER_STORED_PHOTON_NO_CACHE)
    in_flight = BYTES_PER_PHOTON_IN_FLIGHT * min(max(st.global_photons, st.caustic_photons),
                                                  CHUNK)
    # The global map is built before the caustic map, which is traced while it is kept.
    photon_peak = max(per_global * n_global + (in_flight if n_global else 0),
                      BYTES_PER_MAP_PHOTON * n_global
                      + BYTES_PER_STORED_PHOTON_NO_CACHE * n_caustic
                      + (in_flight if n_caustic else 0))
    maps_kept = BYTES_PER_MAP_PHOTON * (n_global + n_caustic)
    outputs = len(st.passes()) + 1 + (2 if st.denoising_data else 0)
    images = pixels * 24 * outputs
    samples = min(pixels * st.samples, SAMPLES_PER_TILE)
    rays = 0
    if gather and n_global:
        rays = min(GATHER_BATCH, samples * max(1, st.final_gather_rays // st.samples))
    tile = (BYTES_PER_SAMPLE_IN_FLIGHT * samples + BYTES_PER_GATHER_RAY * rays
            + BYTES_PER_SHADE_SLOT * shade_slots(scene, st, samples))
    assembled = pixels * (12 * outputs + 24)
    camera_peak = images + max(tile, assembled)
    if photon_peak >= maps_kept + camera_peak:
        parts["photons"] = int(photon_peak)
    else:
        parts["photons"] = int(maps_kept)
        parts["pixels"] = int(images + assembled if assembled >= tile else images)
        if tile > assembled:
            parts["tile"] = int(tile)
    if n_caustic > n_global:
        names["photons"] = '"Caustic Photons"'
    else:
        names["photons"] = '"Global Photons"'
    names["pixels"] = '"Resolution"'
    names["tile"] = '"Final Gather Rays"' if rays else '"Samples"'
    return MemoryEstimate(parts, names)


def parse_bytes(text: str) -> int:
    """Bytes from ``text``: an integer or a number with a unit of UNITS (case and spaces
    ignored). Raises SettingsError naming ENV_LIMIT."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", text or "")
    unit = m.group(2).lower() if m else None
    if m is None or unit not in UNITS:
        raise SettingsError(f'{ENV_LIMIT} must be bytes or a number with a unit '
                            f'(e.g. 512M, 8GiB, 16GB), got {text!r}')
    value = float(m.group(1)) * UNITS[unit]
    if not np.isfinite(value) or value < 1:
        raise SettingsError(f"{ENV_LIMIT} must be at least 1 byte, got {text!r}")
    return int(value)


def _read(path: str) -> str | None:
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return None


def cgroup_limit() -> int | None:
    """This process's cgroup memory limit in bytes (v2: the smallest ``memory.max`` on
    its cgroup's path; v1: ``memory.limit_in_bytes``), None without one."""
    own = _read("/proc/self/cgroup") or ""
    limits = []
    for line in own.splitlines():
        _, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if controllers == "":  # v2: 0::/path
            parts = [p for p in path.split("/") if p]
            for k in range(len(parts), -1, -1):
                text = _read(os.path.join("/sys/fs/cgroup", *parts[:k], "memory.max"))
                if text and text != "max":
                    limits.append(int(text))
        elif "memory" in controllers.split(","):
            for base in (os.path.join("/sys/fs/cgroup/memory", path.lstrip("/")),
                         "/sys/fs/cgroup/memory"):
                text = _read(os.path.join(base, "memory.limit_in_bytes"))
                if text and text.isdigit() and int(text) < (1 << 60):  # "no limit": ~2^63
                    limits.append(int(text))
                    break
    return min(limits) if limits else None


def physical_memory() -> int | None:
    """Physical memory in bytes, None where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def memory_limit() -> tuple[int | None, str]:
    """(bytes, where the figure comes from): ENV_LIMIT, else the cgroup limit, else the
    physical memory; (None, "") when nothing is known."""
    text = os.environ.get(ENV_LIMIT, "").strip()
    if text:
        return parse_bytes(text), ENV_LIMIT
    limit = cgroup_limit()
    if limit is not None:
        return limit, "the cgroup limit"
    limit = physical_memory()
    return (limit, "physical memory") if limit is not None else (None, "")


def resident_bytes() -> int:
    """What this process holds now (VmRSS), 0 where unknown."""
    for line in (_read("/proc/self/status") or "").splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def _size(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def check(scene: Scene, settings: RenderSettings, what: str = "this render") -> MemoryEstimate:
    """The estimate, or MemoryLimitError when it does not fit in the memory available
    (the limit less what this process already holds)."""
    need = estimate(scene, settings)
    limit, source = memory_limit()
    if limit is None:
        return need
    held = resident_bytes() if source != ENV_LIMIT else 0
    available = limit - held
    if need.total > available:
        part = need.largest()
        lower = need.settings[part]
        held_text = f", {_size(held)} of it already in use" if held else ""
        raise MemoryLimitError(
            f"{what} needs about {_size(need.total)} of memory, more than the "
            f"{_size(max(available, 0))} available ({source}: {_size(limit)}{held_text}); "
            f"lower {lower} (the largest part, {_size(need.parts[part])}), or set "
            f"{ENV_LIMIT} to raise the limit")
    return need

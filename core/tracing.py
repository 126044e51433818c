"""The photon pass: trace photons from the lights into a global and a caustic PhotonMap.

Wavefront: the photons of a source are emitted in chunks (``emission.emit``); each bounce
intersects the whole chunk in Embree, then one numba kernel (``scatter.scatter_kernel``)
stores and scatters every photon; the survivors are compacted with numpy and the loop goes
on until no photon is left or ``photon_max_bounces`` bounces were made. No Python code
runs per photon.

Maps (flux in watts per stored photon: a map's flux summed over a region / area =
irradiance, W/m^2):
- global: photons emitted unaimed (``global_photons`` of them, shared between the sources
  in proportion to their power, times their importance), stored at every hit on a surface with a diffuse lobe;
  with ``include_direct=False`` only after at least one diffuse bounce (``scatter.STORE_*``).
- caustic: photons aimed at the specular objects (projection map, ``caustic_photons``),
  stored at the first diffuse hit of paths light -> specular+ -> diffuse.

With more than one source, each map's photons are shared by power x visual importance
(``photon_importance``; core/importance.py: a camera pre-pass and pilot photons), still
unbiased: every photon's flux is divided by its own source's count.

What is skipped and why, and how many photons each source gets, is listed in
``stats["decisions"]``, one line each (the render log prints them).

Determinism: a photon's random numbers are counter hashes of (seed, map, source, photon
index, bounce), so the maps do not depend on chunk sizes or threads; the stored photons
are concatenated in emission order, bounce by bounce.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numba
import numpy as np

from . import bsdf, emission, geometry, sampling, scatter, textures
from .accel import Accelerator, default_threads
from .lights import EmissiveTriangles, LightSet
from .photon_map import PhotonMap
from .scene import Scene
from .settings import RenderSettings

ProgressFn = Callable[[float, str], bool]

# Photons emitted and traced together: big enough for Embree's batch rate, small enough
# that a chunk's arrays (~250 B per photon) stay near 60 MB.
CHUNK = 1 << 18
MAP_GLOBAL = 0
MAP_CAUSTIC = 1


@dataclass
class PhotonMaps:
    """global_map: photons at diffuse hits, or None when not built.
    caustic_map: photons of light -> specular+ -> diffuse paths, or None.
    global_emitted / caustic_emitted: photons emitted for each map (their flux is already
    divided by these counts). stats: counts, times, which maps were built and why not."""

    global_map: PhotonMap | None
    caustic_map: PhotonMap | None
    global_emitted: int
    caustic_emitted: int
    stats: dict = field(default_factory=dict)


@dataclass
class _Setup:
    tri_v: np.ndarray
    tri_n: np.ndarray
    tri_mat: np.ndarray
    extent: float
    mats: dict
    light_set: LightSet
    emissive: EmissiveTriangles
    world: np.ndarray
    centre: np.ndarray
    radius: float
    objects: emission.Targets
    specular_objects: np.ndarray
    surfaces: textures.SurfaceTextures | None = None


def _setting(settings, name, default):
    return getattr(settings, name, default)


def _prepare(scene: Scene) -> _Setup:
    mesh = scene.mesh
    tri_v = np.ascontiguousarray(mesh.triangle_vertices(), np.float32)
    mats = bsdf.material_table(scene.materials)
    lo, hi = scene.bounds()
    if mesh.vertices.size:
        glo = mesh.vertices.min(axis=0).astype(np.float64)
        ghi = mesh.vertices.max(axis=0).astype(np.float64)
    else:
        glo = ghi = np.zeros(3)
    centre, radius = emission.bounding_sphere(glo, ghi)
    n_obj = int(mesh.object_index.max()) + 1 if mesh.triangle_count else 0
    objects = emission.object_spheres(tri_v, mesh.object_index, n_obj)
    spec_mat = np.any(mats["specular"] > 0, axis=1) | np.any(mats["transmission"] > 0, axis=1)
    spec_obj = np.zeros(n_obj, bool)
    if mesh.triangle_count:
        spec_obj[np.unique(mesh.object_index[spec_mat[mesh.material_index]])] = True
    return _Setup(
        tri_v=tri_v, tri_n=np.ascontiguousarray(mesh.normals, np.float32),
        tri_mat=np.ascontiguousarray(mesh.material_index, np.int32),
        extent=geometry.scene_extent(lo, hi), mats=mats,
        light_set=LightSet.from_lights(scene.lights),
        emissive=EmissiveTriangles.from_mesh(mesh, scene.materials),
        world=np.asarray(scene.world.radiance, np.float64).reshape(3),
        centre=centre, radius=radius * 1.01 if radius > 0 else 0.0, objects=objects,
        specular_objects=spec_obj, surfaces=textures.SurfaceTextures(scene, mats["diffuse"]))


class _Store:
    """Stored photons, appended per bounce as arrays (float32)."""

    def __init__(self):
        self.pos, self.flux, self.dir = [], [], []
        self.count = 0

    def add(self, pos, flux, direction):
        if pos.shape[0]:
            self.pos.append(pos)
            self.flux.append(flux)
            self.dir.append(direction)
            self.count += pos.shape[0]

    def take(self):
        """The stored (M, 3) float32 arrays; the per-bounce pieces are released one array
        at a time, so the peak is one array's copy, not all three."""
        out = []
        for name in ("pos", "flux", "dir"):
            parts = getattr(self, name)
            out.append(np.concatenate(parts) if parts else np.zeros((0, 3), np.float32))
            setattr(self, name, [])
        return out


def _trace_chunk(setup: _Setup, accel, em: emission.Emitted, pid: np.ndarray, mode: int,
                 store_rule: int, max_bounces: int, seed: int, map_id: int,
                 store: _Store, counters: dict) -> None:
    """Trace one chunk of emitted photons through every bounce into ``store``."""
    keep = np.any(em.flux > 0, axis=1)
    if keep.all():  # the usual case: no boolean indexing (~30 ns per (N, 3) row)
        o, d, f = em.origin.astype(np.float32), em.direction.astype(np.float32), em.flux
    else:
        idx = np.flatnonzero(keep)
        o, d = em.origin[idx].astype(np.float32), em.direction[idx].astype(np.float32)
        f, pid = em.flux[idx], pid[idx]
    n_diff = np.zeros(o.shape[0], np.int32)
    n_spec = np.zeros(o.shape[0], np.int32)
    dims = np.array([sampling.stream(sampling.PHOTON, 1 + map_id, k) for k in range(4)], np.int64)
    m = setup.mats
    for bounce in range(max_bounces + 1):
        n = o.shape[0]
        if n == 0:
            break
        t0 = time.perf_counter()
        hits = accel.intersect(o, d)
        t1 = time.perf_counter()
        counters["rays"] += n
        counters["time_intersect"] += t1 - t0
        s_flag = np.empty(n, bool)
        s_pos = np.empty((n, 3), np.float32)
        s_flux = np.empty((n, 3), np.float32)
        s_dir = np.empty((n, 3), np.float32)
        alive = np.empty(n, bool)
        # float32 origins and directions: what Embree takes, so no conversion per bounce.
        o2 = np.empty((n, 3), np.float32)
        d2 = np.empty((n, 3), np.float32)
        f2 = np.empty((n, 3))
        surf = setup.surfaces
        scatter.scatter_kernel(setup.tri_v, setup.tri_n, setup.tri_mat, setup.extent,
                               m["diffuse"], m["specular"], m["transmission"], m["alpha"], m["ior"],
                               surf.photon_albedo(hits.prim, hits.u, hits.v),
                               surf.photon_opacity(hits.prim, hits.u, hits.v),
                               hits.prim, hits.u, hits.v, d, f, pid, n_diff, n_spec,
                               np.int64(seed), dims, np.int64(bounce), mode,
                               np.int64(store_rule), bounce == max_bounces, s_flag, s_pos,
                               s_flux, s_dir, alive, o2, d2, f2)
        store.add(*scatter.compact_stored(s_flag, s_pos, s_flux, s_dir))
        o, d, f, pid, n_diff, n_spec = scatter.compact_alive(alive, o2, d2, f2, pid, n_diff, n_spec)
        counters["time_scatter"] += time.perf_counter() - t1


def _trace_map(setup, accel, sources, counts, targets_per_source, mode, store_rule,
               settings, map_id, counters, progress, done_before, total_work, flux_out=None):
    """Emit counts[s] photons from each source and trace them; returns (store, cancelled).
    flux_out: optional (S, 3) float64 array, += the flux each source emitted (watts)."""
    seed = int(_setting(settings, "seed", 0))
    max_bounces = int(_setting(settings, "photon_max_bounces", 8))
    store = _Store()
    first_id = 0
    done = done_before
    for slot, (src, n_src) in enumerate(zip(sources, counts)):
        n_src = int(n_src)
        targets, probs = targets_per_source[slot]
        for first in range(0, n_src, CHUNK):
            count = min(CHUNK, n_src - first)
            t0 = time.perf_counter()
            em = emission.emit(src, setup.light_set, setup.emissive, setup.world, setup.centre,
                               setup.radius, n_src, first, count, seed=seed, map_id=map_id,
                               source_slot=slot, targets=targets, target_prob=probs,
                               extent=setup.extent)
            counters["time_emission"] += time.perf_counter() - t0
            if flux_out is not None:
                flux_out[slot] += em.flux.sum(axis=0)
            pid = np.arange(first_id + first, first_id + first + count, dtype=np.int64)
            t1 = time.perf_counter()
            _trace_chunk(setup, accel, em, pid, mode, store_rule, max_bounces, seed, map_id,
                         store, counters)
            counters["time_tracing"] += time.perf_counter() - t1
            done += count
            if progress is not None and progress(min(done / max(total_work, 1), 1.0),
                                                 f"Traced {done}/{total_work} photons"):
                return store, True
        first_id += n_src
    return store, False


def _build(store: _Store, counters: dict):
    t0 = time.perf_counter()
    # From the per-bounce pieces, encoded piece by piece (no float64 copies of the map).
    pm = PhotonMap.from_parts(store.pos, store.flux, store.dir) if store.count else None
    store.count = 0
    counters["time_balancing"] += time.perf_counter() - t0
    return pm


@dataclass(frozen=True)
class _PassSettings:
    """The two settings _trace_map reads, for trace_stored_photons."""

    seed: int
    photon_max_bounces: int


def prepare(scene: Scene) -> _Setup:
    """The per-scene tables photon passes share (triangles, materials, lights, bounds)."""
    return _prepare(scene)


def photon_sources(setup: _Setup, with_world: bool = True) -> list:
    """The emitting sources of a prepared scene (``emission.Source``), power-weighted."""
    spheres = setup.objects if setup.objects.count else None
    return emission.source_powers(setup.light_set, setup.emissive, setup.world, setup.centre,
                                  setup.radius, spheres, with_world)


def trace_stored_photons(setup: _Setup, accel, sources: list, n_photons: int, *, seed: int,
                         max_bounces: int, store_rule: int = scatter.STORE_ALL):
    """Trace ``n_photons`` unaimed photons (shared between ``sources`` by power) and return
    the photons stored at diffuse hits as raw arrays, without building a PhotonMap.

    The global map's rules (``scatter.MODE_GLOBAL``, stored by ``store_rule``); for
    progressive passes that need one batch of photons at a time. Returns (positions
    (M, 3) float32 metres, flux (M, 3) float32 watts already divided by the photons
    emitted, incident directions (M, 3) float32 pointing back towards where each photon
    came from, counters dict).
    """
    counters = {"rays": 0, "time_emission": 0.0, "time_tracing": 0.0, "time_intersect": 0.0,
                "time_scatter": 0.0, "time_balancing": 0.0}
    if not sources or n_photons <= 0:
        z = np.zeros((0, 3), np.float32)
        return z, z.copy(), z.copy(), counters
    counts = emission.allocate(np.array([emission.luminance(s.power) for s in sources]),
                               int(n_photons))
    params = _PassSettings(seed=int(seed), photon_max_bounces=int(max_bounces))
    store, _ = _trace_map(setup, accel, sources, counts, [(None, None)] * len(sources),
                          scatter.MODE_GLOBAL, store_rule, params, MAP_GLOBAL, counters,
                          None, 0, int(counts.sum()))
    pos, flux, direction = store.take()
    return pos, flux, direction, counters


_KIND_NAMES = {0: "point", 1: "spot", 2: "sun", 3: "area"}


def _source_label(src, light_set: LightSet) -> str:
    """How the log names a source: "light 'Lamp' (point, 100 W)", "world (background, 3 W)"."""
    watts = f"{float(emission.luminance(src.power)):,.4g} W"
    if src.index >= 0:
        return f"light '{src.name}' ({_KIND_NAMES.get(int(light_set.kind[src.index]), 'light')}, {watts})"
    kind = "mesh" if src.index == emission.SOURCE_TRIANGLES else "background"
    return f"{src.name} ({kind}, {watts})"


def _pilot_fractions(setup, accel, sources, targets_per_source, power_lum, mode, store_rule,
                     seed, max_bounces, map_id, n_pilot, grid, counters):
    """Step 2-3 of core/importance.py: per source, the fraction f_s of its power (luminance)
    that its n_pilot pilot photons store near the visible points (``grid``). (S,) float64."""
    from . import importance, sppm

    frac = np.zeros(len(sources))
    for slot, src in enumerate(sources):
        # A seed of its own per (source, map): the pilot shares no random numbers with
        # the real pass, whose streams are keyed by (seed, map 0/1, slot).
        params = _PassSettings(seed=sppm.pass_seed(seed, (1 << 20) + 2 * slot + map_id),
                               photon_max_bounces=max_bounces)
        store, _ = _trace_map(setup, accel, [src], np.array([n_pilot]), [targets_per_source[slot]],
                              mode, store_rule, params, importance.MAP_PILOT + map_id, counters,
                              None, 0, n_pilot)
        pos, flux, direction = store.take()
        if pos.shape[0] and power_lum[slot] > 0:
            near = grid.near(pos, direction)
            frac[slot] = float(emission.luminance(flux[near].astype(np.float64)).sum()
                               / power_lum[slot])
    return frac


def trace_photons(scene: Scene, settings: RenderSettings, accel: Accelerator | None = None,
                  progress: ProgressFn | None = None, *, include_direct: bool = True,
                  skip: dict | None = None) -> PhotonMaps:
    """Trace the global and caustic photon maps of a scene (see the module doc).

    accel: the render's Accelerator over ``scene.mesh`` (built and closed here if None).
    progress(fraction, message) -> True cancels (the maps built so far are returned
    as None and ``stats["cancelled"]`` is True). skip: {"global" or "caustic": reason}
    for maps the caller has already decided against (not traced; the reason is logged).
    """
    t_start = time.perf_counter()
    decisions: list[str] = []
    counters = {"rays": 0, "time_emission": 0.0, "time_tracing": 0.0, "time_intersect": 0.0,
                "time_scatter": 0.0, "time_balancing": 0.0}
    global_rule = scatter.STORE_ALL if include_direct else scatter.STORE_BOUNCED
    setup = _prepare(scene)
    threads = default_threads(int(_setting(settings, "threads", 0)))
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    n_global = int(_setting(settings, "global_photons", 200_000))
    n_caustic = int(_setting(settings, "caustic_photons", 100_000))
    indirect_mode = str(_setting(settings, "indirect_mode", "final_gather"))
    want_caustics = bool(_setting(settings, "caustics", True))
    projection = bool(_setting(settings, "projection_map", True))
    with_world = bool(_setting(settings, "photon_world", True))
    mats = setup.mats
    used = np.zeros(mats["diffuse"].shape[0], bool)
    used[np.unique(setup.tri_mat)] = True
    diffuse_any = bool(np.any(np.any(mats["diffuse"] > 0, axis=1) & used))
    spec_any = bool(np.any(setup.specular_objects))

    geometry_spheres = setup.objects if setup.objects.count else None
    sources = emission.source_powers(setup.light_set, setup.emissive, setup.world,
                                     setup.centre, setup.radius, geometry_spheres, with_world)
    skipped = [setup.light_set.names[i] if i < len(setup.light_set.names) else f"light {i}"
               for i in range(setup.light_set.count) if i not in {s.index for s in sources}]
    for name in skipped:
        decisions.append(f"light '{name}': no photons, zero power or no geometry in reach")
    if np.any(setup.world > 0) and not with_world:
        decisions.append("world background emits no photons (photon_world off)")

    skip = dict(skip or {})
    build_global = True
    if "global" in skip:
        build_global, why = False, skip["global"]
    elif indirect_mode == "off":
        build_global, why = False, "indirect light is off"
    elif not diffuse_any:
        build_global, why = False, "no surface has a diffuse lobe (nothing can bounce)"
    elif n_global <= 0:
        build_global, why = False, "global_photons is 0"
    elif not sources or scene.mesh.triangle_count == 0:
        build_global, why = False, "no light reaches any geometry"
    if not build_global:
        decisions.append(f"global map: skipped, {why}")

    build_caustic = True
    if "caustic" in skip:
        build_caustic, why = False, skip["caustic"]
    elif not want_caustics:
        build_caustic, why = False, "caustics are off"
    elif not spec_any:
        build_caustic, why = False, "no mirror, glass or glossy surface"
    elif not diffuse_any:
        build_caustic, why = False, "no diffuse surface to receive caustics"
    elif n_caustic <= 0:
        build_caustic, why = False, "caustic_photons is 0"
    elif not sources:
        build_caustic, why = False, "no light"

    caustic_sources, caustic_counts, caustic_targets = [], np.zeros(0, np.int64), []
    if build_caustic:
        if projection:
            targets = emission.Targets(setup.objects.centre[setup.specular_objects],
                                       setup.objects.radius[setup.specular_objects])
            shares = []
            for src in sources:
                if src.index == emission.SOURCE_WORLD:
                    decisions.append("world background: no caustic photons (not aimed)")
                    continue
                power, probs = emission.aimed_power(src, setup.light_set, setup.emissive,
                                                    targets, setup.centre, setup.radius)
                if np.any(power > 0) and np.any(probs > 0):
                    caustic_sources.append(src)
                    caustic_targets.append((targets, probs))
                    shares.append(emission.luminance(power))
            caustic_power = np.array(shares)
            caustic_counts = emission.allocate(caustic_power, n_caustic)
            caustic_how = f"aimed at {targets.count} specular object(s) (projection map)"
        else:
            caustic_sources = list(sources)
            caustic_targets = [(None, None)] * len(sources)
            caustic_power = np.array([emission.luminance(s.power) for s in sources])
            caustic_counts = emission.allocate(caustic_power, n_caustic)
            caustic_how = "emitted unaimed (projection map off)"
        if not caustic_sources or caustic_counts.sum() == 0:
            build_caustic, why = False, "no light reaches a specular object"
    if not build_caustic:
        decisions.append(f"caustic map: skipped, {why}")

    global_power = np.array([emission.luminance(s.power) for s in sources])
    global_counts = (emission.allocate(global_power, n_global) if build_global
                     else np.zeros(len(sources), np.int64))

    # Visual importance (core/importance.py): only where there is a choice to make.
    use_importance = bool(_setting(settings, "photon_importance", True))
    g_multi = build_global and len(sources) > 1
    c_multi = build_caustic and len(caustic_sources) > 1
    imp = {"prepass": False, "time": 0.0, "time_camera": 0.0, "time_pilot": 0.0,
           "camera_rays": 0, "visible_points": 0, "pilot_photons": 0, "pilot_rays": 0,
           "radius_global": 0.0, "radius_caustic": 0.0, "reason": ""}
    g_imp, c_imp = np.ones(len(sources)), np.ones(len(caustic_sources))
    g_frac, c_frac = np.full(len(sources), np.nan), np.full(len(caustic_sources), np.nan)
    if not (build_global or build_caustic):
        imp["reason"] = "no photon map to trace"
    elif not use_importance:
        imp["reason"] = "photon_importance off: photons shared by power"
    elif not (g_multi or c_multi):
        imp["reason"] = "one source per map: nothing to allocate"
    own_accel = accel is None and (build_global or build_caustic)
    if own_accel:
        accel = Accelerator(setup.tri_v, threads=threads)
    cancelled = False
    global_map = caustic_map = None
    g_store = c_store = None
    g_flux = np.zeros((len(sources), 3))
    c_flux = np.zeros((len(caustic_sources), 3))
    t_caustic = 0.0
    try:
        if use_importance and (g_multi or c_multi):
            from . import gather, importance

            t0 = time.perf_counter()
            seed = int(_setting(settings, "seed", 0))
            max_bounces = int(_setting(settings, "photon_max_bounces", 8))
            view = importance.visible_points(scene, setup, accel, seed,
                                             int(_setting(settings, "max_specular_depth", 8)))
            imp.update(prepass=True, time_camera=view.time, camera_rays=view.rays,
                       visible_points=int(view.position.shape[0]))
            area = gather.diffuse_area(setup.tri_v, setup.tri_mat, mats["diffuse"])
            pilot_counters = dict(counters, rays=0)
            t1 = time.perf_counter()
            if view.position.shape[0] == 0:
                imp["reason"] = "the camera sees no diffuse surface: photons shared by power"
            for multi, name, srcs, tps, power, total, mode, rule, map_id in (
                    (g_multi, "global", sources, [(None, None)] * len(sources), global_power,
                     n_global, scatter.MODE_GLOBAL, global_rule, MAP_GLOBAL),
                    (c_multi, "caustic", caustic_sources, caustic_targets,
                     caustic_power if build_caustic else None, n_caustic, scatter.MODE_CAUSTIC,
                     scatter.STORE_ALL, MAP_CAUSTIC)):
                n_pilot = importance.pilot_count(total, len(srcs))
                if not multi or view.position.shape[0] == 0 or n_pilot < importance.MIN_PILOT:
                    continue
                k = int(_setting(settings, f"{name}_k", 50))
                radius = importance.view_radius(area, view.position.shape[0], k, total)
                grid = importance.ViewGrid(view, radius)
                frac = _pilot_fractions(setup, accel, srcs, tps, power, mode, rule, seed,
                                        max_bounces, map_id, n_pilot, grid, pilot_counters)
                weight = importance.weights(power, importance.importance_of(frac))
                counts = importance.allocate(weight, total)
                imp[f"radius_{name}"] = radius
                imp["pilot_photons"] = max(imp["pilot_photons"], n_pilot)
                if name == "global":
                    g_frac, g_imp, global_counts = frac, importance.importance_of(frac), counts
                else:
                    c_frac, c_imp, caustic_counts = frac, importance.importance_of(frac), counts
            imp["pilot_rays"] = pilot_counters["rays"]
            imp["time_pilot"] = time.perf_counter() - t1
            imp["time"] = time.perf_counter() - t0
            decisions.append(
                f"photon importance: camera pre-pass {view.rays:,} rays, "
                f"{imp['visible_points']:,} visible points; pilot {imp['pilot_photons']:,} "
                f"photons per source and map; {imp['time']:.2f} s; floor {importance.FLOOR:.0%}"
                + (f" ({imp['reason']})" if imp["reason"] else ""))
        elif imp["reason"] and (build_global or build_caustic):
            decisions.append(f"photon importance: not used, {imp['reason']}")
        total_work = int(global_counts.sum()) + (int(caustic_counts.sum()) if build_caustic else 0)
        if build_global:
            purpose = ("final gathering (direct light included)" if include_direct
                       else "indirect light (stored after the first diffuse bounce)")
            decisions.append(f"global map: {int(global_counts.sum()):,} photons for {purpose}")
        if build_caustic:
            decisions.append(f"caustic map: {int(caustic_counts.sum()):,} photons {caustic_how}")
        c_slot = {src.index: j for j, src in enumerate(caustic_sources)} if build_caustic else {}
        for slot, src in enumerate(sources):
            parts = []
            for built, frac, imps, counts, j, name in (
                    (build_global, g_frac, g_imp, global_counts, slot, "global"),
                    (build_caustic, c_frac, c_imp, caustic_counts, c_slot.get(src.index), "caustic")):
                if not built or j is None:
                    continue
                text = f"{int(counts[j]):,} {name} photons"
                if not np.isnan(frac[j]):
                    if frac[j] == 0:
                        text = (f"{name} importance 0.00 (none of its pilot photons reach the "
                                f"view), {text} (floor)")
                    else:
                        text = f"{name} importance {imps[j]:.2f}, {text}"
                parts.append(text)
            if parts:
                decisions.append(f"{_source_label(src, setup.light_set)}: " + "; ".join(parts))
        if build_global:
            g_store, cancelled = _trace_map(
                setup, accel, sources, global_counts, [(None, None)] * len(sources),
                scatter.MODE_GLOBAL, global_rule, settings, MAP_GLOBAL, counters, progress,
                0, total_work, g_flux)
        if build_caustic and not cancelled:
            t0 = time.perf_counter()
            c_store, cancelled = _trace_map(
                setup, accel, caustic_sources, caustic_counts, caustic_targets,
                scatter.MODE_CAUSTIC, False, settings, MAP_CAUSTIC, counters, progress,
                int(global_counts.sum()), total_work, c_flux)
            t_caustic = time.perf_counter() - t0
    finally:
        if own_accel:
            accel.close()
    if not cancelled:
        if g_store is not None:
            global_map = _build(g_store, counters)
            if global_map is None:
                decisions.append("global map: empty, no photon was stored")
        if c_store is not None:
            caustic_map = _build(c_store, counters)
            if caustic_map is None:
                decisions.append("caustic map: empty, no photon reached a diffuse surface "
                                 "through a specular one")
    c_slot = {src.index: j for j, src in enumerate(caustic_sources)} if build_caustic else {}
    per_source = []
    for slot, src in enumerate(sources):
        j = c_slot.get(src.index)
        per_source.append({
            "name": src.name, "index": src.index, "power": src.power.copy(),
            "global_photons": int(global_counts[slot]) if build_global else 0,
            "global_importance": float(g_imp[slot]), "global_fraction": float(g_frac[slot]),
            "global_flux": g_flux[slot].copy(),
            "caustic_photons": int(caustic_counts[j]) if j is not None else 0,
            "caustic_importance": float(c_imp[j]) if j is not None else float("nan"),
            "caustic_fraction": float(c_frac[j]) if j is not None else float("nan"),
            "caustic_flux": c_flux[j].copy() if j is not None else np.zeros(3)})
    elapsed = time.perf_counter() - t_start
    traced = counters["time_tracing"] + counters["time_emission"]
    stats = {
        "global_built": global_map is not None,
        "caustic_built": caustic_map is not None,
        "global_emitted": int(global_counts.sum()),
        "caustic_emitted": int(caustic_counts.sum()) if build_caustic else 0,
        "global_stored": len(global_map) if global_map is not None else 0,
        "caustic_stored": len(caustic_map) if caustic_map is not None else 0,
        "include_direct": bool(include_direct),
        "photon_rays": counters["rays"],
        "photons_per_second": total_work / traced if traced > 0 else 0.0,
        "rays_per_second": counters["rays"] / traced if traced > 0 else 0.0,
        "time_emission": counters["time_emission"],
        "time_tracing": counters["time_tracing"],
        "time_intersect": counters["time_intersect"],
        "time_scatter": counters["time_scatter"],
        "time_balancing": counters["time_balancing"],
        "time_photons": elapsed,
        "time_caustic_map": t_caustic,
        "sources": [s.name for s in sources],
        "per_source": per_source,
        "importance": imp,
        "decisions": decisions,
        "cancelled": cancelled,
    }
    return PhotonMaps(global_map, caustic_map, stats["global_emitted"], stats["caustic_emitted"],
                      stats)

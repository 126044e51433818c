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
  with ``include_direct=False`` only after at least one diffuse bounce (``core.photons.store``).
- caustic: photons aimed at the specular objects (projection map, ``caustic_photons``),
  stored at the first diffuse hit of paths light -> specular+ -> diffuse.

Bounces (issue 13): Cycles' Max Bounces B lets a camera path reflect B + 1 times (the
light sampled at its (B + 1)-th vertex). A photon stored after b bounces makes b + 1
reflections where it is read at the camera ray's hit or along a camera segment (the
caustic map, the preview's global map, the volume maps of camera rays, SPPM), b + 2 where
a final-gather ray reads it (the global map with direct photons, the volume photons
along gather rays: x, then the gather hit). So with ``photon_max_bounces`` P the maps
read at the camera's hit keep photons of up to P bounces and those read by final-gather
rays up to P - 1 (``gather_bounces``): every estimate makes at most P + 1 reflections, as
Cycles does with B = P. One trace serves both: the global emission's photons are traced
to P bounces; the surface photons of its last bounce are not shaded when only final
gathering reads them (the wavefront is not even intersected without a medium), and its
last bounce's volume photons are kept for the camera rays' map only.

Sources: the lights, emissive triangles, the world background and the emissive media
inside closed meshes (core/photons/medium_emission.py: their photons start with one
diffuse-like bounce counted, since no shadow ray samples a medium, and emit no caustic
photons).

With more than one source, each map's photons are shared by power x visual importance
(``photon_importance``; core/photons/importance.py: a camera pre-pass and pilot photons), still
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

import numpy as np

from .. import sampling
from ..materials import closure
from ..color import luminance
from ..lights.light_set import LightSet
from ..passes import ProgressFn, StopFn
from ..prepared import PreparedScene
from ..scene.bounds import Targets
from ..settings import RenderSettings
from ..media import regions
from ..scene.contract import LIGHT_SUN
from ..shading import light_path
from . import emission, importance, medium_emission, medium_flight, scatter
from .beam import VolumePhotonMap, photon_radii
from .photon_map import PhotonMap
from .store import MODE_CAUSTIC, MODE_GLOBAL, STORE_ALL, STORE_BOUNCED, PhotonStore, compact_stored

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
    divided by these counts). stats: counts, times, which maps were built and why not.
    volume_map / volume_caustic_map: the volume photons of the global and the caustic
    emission for camera rays, volume_gather_map: every collision of the global emission
    after at most photon_max_bounces - 1 bounces, for final-gather rays (module doc,
    "Bounces"; core/photons/medium_flight.py); None without a scattering medium."""

    global_map: PhotonMap | None
    caustic_map: PhotonMap | None
    global_emitted: int
    caustic_emitted: int
    stats: dict = field(default_factory=dict)
    volume_map: VolumePhotonMap | None = None
    volume_caustic_map: VolumePhotonMap | None = None
    volume_gather_map: VolumePhotonMap | None = None


@dataclass
class _Medium:
    """The World's medium of a photon pass and where its volume photons go: ``vstore``
    (a medium_flight.VolumeStore), ``caustic_apart`` (the caustic emission keeps light ->
    S+ -> V photons), ``store_direct`` (the source's first collisions are stored)."""

    medium: regions.Medium
    vstore: medium_flight.VolumeStore
    caustic_apart: bool
    store_direct: bool = False


def gather_bounces(max_bounces: int) -> int:
    """The most bounces a photon read by a final-gather ray has made (module doc,
    "Bounces"): photon_max_bounces - 1, so that a gathered estimate makes photon_max_bounces
    + 1 reflections like the caustic map's, as Cycles' Max Bounces."""
    return int(max_bounces) - 1


def _fly(medium: _Medium, hits, o, d, f, pid, n_diff, n_spec, seed, map_id, bounce, mode, last,
         gathered=True, near=None, lead=None):
    """The free flights of one wavefront (core/photons/medium_flight.py): stores its volume
    photons and returns (prim with the collided photons as misses, so the surface kernel
    leaves them, collided (n,) bool, alive, o_new, d_new, f_new of the collided ones);
    the passing photons' flux f is weighted in place. gathered: False when this bounce is
    past ``gather_bounces`` (its photons go to the camera rays' map only). near, lead (n,):
    a soft-falloff light's photons at their first flight (``emission.Emitted``): a
    collision closer than near carries nothing, and every first event at t >= near takes
    the transmittance of the lead / t metres behind the origin (``_lead_transmittance``)."""
    n = o.shape[0]
    m = medium.medium
    t_hit = np.where(hits.prim >= 0, hits.t.astype(np.float64), np.inf)
    st = m.stretches(o, d, t_hit)
    dims = np.array([sampling.stream(sampling.MEDIUM_FLIGHT, map_id, k) for k in (0, 1, 2, 3)],
                    np.int64)
    out = (np.empty(n, bool), np.empty(n, bool), np.empty(n, bool), np.empty((n, 3), np.float32),
           np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty(n, bool),
           np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty((n, 3)))
    pre = medium_flight.flight_through(m, st, o, d, pid, seed, map_id, bounce)
    medium_flight.fly_kernel(o, d, f, pid, n_diff, n_spec, st.start, st.t0, st.t1,
                             np.ascontiguousarray(st.sigma_a), np.ascontiguousarray(st.sigma_s),
                             st.g, np.int64(seed), dims, np.int64(bounce), mode,
                             medium.caustic_apart, medium.store_direct, last, *pre,
                             np.zeros(0) if near is None else near, *out)
    collided, v_store, v_camera, v_pos, v_flux, v_dir, alive, o_new, d_new, f_new = out
    if near is not None:
        # The first event's distance: the collision's (stored or going on), else the
        # surface hit's; collisions that neither store nor go on carry nothing further.
        carried = np.flatnonzero(v_store | alive)
        t_event = t_hit.copy()
        t_event[collided] = np.inf
        pos = np.where(v_store[carried, None], v_pos[carried], o_new[carried])
        t_event[carried] = np.linalg.norm(pos.astype(np.float64) - o[carried], axis=1)
        j, tr = _lead_transmittance(m, o, d, t_event, near, lead)
        passing = ~collided[j]
        f[j[passing]] *= tr[passing]
        # a carried collision's stored and going-on flux (the kernel's rows of a photon
        # not stored or not going on are zeros)
        c, tr_c = j[~passing], tr[~passing]
        v_flux[c] *= tr_c.astype(np.float32)
        f_new[c] *= tr_c
    medium.vstore.add(v_store, v_camera, v_pos, v_flux, v_dir, gathered)
    prim = np.where(collided, -1, hits.prim).astype(hits.prim.dtype)
    return prim, collided, alive, o_new, d_new, f_new


def _lead_transmittance(medium: regions.Medium, o, d, t_event, near, lead):
    """The transmittance of the stretch behind a soft-falloff light's photons (``_fly``):
    for first events at t_event (n,) metres (inf: none) from origins o along unit d (n, 3),
    the point of the disk facing the event lies lead / t_event metres behind o
    (core/photons/emission.py, "Soft falloff"), and Cycles' shadow ray crosses that
    stretch too. Returns (rows (k,) int64 with such a stretch, transmittance (k, 3))."""
    j = np.flatnonzero((lead > 0.0) & np.isfinite(t_event) & (t_event >= near)
                       & (t_event > 0.0))
    if j.size == 0:
        return j, np.ones((0, 3))
    back = lead[j] / t_event[j]
    dj = d[j].astype(np.float64)
    return j, medium.transmittance(o[j].astype(np.float64) - back[:, None] * dj, dj, back)


def _trace_chunk(prepared: PreparedScene, em: emission.Emitted, pid: np.ndarray, mode: int,
                 store_rule: int, max_bounces: int, seed: int, map_id: int,
                 store: PhotonStore, counters: dict, medium: _Medium | None = None,
                 first_bounces: int = 0, surface_bounces: int | None = None,
                 volume_gather: int | None = None) -> None:
    """Trace one chunk of emitted photons through every bounce into ``store`` (and, in a
    medium, its volume photons into ``medium.vstore``). first_bounces: the diffuse-like
    bounces the photons start with (``medium_emission.FIRST_BOUNCES`` for an emissive
    medium's, whose direct light no shadow ray takes). surface_bounces: the most bounces
    a stored surface photon has made, max_bounces (None) or max_bounces - 1 (then the last
    bounce's surface hits are not shaded; module doc, "Bounces"). volume_gather: the most
    bounces a volume photon of the final-gather rays' map has made (None: max_bounces)."""
    surface_bounces = max_bounces if surface_bounces is None else int(surface_bounces)
    if not max_bounces - 1 <= surface_bounces <= max_bounces:
        raise ValueError(f"surface_bounces {surface_bounces} with max_bounces {max_bounces}")
    volume_gather = max_bounces if volume_gather is None else int(volume_gather)
    keep = np.any(em.flux > 0, axis=1)
    near, lead = em.near, em.lead
    if keep.all():  # the usual case: no boolean indexing (~30 ns per (N, 3) row)
        o, d, f = em.origin.astype(np.float32), em.direction.astype(np.float32), em.flux
    else:
        idx = np.flatnonzero(keep)
        o, d = em.origin[idx].astype(np.float32), em.direction[idx].astype(np.float32)
        f, pid = em.flux[idx], pid[idx]
        if near is not None:
            near, lead = near[idx], lead[idx]
    n_diff = np.full(o.shape[0], first_bounces, np.int32)
    n_spec = np.zeros(o.shape[0], np.int32)
    lam = np.zeros(o.shape[0])  # nm; 0 = RGB, until a dispersive surface (scatter.py)
    dims = np.array([sampling.stream(sampling.PHOTON, 1 + map_id, k) for k in range(4)]
                    + [sampling.stream(sampling.WAVELENGTH, 1 + map_id)], np.int64)
    accel = prepared.accel
    for bounce in range(max_bounces + 1):
        n = o.shape[0]
        shaded = bounce <= surface_bounces  # False only at the last bounce
        if n == 0 or (not shaded and medium is None):
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
        surf = prepared.surfaces
        prim = hits.prim
        first = near if bounce == 0 else None
        if medium is not None:
            prim, collided, v_alive, v_o, v_d, v_f = _fly(
                medium, hits, o, d, f, pid, n_diff, n_spec, seed, map_id, bounce, mode,
                bounce == max_bounces, bounce <= volume_gather, first, lead)
        if first is not None:
            # A soft-falloff light's photon hitting a surface before ``near`` carries
            # nothing there (emission.py, "Soft falloff"): it ends as a miss.
            prim = np.where(hits.t < first, -1, prim).astype(prim.dtype)
        if not shaded:  # the last bounce's volume photons only: nothing goes on
            counters["time_scatter"] += time.perf_counter() - t1
            break
        path = photon_path(prepared, hits.t)
        tab, rows, nrm = photon_closures(prepared, prim, hits.u, hits.v, d, path)
        tan = photon_tangents(prepared, prim, hits.u, hits.v, tab, rows)
        scatter.scatter_kernel(prepared.tri_vertices, prepared.tri_normals, prepared.tri_material,
                               prepared.extent, tab, prepared.has_diffuse,
                               prepared.specular_material,
                               prepared.texels.photon_albedo(prim, hits.u, hits.v), rows,
                               tan, nrm, surf.photon_opacity(prim, hits.u, hits.v, path),
                               prim, hits.u, hits.v, d, f, pid, n_diff, n_spec, lam,
                               np.int64(seed), dims, np.int64(bounce), mode,
                               np.int64(store_rule), bounce == max_bounces, s_flag, s_pos,
                               s_flux, s_dir, alive, o2, d2, f2)
        if medium is not None and collided.any():
            alive = np.where(collided, v_alive, alive)
            o2[collided], d2[collided], f2[collided] = v_o[collided], v_d[collided], v_f[collided]
        store.add(*compact_stored(s_flag, s_pos, s_flux, s_dir))
        o, d, f, pid, n_diff, n_spec, lam = scatter.compact_alive(alive, o2, d2, f2, pid, n_diff,
                                                                  n_spec, lam)
        counters["time_scatter"] += time.perf_counter() - t1


def photon_path(prepared, t):
    """(N, K) float32 the Light Path context of photon hits at distances t (N,) metres
    from the photons' last vertex, or None when no program reads it. A photon hit stands
    for what camera paths see through diffuse interreflection (the photon maps' indirect
    and caustic light): Is Diffuse Ray and Is Reflection Ray 1, Ray Depth and Diffuse
    Depth 1, Is Camera Ray 0 (an object hidden from the camera still scatters photons),
    Ray Length the photon's segment (core/shading/light_path.py)."""
    if not prepared.hit_shader.reads_light_path:
        return None
    return light_path.after_bounce(np.where(np.isfinite(t), t, 0.0), light_path.BOUNCE_DIFFUSE,
                                   False, 1, diffuse_depth=1)


def photon_closures(prepared, prim, u, v, d, path=None):
    """(tab, rows, normals) for a photon wavefront (``HitShader.shade`` at the hits that
    are not misses; prim (N,) int32 triangle, -1 for a miss or a photon that scattered in a
    medium first; u, v (N,) float32 barycentrics; d (N, 3) directions): rows (N,) int32, -1
    where prim is, or (0,) with the prepared table when no photon met a programmed material
    (the kernel then reads the triangles' materials); normals (N, 3) float64 the shading
    normal a program set (zero rows elsewhere), or (0, 3) when no program set one.
    path: (N, K) the hits' Light Path context (``photon_path``) or None."""
    shader = prepared.hit_shader
    none = np.zeros((0, 3))
    if not shader.active:
        return prepared.closures, np.zeros(0, np.int32), none
    got = np.flatnonzero(prim >= 0)
    mat = prepared.tri_material[prim[got]]
    zero = np.zeros((got.size, 3))
    tab, r, bent = shader.shade(prim[got], u[got], v[got], d[got], mat, zero,
                                None if path is None else path[got])
    if r is mat:
        return tab, np.zeros(0, np.int32), none
    rows = np.full(prim.shape[0], -1, np.int32)
    rows[got] = r
    normals = none
    if bent is not zero:
        normals = np.zeros((prim.shape[0], 3))
        normals[got] = bent
    return tab, rows, normals


def photon_tangents(prepared, prim, u, v, tab, rows) -> np.ndarray:
    """The BSDF frames' tangents of a photon wavefront (``HitShader.tangents``; prim, u, v
    as for ``photon_closures``, (tab, rows) what it returned): (N, 3) float64, or (0, 3)
    when no photon met an anisotropic closure (the kernel's default tangent)."""
    if not closure.anisotropic_rows(tab).any():
        return np.zeros((0, 3))
    got = np.flatnonzero(prim >= 0)
    hit_rows = rows[got] if rows.shape[0] else prepared.tri_material[prim[got]]
    tri = prepared.tri_vertices[prim[got]].astype(np.float64)
    b1, b2 = u[got].astype(np.float64)[:, None], v[got].astype(np.float64)[:, None]
    pos = tri[:, 0] + b1 * (tri[:, 1] - tri[:, 0]) + b2 * (tri[:, 2] - tri[:, 0])
    out = closure.default_tangents(prim.shape[0])
    out[got] = prepared.hit_shader.tangents(prim[got], pos, tab, hit_rows)
    return out


def _trace_map(prepared, sources, counts, targets_per_source, mode, store_rule, seed: int,
               max_bounces: int, map_id, counters, on_progress=None, should_stop=None,
               done_before=0, total_work=0, flux_out=None, medium: _Medium | None = None,
               surface_bounces: int | None = None, volume_gather: int | None = None):
    """Emit counts[s] photons from each source and trace them; returns (store, cancelled).
    on_progress(fraction, message) after each chunk, should_stop() -> True ends the map
    between chunks. flux_out: optional (S, 3) float64 array, += the flux each source
    emitted (watts). medium: the World's medium the photons fly through (None: vacuum).
    surface_bounces, volume_gather: the bounce limits of the surface photons and of the
    final-gather rays' volume photons (``_trace_chunk``; None: max_bounces)."""
    store = PhotonStore()
    first_id = 0
    done = done_before
    for slot, (src, n_src) in enumerate(zip(sources, counts)):
        n_src = int(n_src)
        targets, probs = targets_per_source[slot]
        if medium is not None:
            # The camera pass takes the lights' single scattering by shadow rays; the
            # emissive triangles' and the world's from their stored first collisions.
            medium.store_direct = src.index < 0
        for first in range(0, n_src, CHUNK):
            count = min(CHUNK, n_src - first)
            t0 = time.perf_counter()
            from_medium = medium_emission.is_medium(src.index)
            if from_medium:
                em, dropped = medium_emission.emit(src, prepared.medium, n_src, first, count,
                                                   seed=seed, map_id=map_id, source_slot=slot,
                                                   centre=prepared.centre, radius=prepared.radius)
                counters["medium_dropped"] = counters.get("medium_dropped", 0) + dropped
            else:
                em = emission.emit(src, prepared.light_set, prepared.emissive, prepared.world,
                                   prepared.centre, prepared.radius, n_src, first, count,
                                   seed=seed, map_id=map_id, source_slot=slot, targets=targets,
                                   target_prob=probs, extent=prepared.extent,
                                   emission_points=prepared.hit_shader.emission_points)
            counters["time_emission"] += time.perf_counter() - t0
            if flux_out is not None:
                flux_out[slot] += em.flux.sum(axis=0)
            if medium is not None and _from_infinity(src, prepared.light_set):
                # Sun and world light cross infinite World fog: none arrives (Cycles).
                em.flux[:, medium.medium.world_sigma_t > 0] = 0.0
            pid = np.arange(first_id + first, first_id + first + count, dtype=np.int64)
            t1 = time.perf_counter()
            _trace_chunk(prepared, em, pid, mode, store_rule, max_bounces, seed, map_id,
                         store, counters, medium,
                         medium_emission.FIRST_BOUNCES if from_medium else 0,
                         surface_bounces, volume_gather)
            counters["time_tracing"] += time.perf_counter() - t1
            done += count
            if on_progress is not None:
                on_progress(min(done / max(total_work, 1), 1.0),
                            f"Traced {done}/{total_work} photons")
            if should_stop is not None and should_stop():
                return store, True
        first_id += n_src
    return store, False


def _from_infinity(src, light_set: LightSet) -> bool:
    """The source's light comes from infinitely far: the sun or the world background."""
    if src.index == emission.SOURCE_WORLD:
        return True
    return src.index >= 0 and int(light_set.kind[src.index]) == LIGHT_SUN


MIN_VOLUME_RADIUS = 1e-7
"""Floor of a volume photon's radius, metres (k photons at one point would give 0)."""


def _volume_maps(medium: _Medium | None, k: int, counters: dict):
    """(camera map, final-gather map): VolumePhotonMaps of a medium's stored volume
    photons, the camera rays' subset and those within the final-gather rays' bounces
    (``gather_bounces``); None where fewer than 2 were stored or none is selected.
    Radii: the distance to the k-th nearest of all of them (itself counted), computed
    once for both maps (the k-NN is the maps' main cost: the camera map's radii are those
    of a k / (its share of the photons) search, a little sharper; each photon's kernel
    integrates to 1 whatever its radius, so leaving photons out of a map keeps the others'
    estimate unbiased)."""
    if medium is None:
        return None, None
    t0 = time.perf_counter()
    pos, flux, direction, camera, gathered = medium.vstore.take()
    if pos.shape[0] < 2:
        return None, None
    radii = np.maximum(photon_radii(pos, min(int(k), pos.shape[0])), MIN_VOLUME_RADIUS)
    maps = []
    for sel in (camera, slice(None) if gathered.all() else gathered):
        p = pos[sel]
        maps.append(VolumePhotonMap(p, flux[sel], direction[sel], radii[sel])
                    if p.shape[0] else None)
    counters["time_balancing"] += time.perf_counter() - t0
    return maps[0], maps[1]


def _balance(store: PhotonStore, counters: dict):
    t0 = time.perf_counter()
    # From the per-bounce pieces, encoded piece by piece (no float64 copies of the map).
    pm = PhotonMap.from_parts(store.pos, store.flux, store.dir) if store.count else None
    store.count = 0
    counters["time_balancing"] += time.perf_counter() - t0
    return pm


def photon_sources(prepared: PreparedScene) -> list:
    """The emitting sources of a prepared scene (``emission.Source``), power-weighted:
    the lights, emissive triangles, the world background and the emissive media inside
    closed meshes (``medium_emission.sources``)."""
    spheres = prepared.objects if prepared.objects.count else None
    return (emission.source_powers(prepared.light_set, prepared.emissive, prepared.world,
                                   prepared.centre, prepared.radius, spheres, True)
            + medium_emission.sources(prepared.medium, prepared.centre, prepared.radius)[0])


def trace_stored_photons(prepared: PreparedScene, sources: list, n_photons: int, *, seed: int,
                         max_bounces: int, store_rule: int = STORE_ALL, volume: bool = False):
    """Trace ``n_photons`` unaimed photons (shared between ``sources`` by power) and return
    the photons stored at diffuse hits as raw arrays, without building a PhotonMap.

    The global map's rules (``MODE_GLOBAL``, stored by ``store_rule``); for
    progressive passes that need one batch of photons at a time. Returns (positions
    (M, 3) float32 metres, flux (M, 3) float32 watts already divided by the photons
    emitted, incident directions (M, 3) float32 pointing back towards where each photon
    came from, counters dict).

    volume=True (a scene with media, ``prepared.medium``): the photons fly through the
    media as the global map's do (``_fly``, caustic paths kept with the rest) and a fifth
    element is returned, the volume photons (positions, flux W, propagation directions
    (V, 3) float32, camera (V,) bool: False for a light's first collision, which Volume
    Direct's shadow rays take), or None without a medium.
    """
    counters = {"rays": 0, "time_emission": 0.0, "time_tracing": 0.0, "time_intersect": 0.0,
                "time_scatter": 0.0, "time_balancing": 0.0}
    medium = None
    if volume and prepared.medium is not None:
        medium = _Medium(prepared.medium, medium_flight.VolumeStore(), caustic_apart=False)
    if not sources or n_photons <= 0:
        z = np.zeros((0, 3), np.float32)
        out = (z, z.copy(), z.copy(), counters)
    else:
        counts = emission.allocate(np.array([luminance(s.power) for s in sources]),
                                   int(n_photons))
        store, _ = _trace_map(prepared, sources, counts, [(None, None)] * len(sources),
                              MODE_GLOBAL, store_rule, int(seed), int(max_bounces), MAP_GLOBAL,
                              counters, total_work=int(counts.sum()), medium=medium)
        pos, flux, direction = store.take()
        out = (pos, flux, direction, counters)
    if not volume:
        return out
    return (*out, None if medium is None else medium.vstore.take()[:4])


_KIND_NAMES = {0: "point", 1: "spot", 2: "sun", 3: "area"}


def _source_label(src, light_set: LightSet) -> str:
    """How the log names a source: "light 'Lamp' (point, 100 W)", "world (background, 3 W)"."""
    watts = f"{float(luminance(src.power)):,.4g} W"
    if src.index >= 0:
        return f"light '{src.name}' ({_KIND_NAMES.get(int(light_set.kind[src.index]), 'light')}, {watts})"
    kind = ("mesh" if src.index == emission.SOURCE_TRIANGLES else
            "volume" if medium_emission.is_medium(src.index) else "background")
    return f"{src.name} ({kind}, {watts})"


def _pilot_fractions(prepared, sources, targets_per_source, power_lum, mode, store_rule,
                     seed, max_bounces, map_id, n_pilot, grid, counters):
    """Step 2-3 of core/photons/importance.py: per source, the fraction f_s of its power
    (luminance) that its n_pilot pilot photons store near the visible points (``grid``).
    (S,) float64."""
    frac = np.zeros(len(sources))
    for slot, src in enumerate(sources):
        store, _ = _trace_map(prepared, [src], np.array([n_pilot]), [targets_per_source[slot]],
                              mode, store_rule, importance.pilot_seed(seed, slot, map_id),
                              max_bounces, importance.MAP_PILOT + map_id, counters,
                              total_work=n_pilot)
        pos, flux, direction = store.take()
        if pos.shape[0] and power_lum[slot] > 0:
            near = grid.near(pos, direction)
            frac[slot] = float(luminance(flux[near].astype(np.float64)).sum()
                               / power_lum[slot])
    return frac


def trace_photons(prepared: PreparedScene, settings: RenderSettings,
                  on_progress: ProgressFn | None = None, should_stop: StopFn | None = None, *,
                  include_direct: bool = True, skip: dict | None = None,
                  prepass: Callable[[], importance.VisibleView] | None = None) -> PhotonMaps:
    """Trace the global and caustic photon maps of a prepared scene (see the module doc).

    on_progress(fraction, message) after each chunk of photons; should_stop() -> True
    cancels between chunks (the maps are then None and ``stats["cancelled"]`` is True).
    skip: {"global" or "caustic": reason} for maps the caller has already decided against
    (not traced; the reason is logged). prepass() -> the camera's visible diffuse points
    (``importance.VisibleView``), called only when photon importance has a choice to make;
    without it photons are shared by power.
    """
    scene = prepared.scene
    t_start = time.perf_counter()
    decisions: list[str] = []
    counters = {"rays": 0, "time_emission": 0.0, "time_tracing": 0.0, "time_intersect": 0.0,
                "time_scatter": 0.0, "time_balancing": 0.0}
    global_rule = STORE_ALL if include_direct else STORE_BOUNCED
    n_global = int(settings.global_photons)
    n_caustic = int(settings.caustic_photons)
    seed = int(settings.seed)
    max_bounces = int(settings.photon_max_bounces)
    # Final-gather rays read the global map with direct photons and the volume photons
    # one reflection later than the camera's hit (module doc, "Bounces").
    gathered = gather_bounces(max_bounces)
    surface_bounces = gathered if include_direct else max_bounces
    diffuse_any = bool(np.any(prepared.has_diffuse & prepared.used_materials))
    spec_any = bool(np.any(prepared.specular_objects))
    ls = prepared.light_set

    sources = photon_sources(prepared)
    skipped = [ls.names[i] if i < len(ls.names) else f"light {i}"
               for i in range(ls.count) if i not in {s.index for s in sources}]
    for name in skipped:
        decisions.append(f"light '{name}': no photons, zero power or no geometry in reach")
    decisions.extend(medium_emission.sources(prepared.medium, prepared.centre,
                                             prepared.radius)[1])

    skip = dict(skip or {})
    # A scattering medium receives photons (volume photons) even without a diffuse surface.
    receives = diffuse_any or (prepared.medium is not None and prepared.medium.scatters)
    build_global = True
    if "global" in skip:
        build_global, why = False, skip["global"]
    elif settings.indirect_mode == "off":
        build_global, why = False, "indirect light is off"
    elif not receives:
        build_global, why = False, "no surface has a diffuse lobe (nothing can bounce)"
    elif n_global <= 0:
        build_global, why = False, "global_photons is 0"
    elif not sources or (scene.mesh.triangle_count == 0 and not receives):
        build_global, why = False, "no light reaches any geometry"
    if not build_global:
        decisions.append(f"global map: skipped, {why}")

    build_caustic = True
    if "caustic" in skip:
        build_caustic, why = False, skip["caustic"]
    elif not settings.caustics:
        build_caustic, why = False, "caustics are off"
    elif not spec_any:
        build_caustic, why = False, "no mirror, glass or glossy surface"
    elif not receives:
        build_caustic, why = False, "no diffuse surface to receive caustics"
    elif n_caustic <= 0:
        build_caustic, why = False, "caustic_photons is 0"
    elif not sources:
        build_caustic, why = False, "no light"

    caustic_sources, caustic_counts, caustic_targets = [], np.zeros(0, np.int64), []
    if build_caustic:
        if settings.projection_map:
            targets = Targets(prepared.objects.centre[prepared.specular_objects],
                              prepared.objects.radius[prepared.specular_objects])
            shares = []
            for src in sources:
                if src.index == emission.SOURCE_WORLD:
                    decisions.append("world background: no caustic photons (not aimed)")
                    continue
                if medium_emission.is_medium(src.index):
                    decisions.append(f"{src.name}: no caustic photons (its light -> "
                                     f"specular -> diffuse paths are in the global map)")
                    continue
                power, probs = emission.aimed_power(src, ls, prepared.emissive, targets,
                                                    prepared.centre, prepared.radius)
                if np.any(power > 0) and np.any(probs > 0):
                    caustic_sources.append(src)
                    caustic_targets.append((targets, probs))
                    shares.append(luminance(power))
            caustic_power = np.array(shares)
            caustic_counts = emission.allocate(caustic_power, n_caustic)
            caustic_how = f"aimed at {targets.count} specular object(s) (projection map)"
        else:
            caustic_sources = [s for s in sources if not medium_emission.is_medium(s.index)]
            caustic_targets = [(None, None)] * len(caustic_sources)
            caustic_power = np.array([luminance(s.power) for s in caustic_sources])
            caustic_counts = emission.allocate(caustic_power, n_caustic)
            caustic_how = "emitted unaimed (projection map off)"
        if not caustic_sources or caustic_counts.sum() == 0:
            build_caustic, why = False, "no light reaches a specular object"
    if not build_caustic:
        decisions.append(f"caustic map: skipped, {why}")

    global_power = np.array([luminance(s.power) for s in sources])
    global_counts = (emission.allocate(global_power, n_global) if build_global
                     else np.zeros(len(sources), np.int64))

    # Visual importance (core/photons/importance.py): only where there is a choice to make.
    use_importance = bool(settings.photon_importance) and prepass is not None
    g_multi = build_global and len(sources) > 1
    c_multi = build_caustic and len(caustic_sources) > 1
    imp = {"prepass": False, "time": 0.0, "time_camera": 0.0, "time_pilot": 0.0,
           "camera_rays": 0, "visible_points": 0, "pilot_photons": 0, "pilot_rays": 0,
           "radius_global": 0.0, "radius_caustic": 0.0, "reason": ""}
    g_imp, c_imp = np.ones(len(sources)), np.ones(len(caustic_sources))
    g_frac, c_frac = np.full(len(sources), np.nan), np.full(len(caustic_sources), np.nan)
    if not (build_global or build_caustic):
        imp["reason"] = "no photon map to trace"
    elif not settings.photon_importance:
        imp["reason"] = "photon_importance off: photons shared by power"
    elif prepass is None:
        imp["reason"] = "no camera pre-pass: photons shared by power"
    elif not (g_multi or c_multi):
        imp["reason"] = "one source per map: nothing to allocate"
    cancelled = False
    global_map = caustic_map = None
    g_store = c_store = None
    g_flux = np.zeros((len(sources), 3))
    c_flux = np.zeros((len(caustic_sources), 3))
    t_caustic = 0.0
    if use_importance and (g_multi or c_multi):
        t0 = time.perf_counter()
        view = prepass()
        imp.update(prepass=True, time_camera=view.time, camera_rays=view.rays,
                   visible_points=int(view.position.shape[0]))
        area = prepared.diffuse_area
        pilot_counters = dict(counters, rays=0)
        t1 = time.perf_counter()
        if view.position.shape[0] == 0:
            imp["reason"] = "the camera sees no diffuse surface: photons shared by power"
        for multi, name, srcs, tps, power, total, mode, rule, map_id in (
                (g_multi, "global", sources, [(None, None)] * len(sources), global_power,
                 n_global, MODE_GLOBAL, global_rule, MAP_GLOBAL),
                (c_multi, "caustic", caustic_sources, caustic_targets,
                 caustic_power if build_caustic else None, n_caustic, MODE_CAUSTIC,
                 STORE_ALL, MAP_CAUSTIC)):
            n_pilot = importance.pilot_count(total, len(srcs))
            if not multi or view.position.shape[0] == 0 or n_pilot < importance.MIN_PILOT:
                continue
            k = int(getattr(settings, f"{name}_k"))
            radius = importance.view_radius(area, view.position.shape[0], k, total)
            grid = importance.ViewGrid(view, radius)
            frac = _pilot_fractions(prepared, srcs, tps, power, mode, rule, seed,
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
        decisions.append(f"global map: {int(global_counts.sum()):,} photons for {purpose}, "
                         f"stored after at most {surface_bounces} bounces")
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
            decisions.append(f"{_source_label(src, ls)}: " + "; ".join(parts))
    medium = prepared.medium
    g_medium = c_medium = None
    if medium is not None:
        g_medium = _Medium(medium, medium_flight.VolumeStore(), caustic_apart=build_caustic)
        c_medium = _Medium(medium, medium_flight.VolumeStore(), caustic_apart=True)
    if build_global:
        g_store, cancelled = _trace_map(
            prepared, sources, global_counts, [(None, None)] * len(sources),
            MODE_GLOBAL, global_rule, seed, max_bounces, MAP_GLOBAL, counters, on_progress,
            should_stop, 0, total_work, g_flux, g_medium, surface_bounces, gathered)
    if build_caustic and not cancelled:
        t0 = time.perf_counter()
        c_store, cancelled = _trace_map(
            prepared, caustic_sources, caustic_counts, caustic_targets,
            MODE_CAUSTIC, STORE_ALL, seed, max_bounces, MAP_CAUSTIC, counters, on_progress,
            should_stop, int(global_counts.sum()), total_work, c_flux, c_medium)
        t_caustic = time.perf_counter() - t0
    volume_map = volume_caustic_map = volume_gather_map = None
    if medium is not None and not cancelled:
        volume_map, volume_gather_map = _volume_maps(g_medium, settings.global_k, counters)
        volume_caustic_map, _ = _volume_maps(c_medium, settings.caustic_k, counters)
        decisions.append(f"volume photons in media {medium.name}: "
                         f"{len(volume_map) if volume_map else 0:,} global "
                         f"({len(volume_gather_map) if volume_gather_map else 0:,} with the "
                         f"direct ones and at most {gathered} bounces, for final "
                         f"gathering), "
                         f"{len(volume_caustic_map) if volume_caustic_map else 0:,} caustic")
        if counters.get("medium_dropped"):
            decisions.append(f"emissive media: {counters['medium_dropped']:,} photons found no "
                             f"point inside their mesh in {medium_emission.MAX_ROUNDS} tries "
                             f"and were dropped (is the boundary closed?)")
        if medium.fields is not None:  # heterogeneous media: the majorants, any clipping
            decisions.append("density majorants " + ", ".join(
                f"'{medium.names[m]}' {v:.4g}" for m, v in medium.fields.majorant.items()))
            decisions.extend(medium.fields.warnings())
    if not cancelled:
        if g_store is not None:
            global_map = _balance(g_store, counters)
            if global_map is None:
                decisions.append("global map: empty, no photon was stored")
        if c_store is not None:
            caustic_map = _balance(c_store, counters)
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
        "volume_stored": len(volume_map) if volume_map is not None else 0,
        "volume_caustic_stored": len(volume_caustic_map) if volume_caustic_map is not None else 0,
    }
    return PhotonMaps(global_map, caustic_map, stats["global_emitted"], stats["caustic_emitted"],
                      stats, volume_map, volume_caustic_map, volume_gather_map)

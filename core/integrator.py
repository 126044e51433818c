"""The camera pass: what the camera sees directly, through mirrors and glass, and the
photon terms at the diffuse surfaces it reaches (the seed lecture's split).

Wavefront: a tile of pixels x samples becomes one batch of camera rays; each bounce
intersects the whole batch in Embree, shades it in numba kernels (emission, the direct
light of core/direct.py: one shadow ray per light per light sample, the photon estimates
of core/gather.py), and spawns at most one specular ray per path.

Passes (each (H, W, 3) float32, radiance W/(m^2 sr), row 0 at the top):
- emission: emitters seen by camera rays (emissive triangles, visible lights);
- environment: the world background seen by camera rays;
- direct: light reflected towards the camera at the first hit (shadow rays);
- specular: everything seen after at least one mirror/glass bounce (emission, lights,
  background, and direct light, caustics and indirect light at the surface reached);
- caustics: the caustic map's radiance estimate at the first hit (diffuse lobe);
- indirect: indirect diffuse light at the first hit: final gathering over the global
  map, or (preview mode) the global map's estimate seen directly;
- combined: their sum (summed in float64 from the float32 passes, then cast), so
  combined == sum of the other passes exactly.
- photons (only with ``settings.photon_debug_pass``): (H, W, 4) float32 RGBA, a dot
  wherever the camera sees a stored photon of ``settings.overlay_map``
  (core/debug_overlay.py); not part of combined. With ``settings.overlay_composite`` the
  dots are also drawn over combined, which is then no longer the sum of the light passes.
A term evaluated at a diffuse surface seen through a mirror or glass belongs to the
specular pass, like the direct light there: the caustics and indirect passes show what
the camera sees directly, and every pixel's light is counted once.

Photon maps: ``render`` first traces them (core/tracing.py, with the render's own
Accelerator) unless ``photon_maps`` is given (tests pass hand-built maps); the photon
pass takes PHOTON_SHARE of the progress bar.

Specular rays: one delta lobe is picked per hit (``bsdf.sample_delta``: mirror vs glass by
tint, reflection vs refraction with probability clamp(F, 1/8, 7/8) like Cycles' camera
paths) and the path weight is lobe / probability, so paths never split.

Sampling: pixel jitter, light samples and lobe choices are stratified over each pixel's
samples (``sampling.stratified2``, scrambled Sobol). Determinism: every random number is a
hash of (seed, pixel, sample, dimension), and a pixel's samples are always traced in one
tile and summed in sample order, so the image does not depend on tile sizes or threads.

Ray offsets: ``geometry`` (eps proportional to the hit's coordinates plus the scene size).

Textures and cut-outs (core/textures.py): the diffuse albedo at each batch of hits is
``ctx.surfaces.albedo`` (textured where the material has an image, else the material's),
passed as (N, 3) to the shading kernel and the photon terms. Camera rays pass cut-outs
(opacity a < 1) with probability 1 - a without counting a bounce, so what is seen through
a cut-out stays in its pass; shadow rays are attenuated by 1 - a per cut-out crossed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numba
import numpy as np
from numba import njit, prange

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from . import denoise_features
from . import (bsdf, camera, debug_overlay, direct, gather, geometry, lights, photon_pass,
               sampling, textures)
from .accel import Accelerator, default_threads
from .passes import BLENDER_PASS_NAMES, PASSES  # noqa: F401  (re-exported)
from .scene import Scene
from .settings import RenderSettings

# A tile holds about this many camera samples (all samples of its pixels); tiles grow
# while they take less than TILE_SECONDS and shrink when longer, so that progress() (and
# cancelling) is never far away.
TARGET_SAMPLES_PER_TILE = 1 << 16
TILE_SECONDS = 0.25
PHOTON_SHARE = 0.2
"""Fraction of the progress bar given to the photon pass when photons are traced."""
UPDATE_SECONDS = 1.0
"""Least time between two ``on_tile`` calls (each assembles the partial images)."""
UPDATE_SHARE = 0.05
"""Most of the camera pass's time the ``on_tile`` calls may take: after a call that took
c seconds the next one waits at least c / UPDATE_SHARE (large images, slow callbacks)."""
REST = "rest"
"""Accumulator of the light terms whose pass is switched off: it feeds "combined" only."""

ProgressFn = Callable[[float, str], bool]
TileFn = Callable[[int, dict], None]


@dataclass
class UsedPhotonMaps:
    """The photon maps the camera pass read: PhotonMap or None (term skipped or not built)."""

    global_map: object = None
    caustic_map: object = None


@dataclass
class RenderOutput:
    """passes: name -> (H, W, 3) float32 ("photons": (H, W, 4)); stats: counters and
    timings; cancelled: stopped early; photon_maps: the UsedPhotonMaps of the render, None
    when it used no photon map (the viewport display shows them, photon_engine/overlay.py)."""

    passes: dict[str, np.ndarray]
    stats: dict = field(default_factory=dict)
    cancelled: bool = False
    photon_maps: UsedPhotonMaps | None = None


@dataclass
class _Context:
    """Everything built once per render and read by every tile."""

    scene: Scene
    settings: RenderSettings
    accel: Accelerator
    tri_vertices: np.ndarray
    tri_normals: np.ndarray
    tri_material: np.ndarray
    materials: dict
    nondelta: np.ndarray
    has_delta: np.ndarray
    light_set: lights.LightSet
    world: np.ndarray
    extent: float
    stats: dict
    light_shows: np.ndarray     # (L,) the light has a surface a ray can see
    direct: direct.DirectLighting  # the shadow rays (core/direct.py), sharing accel and stats
    has_diffuse: np.ndarray = None   # (M,) the material has a diffuse lobe
    terms: "gather.PhotonTerms | None" = None
    surfaces: "textures.SurfaceTextures | None" = None  # textured albedo, cut-outs
    # The per-pixel images kept: the produced passes, then REST when some are off.
    outputs: tuple = PASSES


def _prepare(scene: Scene, settings: RenderSettings) -> _Context:
    mesh = scene.mesh
    mats = bsdf.material_table(scene.materials)
    singular = mats["alpha"] <= np.sqrt(bsdf.SINGULAR_ALPHA2)
    nondelta = np.any(mats["diffuse"] > 0, axis=1) | (np.any(mats["specular"] > 0, axis=1) & ~singular)
    has_delta = np.any(mats["transmission"] > 0, axis=1) | (np.any(mats["specular"] > 0, axis=1) & singular)
    lo, hi = scene.bounds()
    extent = geometry.scene_extent(lo, hi)
    light_set = lights.LightSet.from_lights(scene.lights)
    threads = default_threads(settings.threads)
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    tri_vertices = np.ascontiguousarray(mesh.triangle_vertices(), np.float32)
    accel = Accelerator(tri_vertices, threads=threads)
    surfaces = textures.SurfaceTextures(scene, mats["diffuse"])
    stats = {"rays_camera": 0, "rays_specular": 0, "rays_shadow": 0,
             "time_intersect": 0.0, "time_shadow": 0.0, "time_shading": 0.0}
    tri_normals = np.ascontiguousarray(mesh.normals, np.float32)
    world = np.asarray(scene.world.radiance, np.float64).reshape(3)
    return _Context(
        scene=scene, settings=settings, accel=accel, tri_vertices=tri_vertices,
        tri_normals=tri_normals,
        tri_material=np.ascontiguousarray(mesh.material_index, np.int32),
        materials=mats, nondelta=nondelta, has_delta=has_delta,
        light_set=light_set, world=world, extent=extent, stats=stats,
        light_shows=np.any(light_set.radiance > 0, axis=1),
        direct=direct.prepare(settings, accel, light_set=light_set,
                              emissive=lights.EmissiveTriangles.from_mesh(mesh, scene.materials),
                              materials=mats, world=world, extent=extent, surfaces=surfaces,
                              tri_vertices=tri_vertices, tri_normals=tri_normals, stats=stats),
        has_diffuse=np.any(mats["diffuse"] > 0, axis=1),
        surfaces=surfaces,
        outputs=settings.passes() + ((REST,) if len(settings.passes()) < len(PASSES) else ()),
    )


# --- kernels --------------------------------------------------------------------------------

CUTOUT_CHOICE = 19
"""Random-number purpose (sampling.stream) of the camera rays' pass-through choices."""


@njit(cache=True, parallel=True, error_model="numpy")
def _pixel_mean_kernel(per_sample, samples, out):
    """Mean over each pixel's consecutive samples, summed in sample order (deterministic)."""
    for p in prange(out.shape[0]):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        base = p * samples
        for s in range(samples):
            a0 += per_sample[base + s, 0]
            a1 += per_sample[base + s, 1]
            a2 += per_sample[base + s, 2]
        out[p, 0] = a0 / samples
        out[p, 1] = a1 / samples
        out[p, 2] = a2 / samples


# --- one tile -------------------------------------------------------------------------------

def _add(acc, rows, values):
    """acc[rows] += values for unique rows (one path per camera sample)."""
    if rows.shape[0]:
        acc[rows] += values


def _photon_terms(ctx: _Context, rows, pos, ngf, nsf, eps, mat, thr, pixel, sample, depth,
                  caustic_target, indirect_target, albedo):
    """Add T * (caustics) and T * (indirect) at the hits with a diffuse lobe (core/gather.py).
    albedo (N, 3): the (textured) diffuse albedo at the hits."""
    terms = ctx.terms
    sel = np.flatnonzero(ctx.has_diffuse[mat])
    if sel.size == 0:
        return
    r = rows[sel]
    albedo = albedo[sel]
    if terms.caustic_map is not None:
        _add(caustic_target, r, thr[sel] * gather.caustics(terms, pos[sel], ngf[sel], albedo))
    if terms.global_map is None:
        return
    if terms.mode == "final_gather":
        incoming = gather.final_gather(terms, ctx, pos[sel], ngf[sel], nsf[sel], eps[sel],
                                       pixel[r], sample[r], depth)
        _add(indirect_target, r, thr[sel] * albedo * incoming)
    elif terms.mode == "preview":
        _add(indirect_target, r, thr[sel] * gather.preview(terms, pos[sel], ngf[sel], albedo))


def _intersect(ctx: _Context, origins, dirs, tmax, rows, pixel, sample, depth):
    """The camera paths' nearest hits, passing cut-outs stochastically
    (``textures.SurfaceTextures.intersect``; plain Embree without cut-outs)."""
    def uniforms(index, layer):
        r = rows[index]
        return sampling.uniform(ctx.settings.seed, pixel[r], sample[r],
                                sampling.stream(CUTOUT_CHOICE, depth, layer))
    return ctx.surfaces.intersect(ctx.accel, ctx.tri_vertices, ctx.tri_normals, ctx.extent,
                                  origins, dirs, tmax, uniforms)


def _render_tile(ctx: _Context, pix: np.ndarray) -> dict[str, np.ndarray]:
    """Per-pixel means (P, 3) float64 of every pass for the pixels ``pix`` (P,) int64."""
    st = ctx.settings
    s_count = st.samples
    pixel = np.repeat(pix.astype(np.int64), s_count)
    sample = np.tile(np.arange(s_count, dtype=np.int64), pix.shape[0])
    n = pixel.shape[0]
    # Switched-off passes share the REST accumulator: every term still reaches combined.
    kept = {name: np.zeros((n, 3)) for name in ctx.outputs}
    acc = {name: kept.get(name, kept.get(REST)) for name in PASSES}
    ls = ctx.light_set
    mats = ctx.materials
    t0 = time.perf_counter()

    # Generate camera rays
    jitter = np.stack(sampling.stratified2(st.seed, pixel, sample, s_count,
                                           sampling.stream(sampling.PIXEL_JITTER)), axis=1)
    lens = None
    if camera.has_aperture(ctx.scene.camera):  # depth of field: a point on the aperture
        lens = np.stack(sampling.stratified2(st.seed, pixel, sample, s_count,
                                             sampling.stream(sampling.PIXEL_JITTER, 1)), axis=1)
    rays = camera.generate_rays(ctx.scene.camera, pixel, jitter, lens)
    origins, dirs, tmax = rays.origins, rays.directions, rays.tmax
    features = None
    if st.denoising_data:  # Cycles' Denoising Albedo / Normal (core/denoise_features.py)
        features = denoise_features.FeatureAccumulator(n, camera.camera_frame(ctx.scene.camera)[1:])
    rows = np.arange(n)
    thr = np.ones((n, 3))
    transmitted = np.zeros(n, bool)
    ctx.stats["rays_camera"] += n
    ctx.stats["time_shading"] += time.perf_counter() - t0

    for depth in range(st.max_specular_depth + 1):
        if rows.shape[0] == 0:
            break
        first = depth == 0
        # Intersect the batch
        t0 = time.perf_counter()
        hits = _intersect(ctx, origins, dirs, tmax, rows, pixel, sample, depth)
        t1 = time.perf_counter()
        ctx.stats["time_intersect"] += t1 - t0
        if not first:
            ctx.stats["rays_specular"] += rows.shape[0]
        emit_target = acc["emission"] if first else acc["specular"]
        hit = hits.prim >= 0

        # Lights seen along the rays (in front of the geometry)
        visible = ls.visible_camera if first else ls.visible_glossy | ls.visible_transmission
        if np.any(visible & ctx.light_shows):
            geo_t = np.where(hit, hits.t.astype(np.float64), np.inf)
            light_t = np.full(rows.shape[0], np.inf)
            light_l = np.zeros((rows.shape[0], 3))
            groups = [(slice(None), ls.visible_camera)] if first else [
                (np.flatnonzero(transmitted), ls.visible_transmission),
                (np.flatnonzero(~transmitted), ls.visible_glossy)]
            for sel, vis in groups:
                light_t[sel], light_l[sel] = lights.intersect_lights(ls, vis, origins[sel], dirs[sel],
                                                                     geo_t[sel])
            seen = light_t < geo_t
            miss = ~seen & ~hit
            # Surfaces in front of the geometry, and sun discs on rays that escape (t = inf).
            shown = seen | miss
            _add(emit_target, rows[shown], thr[shown] * light_l[shown])
            hit &= ~seen
        else:
            miss = ~hit

        # Rays that escape see the world
        if np.any(ctx.world > 0) and np.any(miss):
            if not first:
                _add(acc["specular"], rows[miss], thr[miss] * ctx.world)
            elif ctx.scene.world.visible_to_camera:
                _add(acc["environment"], rows[miss], thr[miss] * ctx.world)
        if not np.any(hit):
            ctx.stats["time_shading"] += time.perf_counter() - t1
            break

        # Shade the hits: geometry, emission seen
        h = np.flatnonzero(hit) if not hit.all() else slice(None)
        rows, thr, d, transmitted = rows[h], thr[h], dirs[h], transmitted[h]
        pos, ngf, nsf, mat, eps, front = geometry.facing_surface_points(
            ctx.tri_vertices, ctx.tri_normals, ctx.tri_material, hits.prim[h], hits.u[h],
            hits.v[h], d, ctx.extent)
        albedo = ctx.surfaces.albedo(hits.prim[h], hits.u[h], hits.v[h], mat)
        _add(emit_target, rows, thr * mats["emission"][mat])  # two-sided, like Cycles' closure
        if features is not None:
            features.surface(rows, albedo, mats["specular"][mat], mats["transmission"][mat],
                             mats["alpha"][mat], nsf)
        ctx.stats["time_shading"] += time.perf_counter() - t1

        # Direct light at the hits' non-delta lobes
        nd = ctx.nondelta[mat]
        sel = slice(None) if nd.all() else np.flatnonzero(nd)
        if isinstance(sel, slice) or sel.size:
            r = rows[sel]
            hit_data = {"pos": pos[sel], "ngf": ngf[sel], "nsf": nsf[sel], "d": d[sel], "mat": mat[sel],
                        "eps": eps[sel], "thr": thr[sel], "rows": r, "albedo": albedo[sel]}
            direct.shade(ctx.direct, hit_data, pixel[r], sample[r], depth,
                          acc["direct"] if first else acc["specular"])

        # Caustics and indirect light at the hits' diffuse lobes
        if ctx.terms is not None and ctx.terms.active:
            _photon_terms(ctx, rows, pos, ngf, nsf, eps, mat, thr, pixel, sample, depth,
                          acc["caustics"] if first else acc["specular"],
                          acc["indirect"] if first else acc["specular"], albedo)

        # Spawn the specular rays
        if depth == st.max_specular_depth:
            break
        t0 = time.perf_counter()
        sd = np.flatnonzero(ctx.has_delta[mat])
        if sd.size == 0:
            break
        rs = rows[sd]
        u_lobe, u_pick = sampling.stratified2(st.seed, pixel[rs], sample[rs], s_count,
                                              sampling.stream(sampling.SPECULAR_CHOICE, depth))
        k = sd.shape[0]
        new_o, new_d, new_thr = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
        new_tr, ok = np.empty(k, bool), np.empty(k, bool)
        bsdf.continue_delta(pos[sd], ngf[sd], nsf[sd], d[sd], front[sd], mat[sd], eps[sd],
                            mats["specular"], mats["alpha"], mats["transmission"], mats["ior"],
                            u_lobe, u_pick, thr[sd], new_o, new_d, new_thr, new_tr, ok)
        keep = np.flatnonzero(ok)
        rows, origins, dirs = rs[keep], new_o[keep], new_d[keep]
        thr, transmitted = new_thr[keep], new_tr[keep]
        tmax = None
        ctx.stats["time_shading"] += time.perf_counter() - t0

    t0 = time.perf_counter()
    out = {}
    if features is not None:
        kept = {**kept, "denoising_albedo": features.albedo, "denoising_normal": features.normal}
    for name, per_sample in kept.items():
        mean = np.empty((pix.shape[0], 3))
        _pixel_mean_kernel(per_sample, s_count, mean)
        out[name] = mean
    ctx.stats["time_shading"] += time.perf_counter() - t0
    return out


# --- the render -----------------------------------------------------------------------------

def render(scene: Scene, settings: RenderSettings | None = None,
           progress: ProgressFn | None = None, photon_maps=None,
           on_tile: TileFn | None = None) -> RenderOutput:
    """Render ``scene``: the photon pass, then the camera pass with every term.

    progress(fraction in [0, 1], message) is called during photon tracing and between
    tiles (at least every ~0.3 s of rendering); returning True stops the render:
    unrendered pixels stay 0 and ``cancelled`` is True. photon_maps: a
    ``tracing.PhotonMaps`` to use instead of tracing (tests build them by hand); its
    global map must match the mode (with direct photons for final gathering, without
    for the preview). Raises SceneError / SettingsError on bad input.

    on_tile(pixels_done, passes) shows a long render filling in: called between tiles,
    at most once per UPDATE_SECONDS and taking at most UPDATE_SHARE of the time (never
    after the last tile), with ``passes`` as
    returned at the end (the pixels after ``pixels_done``, in row-major order from the
    top-left, still 0; no "photons" pass yet).

    Passes: "combined" always; of the light passes only ``settings.passes()`` (a
    switched-off term is still in combined but has no image of its own; the per-sample
    accumulators are the produced passes plus one shared by the others); "photons" only
    with ``settings.photon_debug_pass`` (no projection or occlusion work otherwise).

    stats (RenderOutput.stats) holds, besides the ray counters and timings,
    ``photon_maps`` (the tracer's stats), ``caustic_photons_stored`` /
    ``global_photons_stored`` (0 when the map was not built), ``caustic_radius`` /
    ``global_radius`` (metres, as used), ``skipped``: term -> why it was not rendered,
    ``passes_produced`` (the light passes returned) and ``pass_buffers`` (accumulator
    arrays per tile: the produced passes, plus one if any is switched off).
    """
    t_start = time.perf_counter()
    scene.validate()
    settings = (settings or RenderSettings()).validated()
    ctx = _prepare(scene, settings)
    t_prepared = time.perf_counter()
    try:
        photon_stats, photons_cancelled = photon_pass.run(ctx, photon_maps, progress,
                                                          PHOTON_SHARE)
    except BaseException:
        ctx.accel.close()
        raise
    t_photons = time.perf_counter()
    cam = scene.camera
    w, h = int(cam.width), int(cam.height)
    n_pix = w * h
    features = denoise_features.FEATURES if settings.denoising_data else ()
    images = {name: np.zeros((n_pix, 3)) for name in (*ctx.outputs, *features)}
    done = 0
    # Start small (the first tile also pays for loading the kernels), then adapt.
    per_tile = max(1, TARGET_SAMPLES_PER_TILE // 8 // settings.samples)
    max_tile = max(1, 4 * TARGET_SAMPLES_PER_TILE // settings.samples)
    tiles = 0
    share = PHOTON_SHARE if photon_stats.get("traced") else 0.0
    cancelled = photons_cancelled
    last_update, update_wait = time.perf_counter(), UPDATE_SECONDS
    try:
        while done < n_pix and not cancelled:
            t0 = time.perf_counter()
            pix = np.arange(done, min(n_pix, done + per_tile), dtype=np.int64)
            result = _render_tile(ctx, pix)
            for name in (*ctx.outputs, *features):
                images[name][pix] = result[name]
            done += pix.shape[0]
            tiles += 1
            took = time.perf_counter() - t0
            # Keep tiles short enough for a responsive progress bar and Esc.
            if took > TILE_SECONDS and per_tile > 1:
                per_tile = max(1, int(per_tile * TILE_SECONDS / took))
            elif took < TILE_SECONDS / 2:
                per_tile = min(per_tile * 2, max_tile)
            if progress is not None and done < n_pix:
                left = -(-(n_pix - done) // per_tile)
                fraction = share + (1.0 - share) * done / n_pix
                if progress(fraction, f"{'Gathering' if ctx.terms.active else 'Rendering'}: "
                                      f"tile {tiles} of {tiles + left} ({done}/{n_pix} pixels)"):
                    cancelled = True
                    break
            if (on_tile is not None and done < n_pix
                    and time.perf_counter() - last_update >= update_wait):
                t_call = time.perf_counter()
                on_tile(done, _assemble(images, ctx.outputs, h, w))
                last_update = time.perf_counter()
                update_wait = max(UPDATE_SECONDS, (last_update - t_call) / UPDATE_SHARE)
        used = UsedPhotonMaps(ctx.terms.global_map, ctx.terms.caustic_map)
        if used.global_map is None and used.caustic_map is None:
            used = None
        debug_dots = None
        if settings.photon_debug_pass and not cancelled:
            debug_dots = _photon_dots(ctx, used)
    finally:
        ctx.accel.close()
    if progress is not None and not cancelled:
        progress(1.0, "Done")
    passes = _assemble(images, ctx.outputs, h, w)
    for name in features:  # not light: not in combined
        passes[name] = images[name].reshape(h, w, 3).astype(np.float32)
    if debug_dots is not None:
        passes["photons"] = debug_dots
        if settings.overlay_composite:
            passes["combined"] = debug_overlay.composite_over(passes["combined"], debug_dots)
    t_end = time.perf_counter()
    stats = dict(ctx.stats)
    stats.update(ctx.terms.stats)
    stats.update(photon_stats)
    rays = (stats["rays_camera"] + stats["rays_specular"] + stats["rays_shadow"]
            + stats["rays_gather"])
    stats.update({
        "pixels": done, "samples": settings.samples, "tiles": tiles,
        "passes_produced": settings.passes(), "pass_buffers": len(ctx.outputs),
        "rays_total": rays, "time_prepare": t_prepared - t_start,
        "time_photons": t_photons - t_prepared,
        "time_render": t_end - t_photons, "time_total": t_end - t_start,
        "rays_per_second": rays / max(t_end - t_photons, 1e-12),  # over the camera pass
        "triangles": scene.mesh.triangle_count, "lights": scene.lights.count,
        "emissive_triangles": ctx.direct.emissive.count,
    })
    return RenderOutput(passes=passes, stats=stats, cancelled=cancelled, photon_maps=used)


def _assemble(images: dict, outputs: tuple, h: int, w: int) -> dict[str, np.ndarray]:
    """The returned passes from the per-pixel images (n_pix, 3) float64 of ``outputs``:
    "combined" (their float64 sum, cast) and each produced light pass, (h, w, 3) float32.
    Each image is cast to float32 before summing, so combined == the sum of the passes."""
    cast = {name: images[name].reshape(h, w, 3).astype(np.float32) for name in outputs}
    combined = np.zeros((h, w, 3))
    for name in outputs:
        combined += cast[name].astype(np.float64)
    cast.pop(REST, None)
    return {"combined": combined.astype(np.float32), **cast}


def _photon_dots(ctx: _Context, used: UsedPhotonMaps | None) -> np.ndarray:
    """The debug pass, (H, W, 4) float32 RGBA (all zero without photons); times it in
    ctx.stats["time_overlay"]."""
    t0 = time.perf_counter()
    positions, flux = debug_overlay.select_photons(
        used.global_map if used else None, used.caustic_map if used else None,
        ctx.settings.overlay_map)
    dots = debug_overlay.photon_overlay(ctx.scene.camera, ctx.accel, positions, flux,
                                        dot_radius_px=ctx.settings.overlay_dot_radius,
                                        extent=ctx.extent)
    ctx.stats["time_overlay"] = time.perf_counter() - t0
    return dots

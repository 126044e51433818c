"""The camera pass: what the camera sees directly, through mirrors and glass, and the
photon terms at the diffuse surfaces it reaches (the seed lecture's split).

Wavefront: a tile of pixels x samples becomes one batch of camera rays; each bounce
intersects the whole batch in Embree, shades it in numba kernels (emission, the direct
light of core/integrators/direct.py: one shadow ray per light per light sample, the photon estimates
of core/integrators/gather.py), and spawns at most one specular ray per path
(core/integrators/camera_paths.py: intersection through cut-outs, lights seen along the
rays, the mirror/glass continuation).

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
  (core/integrators/debug_overlay.py); not part of combined. With ``settings.overlay_composite`` the
  dots are also drawn over combined, which is then no longer the sum of the light passes.
A term evaluated at a diffuse surface seen through a mirror or glass belongs to the
specular pass, like the direct light there: the caustics and indirect passes show what
the camera sees directly, and every pixel's light is counted once.

Photon maps: ``render`` first traces them (core/integrators/photon_terms.py, over the
render's PreparedScene) unless ``photon_maps`` is given (tests pass hand-built maps); the
photon pass takes PHOTON_SHARE of the progress bar.

Specular rays: one lobe is sampled per hit (``camera_paths.follow_bsdf``,
``closure.sample_bsdf``: by the closures' sample weights, as Cycles picks a closure) and the
path weight is lobe / probability, so paths never split.

Sampling: pixel jitter, light samples and lobe choices are stratified over each pixel's
samples (``sampling.stratified2``, scrambled Sobol). Determinism: every random number is a
hash of (seed, pixel, sample, dimension), and a pixel's samples are always traced in one
tile and summed in sample order, so the image does not depend on tile sizes or threads.

Ray offsets: ``core.scene.geometry`` (eps proportional to the hit's coordinates plus the
scene size).

Textures and cut-outs (core/materials/textures.py): the diffuse albedo at each batch of
hits is ``PreparedScene.surfaces.albedo`` (textured where the material has an image, else the material's),
passed as (N, 3) to the shading kernel and the photon terms. Camera rays pass cut-outs
(opacity a < 1) with probability 1 - a without counting a bounce, so what is seen through
a cut-out stays in its pass; shadow rays are attenuated by 1 - a per cut-out crossed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import sampling
from ..materials import closure
from ..passes import (LIGHT_PASSES, PASSES, VOLUME_PASSES, ProgressFn, RenderOutput, StopFn,
                      TileFn, UsedPhotonMaps, consecutive_mean)
from ..prepared import PreparedScene, prepare
from ..scene import camera, geometry
from ..shading import light_path
from ..scene.contract import Scene
from ..settings import RenderSettings
from . import (adaptive, camera_paths, debug_overlay, denoise_features, direct, gather,
               photon_terms, volume)

# A tile holds about this many camera samples (all samples of its pixels); tiles grow
# while they take less than TILE_SECONDS and shrink when longer, so that progress (and
# cancelling) is never far away.
TARGET_SAMPLES_PER_TILE = 1 << 16
TILE_GROWTH = 4
"""A tile grows to at most TILE_GROWTH x TARGET_SAMPLES_PER_TILE samples (memory.py's
SAMPLES_PER_TILE: what the memory estimate allows in flight)."""
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


@dataclass
class _CameraPass:
    """What every tile reads: the prepared scene, the settings, the shadow rays, the
    photon terms, the counters, and the per-pixel images kept (the produced passes, then
    REST when some are off)."""

    prepared: PreparedScene
    settings: RenderSettings
    direct: direct.DirectLighting
    stats: dict
    outputs: tuple
    emits: bool
    """Some material emits (a constant or a program's emission): else the hits add none."""
    terms: gather.PhotonTerms | None = None
    volume: volume.VolumeTerms | None = None


def _camera_pass(prepared: PreparedScene, settings: RenderSettings) -> _CameraPass:
    stats = {"rays_camera": 0, "rays_specular": 0, "rays_shadow": 0,
             "time_intersect": 0.0, "time_shadow": 0.0, "time_shading": 0.0}
    media = volume.prepare(settings, prepared, settings.samples)
    passes = settings.passes()
    terms = LIGHT_PASSES
    if media is None:  # no medium: no volume passes (their terms are 0)
        passes = tuple(p for p in passes if p not in VOLUME_PASSES)
        terms = PASSES
    return _CameraPass(prepared=prepared, settings=settings,
                       direct=direct.prepare(settings, prepared, settings.samples, stats,
                                             None if media is None else media.medium),
                       stats=stats, volume=media,
                       outputs=passes + ((REST,) if len(passes) < len(terms) else ()),
                       emits=bool(np.any(prepared.materials["emission"] != 0.0)
                                  or prepared.hit_shader.emission_programmed.any()))


# --- one tile -------------------------------------------------------------------------------

def _add(acc, rows, values):
    """acc[rows] += values for unique rows (one path per camera sample)."""
    if rows.shape[0]:
        acc[rows] += values


def _photon_terms(ctx: _CameraPass, rows, pos, ngf, nsf, eps, mat, thr, pixel, sample, depth,
                  caustic_target, indirect_target, albedo, after_glossy, d, texel, front,
                  tab, crow, tangent, lam):
    """Add T * (caustics) and T * (indirect) at the hits with a diffuse lobe
    (core/integrators/gather.py). albedo (N, 3): the (textured) diffuse albedo at the hits;
    d (N, 3) the arriving directions, texel (N, 3), front (N,), tab and crow (N,) (the hits'
    closure rows, ``HitShader.closures_at``), tangent (N, 3) (``HitShader.tangents``): the
    BSDF where the diffuse-like lobes are not Lambert (``gather.bsdf_terms``); lam (N,)
    float64 the paths' wavelengths in nm (0: RGB), at which that BSDF is built and which
    their gather rays keep (docs/dispersion.md).
    after_glossy (N,) bool: the path reached the hit through a rough lobe; with
    ``global_after_glossy(terms)`` the diffuse part's whole radiance there is the global
    map's estimate (direct and caustic photons included), added to indirect_target."""
    terms = ctx.terms
    sel = np.flatnonzero(ctx.prepared.has_diffuse[mat])
    if sel.size == 0:
        return
    if global_after_glossy(terms):
        blur = after_glossy[sel]
        g = sel[blur]
        if g.size:
            t0 = time.perf_counter()
            # Non-Lambert diffuse-like lobes: the BSDF estimate (photons of both sides; the
            # cache holds Lambert's E / pi, so it is not read there)
            g, gb, hb = gather.bsdf_terms(terms, tab, g, mat, crow, texel, d, nsf, front, tangent,
                                          lam)
            if hb is not None:
                _add(indirect_target, rows[gb],
                     thr[gb] * gather.preview(terms, pos[gb], ngf[gb], None, hb))
            if g.size:
                est = (gather.cached_radiance(terms, pos[g], ngf[g], albedo[g])
                       if terms.cache is not None
                       else gather.preview(terms, pos[g], ngf[g], albedo[g]))
                _add(indirect_target, rows[g], thr[g] * est)
            ctx.stats["time_global_after_glossy"] = (ctx.stats.get("time_global_after_glossy", 0.0)
                                                     + time.perf_counter() - t0)
            ctx.stats["hits_global_after_glossy"] = ctx.stats.get("hits_global_after_glossy", 0) + g.size
        sel = sel[~blur]
        if sel.size == 0:
            return
    sel, bs, hb = gather.bsdf_terms(terms, tab, sel, mat, crow, texel, d, nsf, front, tangent,
                                    lam)
    if hb is not None:
        r = rows[bs]
        if terms.caustic_map is not None:
            _add(caustic_target, r, thr[bs] * gather.caustics(terms, pos[bs], ngf[bs], None, hb))
        if terms.global_map is not None and terms.mode == "final_gather":
            _add(indirect_target, r, thr[bs] * gather.final_gather(
                terms, ctx.prepared, ctx.settings, pos[bs], ngf[bs], nsf[bs], eps[bs],
                pixel[r], sample[r], depth, hb, lam[bs]))
        elif terms.global_map is not None and terms.mode == "preview":
            _add(indirect_target, r, thr[bs] * gather.preview(terms, pos[bs], ngf[bs], None, hb))
        if sel.size == 0:
            return
    r = rows[sel]
    albedo = albedo[sel]
    if terms.caustic_map is not None:
        _add(caustic_target, r, thr[sel] * gather.caustics(terms, pos[sel], ngf[sel], albedo))
    if terms.global_map is None:
        return
    if terms.mode == "final_gather":
        incoming = gather.final_gather(terms, ctx.prepared, ctx.settings, pos[sel], ngf[sel],
                                       nsf[sel], eps[sel], pixel[r], sample[r], depth,
                                       lam=lam[sel])
        _add(indirect_target, r, thr[sel] * albedo * incoming)
    elif terms.mode == "preview":
        _add(indirect_target, r, thr[sel] * gather.preview(terms, pos[sel], ngf[sel], albedo))


GLOBAL_AFTER_GLOSSY = False
"""At a diffuse hit reached through a rough (glossy) lobe, take the diffuse part's radiance
from the global map alone (built with direct photons for final gathering) instead of shadow
rays + caustic map + final gathering. Off: measured by benchmarks/bench_glossy.py (glossy
room, 64x64, 8 spp, against 32 spp with it off), the global map alone saves 30 % of the
render time (32 % fewer gather rays) at the same RMS error, but its estimate is 7 % high on
the specular pass (density-estimation bias seen through the glossy lobe), while final
gathering there is within 1 % of the reference."""


def global_after_glossy(terms) -> bool:
    """Whether diffuse hits after a glossy bounce read the global map alone: the map holds
    direct photons (final gathering) and GLOBAL_AFTER_GLOSSY is on."""
    return (GLOBAL_AFTER_GLOSSY and terms is not None and terms.global_map is not None
            and terms.mode == "final_gather")


def _render_tile(ctx: _CameraPass, pix: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Per-pixel means (P, 3) float64 of every pass (and denoising feature) for the pixels
    ``pix`` (P,) int64, and the samples each pixel took (P,) int64.

    Without adaptive sampling every pixel takes ``settings.samples``. With it
    (``settings.adaptive_threshold`` > 0) every pixel first takes ``adaptive.min_samples``,
    then the pixels whose ``adaptive.relative_error`` is still above the threshold, and
    their neighbours in the row (``adaptive.unconverged``; the tiles are whole rows then),
    double their samples, round after round, up to ``settings.samples``. A sample is the same
    whichever round takes it: its random numbers are those of its index in the pixel's
    set of ``settings.samples``, whose first 2^b indices are themselves stratified
    (``sampling.stratified2``)."""
    st = ctx.settings
    pix = pix.astype(np.int64)
    first = adaptive.min_samples(st)
    moments = adaptive.Moments(pix.shape[0]) if first < st.samples else None
    means = _trace_means(ctx, pix, 0, first, moments, np.arange(pix.shape[0]))
    count = np.full(pix.shape[0], first, np.int64)
    if first == st.samples:  # every sample in one round
        return means, count
    sums = {name: v * first for name, v in means.items()}
    lo = first
    while lo < st.samples:
        active = np.flatnonzero(adaptive.unconverged(moments, pix, ctx.prepared.scene.camera.width,
                                                     st.adaptive_threshold))
        if active.size == 0:
            break
        hi = min(2 * lo, st.samples)
        for name, v in _trace_means(ctx, pix[active], lo, hi, moments, active).items():
            sums[name][active] += v * (hi - lo)
        count[active] = hi
        lo = hi
    return {name: v / count[:, None] for name, v in sums.items()}, count


def _trace_means(ctx: _CameraPass, pix: np.ndarray, lo: int, hi: int,
                 moments: adaptive.Moments | None, rows: np.ndarray) -> dict[str, np.ndarray]:
    """Per-pixel means (P, 3) float64 of every pass and denoising feature over samples
    lo ... hi - 1 of the pixels ``pix`` (P,) int64, whose combined values go into
    ``moments`` (when sampling adaptively) at ``rows`` (P,) int64.

    Traced in batches of at most TILE_GROWTH x TARGET_SAMPLES_PER_TILE samples (the
    most a tile holds): an adaptive tile is whole
    rows, whose rounds can be wider than that. A sample's values do not depend on its
    batch, and a pixel's samples are summed in order within a batch of its samples, so the
    batching changes nothing below that size."""
    cap = TILE_GROWTH * TARGET_SAMPLES_PER_TILE
    k = hi - lo
    if k > cap:  # one pixel's samples exceed a batch: sums of sub-ranges
        out = None
        for a in range(lo, hi, cap):
            b = min(a + cap, hi)
            part = _trace_means(ctx, pix, a, b, moments, rows)
            out = ({n: v * (b - a) for n, v in part.items()} if out is None
                   else {n: out[n] + v * (b - a) for n, v in part.items()})
        return {n: v / k for n, v in out.items()}
    per_batch = max(1, cap // k)
    out = {}
    for start in range(0, pix.shape[0], per_batch):
        part = slice(start, start + per_batch)
        values, features = _trace_samples(ctx, pix[part], lo, hi)
        if moments is not None:
            moments.add(rows[part], _combined(values, ctx.outputs), k)
        for name, v in (*((n, consecutive_mean(v, k)) for n, v in values.items()),
                        *features.items()):
            if name not in out:
                out[name] = np.empty((pix.shape[0], 3))
            out[name][part] = v
    return out


def _combined(values: dict[str, np.ndarray], outputs: tuple) -> np.ndarray:
    """(N, 3) float64: each sample's sum of the light terms (what "combined" averages)."""
    total = np.zeros_like(values[outputs[0]])
    for name in outputs:
        total += values[name]
    return total


def _trace_samples(ctx: _CameraPass, pix: np.ndarray, lo: int, hi: int):
    """Trace samples lo ... hi - 1 of each pixel ``pix`` (P,) int64: (the per-sample values
    (P * (hi - lo), 3) float64 of each produced pass (``ctx.outputs``), a pixel's samples
    consecutive; the per-pixel means (P, 3) of the denoising features, or {} without
    them)."""
    st = ctx.settings
    s_count = st.samples
    pixel = np.repeat(pix, hi - lo)
    sample = np.tile(np.arange(lo, hi, dtype=np.int64), pix.shape[0])
    n = pixel.shape[0]
    # Switched-off passes share the REST accumulator: every term still reaches combined.
    kept = {name: np.zeros((n, 3)) for name in ctx.outputs}
    acc = {name: kept.get(name, kept.get(REST)) for name in LIGHT_PASSES}
    pr = ctx.prepared
    mats = pr.materials
    k_light = int(st.light_samples)
    blur_global = global_after_glossy(ctx.terms) and ctx.terms.active
    emits = ctx.emits
    t0 = time.perf_counter()

    # Generate camera rays
    jitter = np.stack(sampling.stratified2(st.seed, pixel, sample, s_count,
                                           sampling.stream(sampling.PIXEL_JITTER)), axis=1)
    lens = None
    if camera.has_aperture(pr.scene.camera):  # depth of field: a point on the aperture
        lens = np.stack(sampling.stratified2(st.seed, pixel, sample, s_count,
                                             sampling.stream(sampling.PIXEL_JITTER, 1)), axis=1)
    rays = camera.generate_rays(pr.scene.camera, pixel, jitter, lens)
    origins, dirs, tmax = rays.origins, rays.directions, rays.tmax
    features = None
    if st.denoising_data:  # Cycles' Denoising Albedo / Normal (denoise_features.py)
        features = denoise_features.FeatureAccumulator(n, camera.camera_frame(pr.scene.camera)[1:])
    rows = np.arange(n)
    thr = np.ones((n, 3))
    transmitted = np.zeros(n, bool)
    # MIS state of each path: the pdf its last direction was sampled with (0: camera ray
    # or delta lobe), the shading normal it left, and whether a rough lobe was followed.
    prev_pdf = np.zeros(n)
    prev_ns = np.zeros((n, 3))
    prev_sphere = np.zeros(n, bool)  # the previous hit transmits: the world sampled all round
    glossy = np.zeros(n, bool)
    # The Light Path node's context (core/shading/light_path.py), only when a program reads
    # it: the last bounce was delta (Is Singular Ray), the transmissions so far.
    lp_read = pr.hit_shader.reads_light_path
    last_delta = np.ones(n, bool)
    n_trans = np.zeros(n)
    # The refractive index of the dielectric each path is inside (1: none). Camera paths
    # do not scale radiance by eta^2 at a refraction (Cycles' convention, exact for paths
    # that leave every dielectric they enter); the photons' estimates inside a dielectric
    # are physical radiance, so the volume terms divide them by n^2 (volume.add_segments).
    n_inside = np.ones(n)
    # Each path's wavelength in nm, 0 while it is RGB (docs/dispersion.md: picked at its
    # first dispersive surface, kept to its end).
    lam = np.zeros(n)
    ctx.stats["rays_camera"] += n
    ctx.stats["time_shading"] += time.perf_counter() - t0

    for depth in range(st.max_specular_depth + 1):
        if rows.shape[0] == 0:
            break
        first = depth == 0
        # Intersect the batch
        t0 = time.perf_counter()
        path = None
        if lp_read:  # the rays' Light Path context; Ray Length is set at the hits
            path = light_path.camera(np.zeros(rows.shape[0])) if first else \
                light_path.after_bounce(np.zeros(rows.shape[0]), np.where(
                    last_delta, light_path.BOUNCE_SINGULAR, light_path.BOUNCE_GLOSSY),
                    transmitted, depth, glossy_depth=depth, transmission_depth=n_trans)
        hits = camera_paths.intersect(
            pr, st.seed, origins, dirs, tmax, rows, pixel, sample,
            lambda layer, depth=depth: sampling.stream(sampling.CUTOUT_CHOICE, depth, layer),
            path)
        t1 = time.perf_counter()
        ctx.stats["time_intersect"] += t1 - t0
        if not first:
            ctx.stats["rays_specular"] += rows.shape[0]
        emit_target = acc["emission"] if first else acc["specular"]
        thr_light = thr  # the lights along the rays are attenuated to themselves
        if ctx.volume is not None:  # the segments' medium: its light, then its transmittance
            thr = volume.add_segments(
                ctx.volume, origins, dirs, np.where(hits.prim >= 0, hits.t, np.inf), thr,
                rows, pixel, sample, depth, acc["volume_direct"] if first else acc["specular"],
                acc["volume_indirect"] if first else acc["specular"], emit_target, ctx.stats,
                n_inside, volume.surface_bounds(pr, hits.prim, dirs))

        # Lights seen along the rays (lights are not occluders), weighed against light
        # sampling after a rough lobe
        hit, miss, shown, light_l = camera_paths.lights_along(
            pr, first, transmitted, origins, dirs, hits, prev_pdf, k_light,
            None if ctx.volume is None else ctx.volume.medium)
        if shown is not None:
            _add(emit_target, rows[shown], thr_light[shown] * light_l[shown])

        # Rays that escape see the world
        if np.any(pr.world > 0) and np.any(miss):
            if not first:
                wm = camera_paths.world_weight(prev_pdf[miss], prev_ns[miss], dirs[miss], k_light,
                                               prev_sphere[miss])
                _add(acc["specular"], rows[miss], thr[miss] * wm[:, None] * pr.world)
            elif pr.scene.world.visible_to_camera:
                _add(acc["environment"], rows[miss], thr[miss] * pr.world)
        if not np.any(hit):
            ctx.stats["time_shading"] += time.perf_counter() - t1
            break

        # Shade the hits: geometry, emission seen
        h = np.flatnonzero(hit) if not hit.all() else slice(None)
        rows, thr, d, transmitted = rows[h], thr[h], dirs[h], transmitted[h]
        prev_pdf, glossy, n_inside, lam = prev_pdf[h], glossy[h], n_inside[h], lam[h]
        prim = hits.prim[h]
        if lp_read:
            path = path[h]
            path[:, light_path.RAY_LENGTH] = hits.t[h]
            last_delta, n_trans = last_delta[h], n_trans[h]
        pos, ngf, nsf, mat, eps, front = geometry.facing_surface_points(
            pr.tri_vertices, pr.tri_normals, pr.tri_material, prim, hits.u[h],
            hits.v[h], d, pr.extent)
        albedo = pr.surfaces.albedo(prim, hits.u[h], hits.v[h], mat)
        texel = pr.texels.albedo(prim, hits.u[h], hits.v[h], mat)
        # Shader programs: the closures at each programmed hit (crow: its row in tab) and
        # the shading normal a Normal Map or Bump sets (every term below reads nsf).
        tab, crow, nsf = pr.hit_shader.shade(prim, hits.u[h], hits.v[h], d, mat, nsf, path)
        albedo = pr.hit_shader.diffuse_albedo(tab, crow, mat, texel, d, nsf, albedo)
        if np.any(tab.abbe > 0):
            # Dispersion: a path picks its wavelength at its first dispersive surface,
            # before it is shaded there (camera_paths.pick_wavelengths), stratified over
            # the pixel's samples (the Sobol set's second coordinate, as for the lobe).
            u_lam = sampling.stratified2(st.seed, pixel[rows], sample[rows], s_count,
                                         sampling.stream(sampling.CAMERA_WAVELENGTH, depth))[1]
            thr = np.array(thr)  # the hits' own copy (thr[h] may be a view)
            camera_paths.pick_wavelengths(tab, crow, u_lam, lam, thr)
        tangent = pr.hit_shader.tangents(prim, pos, tab, crow)
        if emits:  # (the (N, 3) scatter-add of zeros was 5 % of a camera pass)
            emission = pr.hit_shader.emission_at(prim, hits.u[h], hits.v[h], d, mat,
                                                 mats["emission"][mat], path)
            if pr.emissive.count and np.any(prev_pdf > 0):
                emission = emission * camera_paths.emission_weight(
                    pr, prim, hits.t[h], d, prev_pdf, k_light)[:, None]
            _add(emit_target, rows, thr * emission)  # two-sided, like Cycles' closure
        if features is not None:
            features.surface(rows, albedo, mats["specular"][mat], mats["transmission"][mat],
                             mats["alpha"][mat], nsf)
        ctx.stats["time_shading"] += time.perf_counter() - t1

        # Direct light at the hits' non-delta lobes (MIS with the BSDF-sampled continuation)
        last = depth == st.max_specular_depth
        nd = pr.nondelta[mat]
        sel = slice(None) if nd.all() else np.flatnonzero(nd)
        if isinstance(sel, slice) or sel.size:
            r = rows[sel]
            diffuse_on = (~glossy[sel]).astype(np.float64) if blur_global else None
            mis = np.full(r.shape[0], not last)
            points = direct.ShadingPoints(pos[sel], ngf[sel], nsf[sel], d[sel], crow[sel],
                                          eps[sel], thr[sel], albedo[sel], r, texel[sel],
                                          diffuse_on, mis, front[sel], tab, lam[sel],
                                          tangent[sel])
            direct.shade(ctx.direct, points, pixel[r], sample[r], depth,
                         acc["direct"] if first else acc["specular"])

        # Caustics and indirect light at the hits' diffuse lobes. Inside a dielectric
        # they are physical radiance, n^2 times what camera paths carry there (they do
        # not scale radiance by eta^2 at a refraction, Cycles' convention; see n_inside).
        if ctx.terms is not None and ctx.terms.active:
            inside = np.flatnonzero(n_inside != 1.0)
            thr_photons = thr
            if inside.size:
                thr_photons = np.array(thr)
                thr_photons[inside] /= (n_inside[inside] ** 2)[:, None]
            _photon_terms(ctx, rows, pos, ngf, nsf, eps, mat, thr_photons, pixel, sample, depth,
                          acc["caustics"] if first else acc["specular"],
                          acc["indirect"] if first else acc["specular"], albedo, glossy, d,
                          texel, front, tab, crow, tangent, lam)

        # Continue through one sampled lobe: mirrors, glass, the glossy part of rough lobes
        if last:
            break
        t0 = time.perf_counter()
        sd = np.flatnonzero(pr.specular_material[mat])
        if sd.size == 0:
            break
        rs = rows[sd]
        u1, u2 = sampling.stratified2(st.seed, pixel[rs], sample[rs], s_count,
                                      sampling.stream(sampling.SPECULAR_CHOICE, depth))
        u3 = sampling.uniform(st.seed, pixel[rs], sample[rs],
                              sampling.stream(sampling.SPECULAR_CHOICE, depth, 1))
        u_rr = sampling.uniform(st.seed, pixel[rs], sample[rs],
                                sampling.stream(sampling.SPECULAR_CHOICE, depth, 2))
        # The lobe choice takes the Sobol set's second coordinate: its first repeats the
        # order of the pixel jitter's, which correlates a pixel's samples (noisier glass).
        keep, origins, dirs, thr, transmitted, prev_pdf, was_delta, lam = camera_paths.follow_bsdf(
            pr, pos[sd], ngf[sd], nsf[sd], d[sd], front[sd], crow[sd], eps[sd], texel[sd],
            thr[sd], lam[sd], u2, u1, u3, u_rr, closures=tab, tangent=tangent[sd])
        prev_ns = nsf[sd][keep]
        prev_sphere = closure.transmitting(tab, crow[sd][keep])
        glossy = glossy[sd][keep] | ~was_delta
        if lp_read:
            last_delta = was_delta
            n_trans = n_trans[sd][keep] + transmitted
        n_inside = camera_paths.index_after(pr, n_inside[sd][keep], transmitted,
                                            front[sd][keep], mat[sd][keep])
        rows = rs[keep]
        tmax = None
        ctx.stats["time_shading"] += time.perf_counter() - t0

    means = {}
    if features is not None:
        means = {"denoising_albedo": consecutive_mean(features.albedo, hi - lo),
                 "denoising_normal": consecutive_mean(features.normal, hi - lo)}
    return kept, means


# --- the render -----------------------------------------------------------------------------

def render(scene: Scene, settings: RenderSettings | None = None,
           on_progress: ProgressFn | None = None, on_tile: TileFn | None = None,
           should_stop: StopFn | None = None, photon_maps=None) -> RenderOutput:
    """Render ``scene``: the photon pass, then the camera pass with every term.

    on_progress(fraction in [0, 1], message) is called during photon tracing and between
    tiles (at least every ~0.3 s of rendering); should_stop() -> True stops the render
    between two batches: unrendered pixels stay 0 and ``cancelled`` is True. photon_maps:
    a ``tracing.PhotonMaps`` to use instead of tracing (tests build them by hand); its
    global map must match the mode (with direct photons for final gathering, without
    for the preview). Raises SceneError / SettingsError on bad input.

    on_tile(pixels_done, passes) shows a long render filling in: called between tiles,
    at most once per UPDATE_SECONDS and taking at most UPDATE_SHARE of the time (never
    after the last tile), with ``passes`` as
    returned at the end (the pixels after ``pixels_done``, in row-major order from the
    top-left, still 0; no "photons" pass yet).

    With a Render Region (``scene.camera.region``) only its pixels are rendered and every
    pass is (y1 - y0, x1 - x0): the same values as those pixels of a whole-frame render.

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
    prepared = prepare(scene, settings.threads, settings.seed)
    ctx = _camera_pass(prepared, settings)
    t_prepared = time.perf_counter()
    try:
        ctx.terms, photon_stats, photons_cancelled = photon_terms.run(
            prepared, settings, photon_maps, on_progress, should_stop, PHOTON_SHARE)
        if ctx.volume is not None:
            ctx.volume.volume_map = ctx.terms.volume_map
            ctx.volume.caustic_map = ctx.terms.volume_caustic_map
    except BaseException:
        prepared.close()
        raise
    t_photons = time.perf_counter()
    cam = scene.camera
    # The Render Region: its pixels only, each rendered from its frame index (rays and
    # random numbers as in a whole-frame render); the passes are the region's size.
    x0, y0, x1, y1 = camera.region_of(cam)
    w, h = x1 - x0, y1 - y0
    frame_pixels = camera.region_pixels(cam)
    n_pix = w * h
    features = denoise_features.FEATURES if settings.denoising_data else ()
    images = {name: np.zeros((n_pix, 3)) for name in (*ctx.outputs, *features)}
    samples_taken = np.zeros(n_pix, np.int64)
    done = 0
    # Start small (the first tile also pays for loading the kernels), then adapt.
    per_tile = max(1, TARGET_SAMPLES_PER_TILE // 8 // settings.samples)
    # Adaptive sampling's neighbour rule reads a pixel's row: tiles of whole rows keep the
    # image independent of the tiling.
    adaptive_rows = adaptive.min_samples(settings) < settings.samples

    def row_multiple(count):
        return max(w, count // w * w) if adaptive_rows else count

    max_tile = max(1, TILE_GROWTH * TARGET_SAMPLES_PER_TILE // settings.samples)
    tiles = 0
    share = PHOTON_SHARE if photon_stats.get("traced") else 0.0
    cancelled = photons_cancelled
    last_update, update_wait = time.perf_counter(), UPDATE_SECONDS
    try:
        while done < n_pix and not cancelled:
            t0 = time.perf_counter()
            rows = np.arange(done, min(n_pix, done + row_multiple(per_tile)), dtype=np.int64)
            result, taken = _render_tile(ctx, frame_pixels[rows])
            for name in (*ctx.outputs, *features):
                images[name][rows] = result[name]
            samples_taken[rows] = taken
            done += rows.shape[0]
            tiles += 1
            took = time.perf_counter() - t0
            # Keep tiles short enough for a responsive progress bar and Esc.
            if took > TILE_SECONDS and per_tile > 1:
                per_tile = max(1, int(per_tile * TILE_SECONDS / took))
            elif took < TILE_SECONDS / 2:
                per_tile = min(per_tile * 2, max_tile)
            if on_progress is not None and done < n_pix:
                left = -(-(n_pix - done) // row_multiple(per_tile))
                fraction = share + (1.0 - share) * done / n_pix
                on_progress(fraction, f"{'Gathering' if ctx.terms.active else 'Rendering'}: "
                                      f"tile {tiles} of {tiles + left} ({done}/{n_pix} pixels)")
            if should_stop is not None and done < n_pix and should_stop():
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
        prepared.close()
    if on_progress is not None and not cancelled:
        on_progress(1.0, "Done")
    passes = _assemble(images, ctx.outputs, h, w)
    for name in features:  # not light: not in combined
        passes[name] = images[name].reshape(h, w, 3).astype(np.float32)
    if debug_dots is not None:
        passes["photons"] = debug_dots = np.ascontiguousarray(debug_dots[y0:y1, x0:x1])
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
        # samples per rendered pixel: all ``samples`` without adaptive sampling
        "samples_per_pixel": samples_taken.reshape(h, w),
        "samples_mean": float(samples_taken[:done].mean()) if done else 0.0,
        "passes_produced": tuple(p for p in ctx.outputs if p != REST),
        "pass_buffers": len(ctx.outputs),
        "rays_total": rays, "time_prepare": t_prepared - t_start,
        "time_photons": t_photons - t_prepared,
        "time_render": t_end - t_photons, "time_total": t_end - t_start,
        "rays_per_second": rays / max(t_end - t_photons, 1e-12),  # over the camera pass
        "triangles": scene.mesh.triangle_count, "lights": scene.lights.count,
        "emissive_triangles": prepared.emissive.count,
    })
    if prepared.medium is not None and prepared.medium.fields is not None:
        # Density clipping over both passes, for Blender's report (photon_engine/render.py)
        stats["medium_warnings"] = prepared.medium.fields.warnings()
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


def _photon_dots(ctx: _CameraPass, used: UsedPhotonMaps | None) -> np.ndarray:
    """The debug pass, (H, W, 4) float32 RGBA (all zero without photons); times it in
    ctx.stats["time_overlay"]."""
    t0 = time.perf_counter()
    positions, flux = debug_overlay.select_photons(
        used.global_map if used else None, used.caustic_map if used else None,
        ctx.settings.overlay_map)
    pr = ctx.prepared
    dots = debug_overlay.photon_overlay(pr.scene.camera, pr.accel, positions, flux,
                                        dot_radius_px=ctx.settings.overlay_dot_radius,
                                        extent=pr.extent)
    ctx.stats["time_overlay"] = time.perf_counter() - t0
    return dots

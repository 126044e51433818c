"""Stochastic progressive photon mapping (SPPM; Hachisuka & Jensen 2009): a render whose
error goes to zero as passes accumulate, with the memory of one photon pass.

Each pass k = 1, 2, ...:

1. Visible points. One jittered camera ray per pixel (a new sample each pass) follows
   mirrors and glass (``bsdf.sample_delta``) to the first surface with a diffuse lobe:
   the pixel's visible point x_k, with path weight beta_k (the throughput, lobe value /
   probability). Emitters, visible lights and the background seen along the way are added
   to the pixel's directly seen radiance sum D. At a material with both a diffuse and a
   delta lobe the path stops at the diffuse lobe with probability
   p = mean(diffuse) / (mean(diffuse) + delta weight) and beta is divided by p (or by
   1 - p when it goes on), so there is one visible point per pixel and pass.
   Direct light at the visible point comes from shadow rays to every light, emissive
   triangle and the world (``direct.shade``, the photon-map integrator's own estimator,
   ``light_samples`` per light and pass), added to D times beta_k.
2. Photons. ``photons_per_pass`` photons are traced with the global map's rules
   (``tracing.trace_stored_photons``), stored at every diffuse hit except the first hit
   of a photon straight from its source (``scatter.STORE_NOT_DIRECT``: that light is the
   shadow rays'), so caustics (light -> specular -> diffuse) and indirect light come from
   photons; with a fresh counter-based seed per pass.
   Each stored photon p has flux Phi_p (watts, already divided by photons_per_pass) and
   incident direction w_p (towards where it came from).
3. Gathering. For every visible point i (radius R_i), over the photons of this pass with
   |x_p - x_i| <= R_i and w_p on the visible side of the surface (n_g . w_p > 0, the
   front-side test; n_g faces the camera ray):
       M_i   = number of such photons,
       Phi_i = sum_p f_i(w_o, w_p) Phi_p        (f = diffuse / pi + rough glossy lobe),
   then the SPPM update with alpha in (0, 1):
       N_i' = N_i + alpha M_i
       R_i' = R_i sqrt((N_i + alpha M_i) / (N_i + M_i))
       tau_i' = (tau_i + beta_i Phi_i) (R_i'^2 / R_i^2)
   (nothing changes where M_i = 0 or the pixel has no visible point this pass).
4. The image after k passes, radiance W/(m^2 sr):
       L_i = D_i / k + tau_i / (k pi R_i^2)
   tau / k is the flux estimate per pass (each pass's photon flux is normalised by its
   own photon count, so pbrt's N_emitted = k passes x photons_per_pass becomes k here).

Direct light by shadow rays, everything else by photons (a hybrid; standard SPPM counts
direct light by photons too): directly lit diffuse surfaces are then exact in
expectation from the first pass on, without the blotches of a photon estimate, at the
cost of one shadow ray per light and visible point per pass; the photon estimate is
left with the paths only photons find well (caustics) and the smooth indirect light.
Both converge to the same image (tests/core/integrators/test_sppm.py checks the split against the
all-photon form).

Initial radius (when not given): R_0 = sqrt(K0 A_d / (pi photons_per_pass)) with A_d the
area of the triangles with a diffuse lobe and K0 = INITIAL_PHOTONS: about K0 photons per
disc if every photon stored once on a uniformly lit surface. It scales with the scene
(a scene scaled by s gets s R_0), so the image is scale-invariant.

Neighbour search: per pass, a hash grid over the pass's photons with cells as wide as the
median current radius (at least the largest / MAX_RING); each visible point scans the
ceil(R_i / h) rings of cells around its own (numba, parallel over visible points, so no
write races; exact: every photon within R_i is found once). Memory: one pass's photons plus per-pixel
statistics (N, R, tau, D: 8 float64 per pixel), whatever the number of passes.

Determinism: camera numbers are hashes of (seed, pixel, pass, dimension) and photon
numbers of (pass seed, photon, bounce, dimension) with pass seed a hash of (seed, pass).
Glossy-only surfaces (no diffuse lobe) store no photons and end camera paths (black).
Textures: the visible points carry the textured diffuse albedo of their hit; camera paths
pass cut-outs stochastically like the integrator's (core/materials/textures.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..materials import bsdf
from ..passes import ProgressFn, RenderOutput, StopFn, TileFn
from ..photons.hash_grid import HashGrid, within
from ..photons.store import STORE_ALL, STORE_NOT_DIRECT
from ..photons.tracing import photon_sources, trace_stored_photons
from ..prepared import PreparedScene, prepare
from ..scene.contract import Scene
from ..settings import MAX_PROGRESSIVE_PASSES as MAX_PASSES, RenderSettings, SettingsError
from . import camera_paths
from . import direct as direct_light
from .camera_paths import VisiblePoints

INITIAL_PHOTONS = 16.0
"""K0 of the automatic initial radius: photons expected in a disc on a uniformly lit surface."""
MAX_RING = 4
"""Largest number of cell rings a visible point scans in the photon grid (cells >= R_max / 4)."""

@dataclass
class SPPMState:
    """Per-pixel statistics after ``passes`` passes (P = width x height pixels, row-major,
    row 0 at the top).

    n: (P,) float64, accumulated photon count N (grows by alpha M per pass).
    radius: (P,) float64, current gather radius R, metres (never grows).
    tau: (P, 3) float64, accumulated weighted flux, watts.
    direct_sum: (P, 3) float64, sum over passes of the radiance seen directly (emitters,
        lights, background), W/(m^2 sr).
    stats: counters of the run so far (see ``render_progressive``).
    """

    width: int
    height: int
    passes: int
    n: np.ndarray
    radius: np.ndarray
    tau: np.ndarray
    direct_sum: np.ndarray
    stats: dict

    def radiance(self) -> np.ndarray:
        """(H, W, 3) float32 image, W/(m^2 sr): L = D / k + tau / (k pi R^2)."""
        k = max(self.passes, 1)
        photon = self.tau / (k * np.pi * self.radius * self.radius)[:, None]
        img = self.direct_sum / k + photon
        return img.reshape(self.height, self.width, 3).astype(np.float32)


# --- kernels --------------------------------------------------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _gather_kernel(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, radius, ph_pos, ph_flux, ph_dir, cells,
                   start, order, lo, inv_h, mask, vp_albedo, specular, alpha, phi, count):
    """phi[i] = sum f(wo, w_p) Phi_p and count[i] = M over this pass's photons within
    radius[i] of visible point i on its visible side."""
    for i in prange(vp_pos.shape[0]):
        px, py, pz = vp_pos[i, 0], vp_pos[i, 1], vp_pos[i, 2]
        r2 = radius[i] * radius[i]
        m = vp_mat[i]
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        c = 0
        ring = np.int64(np.ceil(radius[i] * inv_h))
        for k in within(px, py, pz, r2, ring, ph_pos, lo, inv_h, mask, cells, start, order):
            wx, wy, wz = ph_dir[k, 0], ph_dir[k, 1], ph_dir[k, 2]
            # Front-side test: the photon arrived on the side the camera sees.
            if vp_ng[i, 0] * wx + vp_ng[i, 1] * wy + vp_ng[i, 2] * wz <= 0.0:
                continue
            c += 1
            kd, ks = bsdf.eval_reflection(
                0.0, 0.0, alpha[m], vp_ns[i, 0], vp_ns[i, 1], vp_ns[i, 2],
                vp_wo[i, 0], vp_wo[i, 1], vp_wo[i, 2], wx, wy, wz)
            a0 += (vp_albedo[i, 0] * kd + specular[m, 0] * ks) * ph_flux[k, 0]
            a1 += (vp_albedo[i, 1] * kd + specular[m, 1] * ks) * ph_flux[k, 1]
            a2 += (vp_albedo[i, 2] * kd + specular[m, 2] * ks) * ph_flux[k, 2]
        phi[i, 0], phi[i, 1], phi[i, 2] = a0, a1, a2
        count[i] = c


def gather_photons(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, radius, ph_pos, ph_flux, ph_dir, mats,
                   vp_albedo=None):
    """Phi (V, 3) float64 and M (V,) int64 of step 3 for V visible points and one pass's
    photons (positions, flux, directions (P, 3) float32); mats: ``bsdf.material_table``;
    vp_albedo (V, 3): the points' (textured) diffuse albedo, default the materials'."""
    if vp_albedo is None:
        vp_albedo = mats["diffuse"][vp_mat]
    v = vp_pos.shape[0]
    phi = np.zeros((v, 3))
    count = np.zeros(v, np.int64)
    if v == 0 or ph_pos.shape[0] == 0:
        return phi, count
    # Cells of the typical radius; a point with a larger radius (a dark pixel that caught
    # few photons keeps a wide one) scans ceil(R / h) rings of cells, at most MAX_RING.
    h = max(float(np.median(radius)), float(np.max(radius)) / MAX_RING)
    g = HashGrid(ph_pos, h)
    _gather_kernel(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, np.ascontiguousarray(radius, np.float64),
                   ph_pos, ph_flux, ph_dir, g.cells, g.start, g.order, g.lo, g.inv_h, g.mask,
                   np.ascontiguousarray(vp_albedo, np.float64), mats["specular"], mats["alpha"],
                   phi, count)
    return phi, count


def _update(state: SPPMState, vps: VisiblePoints, phi: np.ndarray, count: np.ndarray,
            alpha: float) -> None:
    """Step 3's statistics update at the pixels whose visible point caught photons."""
    s = np.flatnonzero(count > 0)
    if s.size == 0:
        return
    p, m = vps.pixel[s], count[s].astype(np.float64)
    n_old, r_old = state.n[p], state.radius[p]
    n_new = n_old + alpha * m
    r_new = r_old * np.sqrt(n_new / (n_old + m))
    state.tau[p] = (state.tau[p] + vps.weight[s] * phi[s]) * ((r_new / r_old) ** 2)[:, None]
    state.n[p] = n_new
    state.radius[p] = r_new


# --- driver ---------------------------------------------------------------------------------

def initial_radius_for(prepared: PreparedScene, photons_per_pass: int) -> float:
    """The automatic R_0 (metres) of the module doc; a scene with no diffuse area gets
    1e-3 of its size (no photon can be gathered there anyway)."""
    extent = prepared.extent
    area = prepared.diffuse_area
    if area <= 0.0 or photons_per_pass <= 0:
        return max(1e-3 * extent, 1e-30)
    r = np.sqrt(INITIAL_PHOTONS * area / (np.pi * photons_per_pass))
    return float(min(r, 0.25 * extent)) if extent > 0 else float(r)


DIRECT_MODES = ("shadow_rays", "photons")
"""How SPPM gets direct light (``RenderSettings.progressive_direct``): shadow rays (the
default, the module doc) or photons (standard SPPM, kept to check the hybrid against)."""


def progressive_passes(scene: Scene, settings: RenderSettings | None = None,
                       max_passes: int | None = None) -> Iterator[SPPMState]:
    """Run SPPM passes, yielding the (live, updated in place) state after each one.

    Settings read: photons_per_pass, progressive_alpha, progressive_radius (0 = automatic),
    progressive_direct, seed, threads, max_specular_depth, photon_max_bounces,
    light_samples. Stops after ``max_passes`` (default settings.progressive_passes) or when
    the caller stops iterating (the Accelerator is released when the generator is closed
    or garbage-collected).
    """
    scene.validate()
    settings = (settings or RenderSettings()).validated()
    max_passes = settings.progressive_passes if max_passes is None else max_passes
    if (not isinstance(max_passes, (int, np.integer)) or isinstance(max_passes, bool)
            or not 1 <= max_passes <= MAX_PASSES):
        raise SettingsError(f'"progressive_passes" must be an integer in [1, {MAX_PASSES}], '
                            f'got {max_passes!r}')
    photons_per_pass = settings.photons_per_pass
    alpha, direct = settings.progressive_alpha, settings.progressive_direct
    prepared = prepare(scene, settings.threads)
    try:
        yield from _passes(prepared, settings, max_passes, photons_per_pass, alpha, direct)
    finally:
        prepared.close()


def _passes(prepared: PreparedScene, settings: RenderSettings, max_passes: int,
            photons_per_pass: int, alpha: float, direct: str) -> Iterator[SPPMState]:
    scene = prepared.scene
    w, h = int(scene.camera.width), int(scene.camera.height)
    r0 = (float(settings.progressive_radius) if settings.progressive_radius > 0
          else initial_radius_for(prepared, photons_per_pass))
    state = SPPMState(width=w, height=h, passes=0, n=np.zeros(w * h),
                      radius=np.full(w * h, r0), tau=np.zeros((w * h, 3)),
                      direct_sum=np.zeros((w * h, 3)), stats={})
    st = state.stats
    st.update({"alpha": float(alpha), "initial_radius": r0, "photons_per_pass": photons_per_pass,
               "photons_emitted": 0, "photons_stored": [], "photons_alive_max": 0,
               "photon_bytes_max": 0, "visible_points": [], "rays_photon": 0, "rays_shadow": 0,
               "time_camera": 0.0, "time_photons": 0.0, "time_gather": 0.0,
               "direct_light": "shadow rays at the visible points; photons for the rest"
               if direct == "shadow_rays" else "photons (standard SPPM: no shadow rays)"})
    has_geometry = scene.mesh.triangle_count > 0
    sources = photon_sources(prepared)
    seed = int(settings.seed)
    max_depth = int(settings.max_specular_depth)
    shadow_rays = None
    if has_geometry and direct == "shadow_rays":
        # The sample index of the shadow rays' random numbers is the pass.
        shadow_rays = direct_light.prepare(settings, prepared, max(1, min(max_passes, MAX_PASSES)))
    for k in range(max_passes):
        t0 = time.perf_counter()
        # Create visible points
        if has_geometry:
            vps = camera_paths.visible_points(prepared, scene.camera, seed, k, max_depth,
                                              state.direct_sum)
            # Direct light by shadow rays (the photons below leave it out)
            if vps.pixel.size and shadow_rays is not None:
                points = direct_light.ShadingPoints(
                    vps.position, vps.ng, vps.ns, -vps.wo, vps.material, vps.eps, vps.weight,
                    vps.albedo, vps.pixel)
                direct_light.shade(shadow_rays, points, vps.pixel,
                                   np.full(vps.pixel.size, k, np.int64), 0, state.direct_sum)
        else:
            vps = None
            if np.any(prepared.world > 0) and scene.world.visible_to_camera:
                state.direct_sum += prepared.world
        t1 = time.perf_counter()
        # Trace photons and accumulate their contributions
        if vps is not None and vps.pixel.size:
            pos, flux, wdir, counters = trace_stored_photons(
                prepared, sources, photons_per_pass, seed=sampling.pass_seed(seed, k),
                max_bounces=int(settings.photon_max_bounces),
                store_rule=STORE_NOT_DIRECT if shadow_rays else STORE_ALL)
            st["rays_photon"] += counters["rays"]
            t2 = time.perf_counter()
            phi, count = gather_photons(vps.position, vps.ng, vps.ns, vps.wo, vps.material,
                                        state.radius[vps.pixel], pos, flux, wdir,
                                        prepared.materials, vps.albedo)
            _update(state, vps, phi, count, alpha)
            stored = int(pos.shape[0])
            st["photon_bytes_max"] = max(st["photon_bytes_max"],
                                         pos.nbytes + flux.nbytes + wdir.nbytes)
            del pos, flux, wdir
        else:
            t2 = time.perf_counter()
            stored = 0
        t3 = time.perf_counter()
        st["photons_emitted"] += photons_per_pass if sources else 0
        st["photons_stored"].append(stored)
        st["photons_alive_max"] = max(st["photons_alive_max"], stored)
        st["visible_points"].append(0 if vps is None else int(vps.pixel.size))
        st["time_camera"] += t1 - t0  # the shadow rays included
        if shadow_rays is not None:
            st["rays_shadow"] = int(shadow_rays.stats["rays_shadow"])
        st["time_photons"] += t2 - t1
        st["time_gather"] += t3 - t2
        state.passes = k + 1
        yield state


def render(scene: Scene, settings: RenderSettings | None = None,
           on_progress: ProgressFn | None = None, on_tile: TileFn | None = None,
           should_stop: StopFn | None = None) -> RenderOutput:
    """Render ``scene`` with ``settings.progressive_passes`` SPPM passes of
    ``settings.photons_per_pass`` photons each (``progressive_passes`` for the others).

    on_tile(k, {"combined": image}) after pass k (1-based) with the image so far, (H, W, 3)
    float32; on_progress(fraction, message) after each pass; should_stop() -> True stops
    after the pass: the output then holds the k passes done and ``cancelled`` is True.
    settings.time_budget > 0 (seconds): ``progressive_passes`` is then an upper bound and
    the render stops (not cancelled) before the pass that would end past the budget,
    judged by the mean pass time so far (at least one pass is made); stats["stopped_by"]
    says why it ended.

    Returns RenderOutput with passes {"combined": (H, W, 3) float32 radiance W/(m^2 sr)}
    and stats: passes, alpha, initial_radius, radius_min / radius_mean / radius_max
    (metres, final), photons_per_pass, photons_emitted, photons_stored (list, one count
    per pass), photons_alive_max (most photons held at once), photon_bytes_max,
    visible_points (list per pass), rays_photon, rays_shadow, time_camera / time_photons /
    time_gather / time_total (s). Raises SettingsError and SceneError on bad input.
    """
    settings = (settings or RenderSettings()).validated()
    passes = settings.progressive_passes
    time_budget = float(settings.time_budget) or None
    t_start = time.perf_counter()
    cancelled = False
    stopped_by = "passes"
    state = None
    runner = progressive_passes(scene, settings, passes)
    try:
        for state in runner:
            k = state.passes
            if on_tile is not None:
                on_tile(k, {"combined": state.radiance()})
            if on_progress is not None:
                on_progress(k / passes, f"Pass {k}/{passes}")
            if should_stop is not None and should_stop():
                cancelled = k < passes
                stopped_by = "cancelled" if cancelled else "passes"
                break
            elapsed = time.perf_counter() - t_start
            if time_budget is not None and k < passes and elapsed * (k + 1) / k > time_budget:
                stopped_by = "time_budget"
                break
    finally:
        runner.close()
    image = state.radiance()
    stats = dict(state.stats)
    stats.update({"passes": state.passes, "stopped_by": stopped_by,
                  "time_budget": time_budget, "radius_min": float(state.radius.min()),
                  "radius_mean": float(state.radius.mean()),
                  "radius_max": float(state.radius.max()),
                  "time_total": time.perf_counter() - t_start})
    return RenderOutput(passes={"combined": image}, stats=stats, cancelled=cancelled)

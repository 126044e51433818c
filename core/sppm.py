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
Both converge to the same image (tests/core/test_sppm.py checks the split against the
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
pass cut-outs stochastically like the integrator's (core/textures.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterator

import numba
import numpy as np
from numba import njit, prange

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from . import bsdf, camera, geometry, lights, sampling, scatter, tracing
from . import direct as direct_light
from .accel import Accelerator, default_threads
from .integrator import RenderOutput
from .scene import Scene
from .settings import RenderSettings, SettingsError

ProgressFn = Callable[[float, str], bool]
PassFn = Callable[[int, np.ndarray], None]

INITIAL_PHOTONS = 16.0
"""K0 of the automatic initial radius: photons expected in a disc on a uniformly lit surface."""
MAX_PASSES = 1 << 20
MAX_RING = 4
"""Largest number of cell rings a visible point scans in the photon grid (cells >= R_max / 4)."""
MAX_PHOTONS_PER_PASS = 1 << 26

# Random dimensions of the camera paths (stream indices; purposes from core/sampling.py).
_DIM_JITTER = sampling.stream(sampling.PIXEL_JITTER, 7)
_DIM_LENS = sampling.stream(sampling.PIXEL_JITTER, 8)


def _dim_lobe(depth: int) -> int:
    return sampling.stream(sampling.SPECULAR_CHOICE, depth, 7)


def pass_seed(seed: int, k: int) -> int:
    """The photon seed of pass k (0-based): a splitmix64 hash of (seed, k), an int < 2^63."""
    x = (int(seed) * 0x9E3779B97F4A7C15 + (int(k) + 1) * 0xD1B54A32D192ED03) & (2**64 - 1)
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & (2**64 - 1)
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & (2**64 - 1)
    return (x ^ (x >> 31)) >> 1


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
def _path_kernel(pos, d, ng, ns, mat, eps, thr, u_vp, u_lobe, u_pick, albedo, specular, alpha,
                 transmission, ior, vp, new_o, new_d, new_thr, go_on, transmitted):
    """At each hit: stop at the diffuse lobe (vp) or follow one delta lobe (go_on).
    albedo (N, 3): the (textured) diffuse albedo at each hit.

    ng, ns: normals as computed from the winding (flipped here to face the ray). thr is
    divided by the probability of the branch taken; new_thr is the visible point's weight
    when vp, the next ray's throughput when go_on."""
    for i in prange(d.shape[0]):
        m = mat[i]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        entering = dx * ng[i, 0] + dy * ng[i, 1] + dz * ng[i, 2] < 0.0
        sg = 1.0 if entering else -1.0
        gx, gy, gz = sg * ng[i, 0], sg * ng[i, 1], sg * ng[i, 2]
        sx, sy, sz = sg * ns[i, 0], sg * ns[i, 1], sg * ns[i, 2]
        ng[i, 0], ng[i, 1], ng[i, 2] = gx, gy, gz
        ns[i, 0], ns[i, 1], ns[i, 2] = sx, sy, sz
        kd = (albedo[i, 0] + albedo[i, 1] + albedo[i, 2]) / 3.0
        mirror = alpha[m] * alpha[m] <= bsdf.SINGULAR_ALPHA2
        kdel = (transmission[m, 0] + transmission[m, 1] + transmission[m, 2]) / 3.0
        if mirror:
            kdel += (specular[m, 0] + specular[m, 1] + specular[m, 2]) / 3.0
        vp[i] = False
        go_on[i] = False
        transmitted[i] = False
        if kd + kdel <= 0.0:
            continue
        p = kd / (kd + kdel)
        if u_vp[i] < p:
            vp[i] = True
            for c in range(3):
                new_thr[i, c] = thr[i, c] / p
            continue
        ox, oy, oz, w0, w1, w2, tr, ok = bsdf.sample_delta(
            specular[m, 0], specular[m, 1], specular[m, 2], alpha[m],
            transmission[m, 0], transmission[m, 1], transmission[m, 2], ior[m],
            dx, dy, dz, sx, sy, sz, gx, gy, gz, entering, u_lobe[i], u_pick[i])
        q = 1.0 - p
        t0, t1, t2 = thr[i, 0] * w0 / q, thr[i, 1] * w1 / q, thr[i, 2] * w2 / q
        if not ok or not (t0 > 0.0 or t1 > 0.0 or t2 > 0.0):
            continue
        side = -eps[i] if tr else eps[i]
        new_o[i, 0] = pos[i, 0] + gx * side
        new_o[i, 1] = pos[i, 1] + gy * side
        new_o[i, 2] = pos[i, 2] + gz * side
        new_d[i, 0], new_d[i, 1], new_d[i, 2] = ox, oy, oz
        new_thr[i, 0], new_thr[i, 1], new_thr[i, 2] = t0, t1, t2
        go_on[i] = True
        transmitted[i] = tr


@njit(cache=True, parallel=True, error_model="numpy")
def _jitter_kernel(seed, k, dim, out):
    """Pixel jitter of pass k: point k of an Owen-scrambled 2D Sobol sequence per pixel, in
    sequence order, so the first k passes are stratified whatever k (progressive)."""
    i = np.uint64(k) & np.uint64(0xFFFFFFFF)
    for p in prange(out.shape[0]):
        pat = sampling.pattern(seed, p, dim)
        x = sampling._owen32(sampling._reverse32(i), (pat >> np.uint64(32)) & np.uint64(0xFFFFFFFF))
        y = sampling._owen32(sampling._sobol1(i), sampling._mix64(pat) & np.uint64(0xFFFFFFFF))
        out[p, 0] = np.float64(x) * 2.0 ** -32
        out[p, 1] = np.float64(y) * 2.0 ** -32


@njit(cache=True, error_model="numpy")
def _cell_hash(ix, iy, iz, mask):
    h = (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791)
    return h & mask


@njit(cache=True, error_model="numpy")
def _grid_kernel(pos, lo, inv_h, mask, cells, start, order):
    """Counting sort of the photons by hashed cell: bucket b holds order[start[b]:start[b+1]]."""
    n = pos.shape[0]
    buckets = np.empty(n, np.int64)
    for c in range(start.shape[0]):
        start[c] = 0
    for i in range(n):
        ix = np.int64(np.floor((pos[i, 0] - lo[0]) * inv_h))
        iy = np.int64(np.floor((pos[i, 1] - lo[1]) * inv_h))
        iz = np.int64(np.floor((pos[i, 2] - lo[2]) * inv_h))
        cells[i, 0], cells[i, 1], cells[i, 2] = ix, iy, iz
        b = _cell_hash(ix, iy, iz, mask)
        buckets[i] = b
        start[b + 1] += 1
    for c in range(1, start.shape[0]):
        start[c] += start[c - 1]
    fill = start[:-1].copy()
    for i in range(n):
        b = buckets[i]
        order[fill[b]] = i
        fill[b] += 1


@njit(cache=True, parallel=True, error_model="numpy")
def _gather_kernel(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, radius, ph_pos, ph_flux, ph_dir, cells,
                   start, order, lo, inv_h, mask, vp_albedo, specular, alpha, phi, count):
    """phi[i] = sum f(wo, w_p) Phi_p and count[i] = M over this pass's photons within
    radius[i] of visible point i on its visible side."""
    for i in prange(vp_pos.shape[0]):
        px, py, pz = vp_pos[i, 0], vp_pos[i, 1], vp_pos[i, 2]
        r2 = radius[i] * radius[i]
        cx = np.int64(np.floor((px - lo[0]) * inv_h))
        cy = np.int64(np.floor((py - lo[1]) * inv_h))
        cz = np.int64(np.floor((pz - lo[2]) * inv_h))
        m = vp_mat[i]
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        c = 0
        ring = np.int64(np.ceil(radius[i] * inv_h))
        for ox in range(-ring, ring + 1):
            for oy in range(-ring, ring + 1):
                for oz in range(-ring, ring + 1):
                    qx, qy, qz = cx + ox, cy + oy, cz + oz
                    b = _cell_hash(qx, qy, qz, mask)
                    for j in range(start[b], start[b + 1]):
                        k = order[j]
                        # Another cell hashed into the same bucket: skip (counted there).
                        if cells[k, 0] != qx or cells[k, 1] != qy or cells[k, 2] != qz:
                            continue
                        ex = ph_pos[k, 0] - px
                        ey = ph_pos[k, 1] - py
                        ez = ph_pos[k, 2] - pz
                        if ex * ex + ey * ey + ez * ez > r2:
                            continue
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
    lo = ph_pos.min(axis=0).astype(np.float64) - h
    size = 1 << max(4, int(2 * ph_pos.shape[0] - 1).bit_length())
    cells = np.empty((ph_pos.shape[0], 3), np.int64)
    start = np.empty(size + 1, np.int64)
    order = np.empty(ph_pos.shape[0], np.int64)
    _grid_kernel(ph_pos, lo, 1.0 / h, np.int64(size - 1), cells, start, order)
    _gather_kernel(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, np.ascontiguousarray(radius, np.float64),
                   ph_pos, ph_flux, ph_dir, cells, start, order, lo, 1.0 / h, np.int64(size - 1),
                   np.ascontiguousarray(vp_albedo, np.float64), mats["specular"], mats["alpha"],
                   phi, count)
    return phi, count


# --- one pass -------------------------------------------------------------------------------

@dataclass
class _Context:
    scene: Scene
    setup: object            # tracing._Setup
    accel: Accelerator
    sources: list
    seed: int
    max_depth: int
    max_bounces: int
    direct: object = None    # direct.DirectLighting: shadow rays at the visible points


@dataclass
class VisiblePoints:
    """One pass's visible points (V of them), float64: pixel (V,) int64, position (V, 3)
    metres, ng / ns (V, 3) unit normals facing the viewer, wo (V, 3) unit towards the
    viewer, material (V,) int32, weight (V, 3) path throughput, albedo (V, 3) the
    diffuse albedo there (textured), eps (V,) metres, the ray offset there."""

    pixel: np.ndarray
    position: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    wo: np.ndarray
    material: np.ndarray
    weight: np.ndarray
    albedo: np.ndarray
    eps: np.ndarray


_CUTOUT_CHOICE = 19  # random purpose of the pass-through choices (as integrator's)


def _intersect(ctx: _Context, origins, dirs, tmax, rows, pixel, sample, depth):
    """Nearest hits of the camera paths, passing cut-outs stochastically."""
    def uniforms(index, layer):
        r = rows[index]
        return sampling.uniform(ctx.seed, pixel[r], sample[r],
                                sampling.stream(_CUTOUT_CHOICE, depth, layer, 7))
    setup = ctx.setup
    return setup.surfaces.intersect(ctx.accel, setup.tri_v, setup.tri_n, setup.extent,
                                    origins, dirs, tmax, uniforms)


def _camera_pass(ctx: _Context, k: int, direct: np.ndarray) -> VisiblePoints:
    """Step 1 for pass k: trace the camera paths, add the radiance seen to direct (P, 3)."""
    cam = ctx.scene.camera
    setup, mats, ls = ctx.setup, ctx.setup.mats, ctx.setup.light_set
    n = int(cam.width) * int(cam.height)
    pixel = np.arange(n, dtype=np.int64)
    sample = np.full(n, k, np.int64)
    jitter = np.empty((n, 2))
    _jitter_kernel(np.int64(ctx.seed), np.int64(k), np.int64(_DIM_JITTER), jitter)
    lens = None
    if camera.has_aperture(cam):  # depth of field: a point on the aperture, per pass
        lens = np.empty((n, 2))
        _jitter_kernel(np.int64(ctx.seed), np.int64(k), np.int64(_DIM_LENS), lens)
    rays = camera.generate_rays(cam, pixel, jitter, lens)
    origins, dirs, tmax = rays.origins, rays.directions, rays.tmax
    rows = pixel
    thr = np.ones((n, 3))
    transmitted = np.zeros(n, bool)
    world = setup.world
    shows = np.any(ls.radiance > 0, axis=1)
    out = []
    for depth in range(ctx.max_depth + 1):
        if rows.shape[0] == 0:
            break
        first = depth == 0
        hits = _intersect(ctx, origins, dirs, tmax, rows, pixel, sample, depth)
        hit = hits.prim >= 0
        # Lights seen along the rays, in front of the geometry
        visible = ls.visible_camera if first else ls.visible_glossy | ls.visible_transmission
        if np.any(visible & shows):
            geo_t = np.where(hit, hits.t.astype(np.float64), np.inf)
            light_t = np.full(rows.shape[0], np.inf)
            light_l = np.zeros((rows.shape[0], 3))
            groups = [(slice(None), ls.visible_camera)] if first else [
                (np.flatnonzero(transmitted), ls.visible_transmission),
                (np.flatnonzero(~transmitted), ls.visible_glossy)]
            for sel, vis in groups:
                light_t[sel], light_l[sel] = lights.intersect_lights(ls, vis, origins[sel],
                                                                     dirs[sel], geo_t[sel])
            seen = light_t < geo_t
            shown = seen | ~hit
            direct[rows[shown]] += thr[shown] * light_l[shown]
            hit &= ~seen
            miss = ~seen & (hits.prim < 0)
        else:
            miss = ~hit
        # Rays that escape see the world
        if np.any(world > 0) and np.any(miss) and (not first or ctx.scene.world.visible_to_camera):
            direct[rows[miss]] += thr[miss] * world
        h = np.flatnonzero(hit)
        if h.size == 0:
            break
        rows, thr, d, transmitted = rows[h], thr[h], dirs[h], transmitted[h]
        sp = geometry.surface_points(setup.tri_v, setup.tri_n, setup.tri_mat, hits.prim[h],
                                     hits.u[h], hits.v[h], d, setup.extent)
        # Emission seen (two-sided, like Cycles' emission closure)
        direct[rows] += thr * mats["emission"][sp.material]
        albedo = setup.surfaces.albedo(hits.prim[h], hits.u[h], hits.v[h], sp.material)
        m = len(rows)
        pix, smp = pixel[rows], sample[rows]
        u_vp = sampling.uniform(ctx.seed, pix, smp, _dim_lobe(depth))
        u_lobe, u_pick = sampling.uniform2(ctx.seed, pix, smp, _dim_lobe(depth) + 1)
        ng, ns = sp.geometric_normal.copy(), sp.shading_normal.copy()
        vp, go_on, new_tr = np.empty(m, bool), np.empty(m, bool), np.empty(m, bool)
        new_o, new_d, new_thr = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        _path_kernel(sp.position, d, ng, ns, sp.material, sp.eps, thr, u_vp, u_lobe, u_pick,
                     albedo, mats["specular"], mats["alpha"], mats["transmission"],
                     mats["ior"], vp, new_o, new_d, new_thr, go_on, new_tr)
        # Visible points: the first diffuse lobe on the path
        s = np.flatnonzero(vp)
        if s.size:
            out.append((rows[s], sp.position[s], ng[s], ns[s], -d[s], sp.material[s], new_thr[s],
                        albedo[s], sp.eps[s]))
        if depth == ctx.max_depth:
            break
        g = np.flatnonzero(go_on)
        rows, origins, dirs = rows[g], new_o[g], new_d[g]
        thr, transmitted, tmax = new_thr[g], new_tr[g], None
    if not out:
        z3 = np.zeros((0, 3))
        return VisiblePoints(np.zeros(0, np.int64), z3, z3, z3, z3, np.zeros(0, np.int32), z3, z3,
                             np.zeros(0))
    cols = [np.concatenate(c) for c in zip(*out)]
    return VisiblePoints(*[np.ascontiguousarray(c) for c in cols])


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

def diffuse_area(scene: Scene) -> float:
    """Total area (m^2) of the triangles whose material has a diffuse lobe."""
    mesh = scene.mesh
    if mesh.triangle_count == 0:
        return 0.0
    tv = mesh.triangle_vertices().astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0]), axis=1)
    diffuse = np.any(np.asarray(scene.materials.diffuse) > 0, axis=1)
    return float(area[diffuse[mesh.material_index]].sum())


def initial_radius_for(scene: Scene, photons_per_pass: int) -> float:
    """The automatic R_0 (metres) of the module doc; a scene with no diffuse area gets
    1e-3 of its size (no photon can be gathered there anyway)."""
    lo, hi = scene.bounds()
    extent = geometry.scene_extent(lo, hi)
    area = diffuse_area(scene)
    if area <= 0.0 or photons_per_pass <= 0:
        return max(1e-3 * extent, 1e-30)
    r = np.sqrt(INITIAL_PHOTONS * area / (np.pi * photons_per_pass))
    return float(min(r, 0.25 * extent)) if extent > 0 else float(r)


def _check(passes, photons_per_pass, alpha, initial_radius):
    for name, v, hi in (("passes", passes, MAX_PASSES),
                        ("photons_per_pass", photons_per_pass, MAX_PHOTONS_PER_PASS)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not 1 <= v <= hi:
            raise SettingsError(f'"{name}" must be an integer in [1, {hi}], got {v!r}')
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not 0.0 < alpha < 1.0:
        raise SettingsError(f'"alpha" must be a number in (0, 1), got {alpha!r}')
    if initial_radius is not None:
        ok = isinstance(initial_radius, (int, float)) and not isinstance(initial_radius, bool)
        if not ok or not (0.0 < float(initial_radius) < np.inf):
            raise SettingsError(f'"initial_radius" must be a finite number > 0 (metres) or None, '
                                f'got {initial_radius!r}')


DIRECT_MODES = ("shadow_rays", "photons")
"""How SPPM gets direct light: shadow rays (the default, the module doc) or photons
(standard SPPM, kept to check the hybrid against)."""


def progressive_passes(scene: Scene, settings: RenderSettings, photons_per_pass: int, *,
                       alpha: float = 2.0 / 3.0, initial_radius: float | None = None,
                       max_passes: int = MAX_PASSES,
                       direct: str = "shadow_rays") -> Iterator[SPPMState]:
    """Run SPPM passes, yielding the (live, updated in place) state after each one.

    Stops after ``max_passes`` or when the caller stops iterating (the Accelerator is
    closed when the generator is closed or garbage-collected). ``direct``: one of
    DIRECT_MODES.
    """
    _check(max_passes, photons_per_pass, alpha, initial_radius)
    if direct not in DIRECT_MODES:
        raise SettingsError(f'"direct" must be one of {DIRECT_MODES}, got {direct!r}')
    scene.validate()
    settings = (settings or RenderSettings()).validated()
    threads = default_threads(settings.threads)
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    setup = tracing.prepare(scene)
    w, h = int(scene.camera.width), int(scene.camera.height)
    r0 = float(initial_radius) if initial_radius is not None else initial_radius_for(
        scene, photons_per_pass)
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
    accel = Accelerator(setup.tri_v, threads=threads) if scene.mesh.triangle_count else None
    ctx = _Context(scene=scene, setup=setup, accel=accel,
                   sources=tracing.photon_sources(setup), seed=int(settings.seed),
                   max_depth=int(settings.max_specular_depth),
                   max_bounces=int(settings.photon_max_bounces))
    if accel is not None and direct == "shadow_rays":
        # The sample index of the shadow rays' random numbers is the pass.
        ctx.direct = direct_light.prepare(
            settings.with_values(samples=max(1, min(max_passes, MAX_PASSES))), accel,
            light_set=setup.light_set, emissive=setup.emissive, materials=setup.mats,
            world=setup.world, extent=setup.extent, surfaces=setup.surfaces,
            tri_vertices=setup.tri_v, tri_normals=setup.tri_n)
    try:
        for k in range(max_passes):
            t0 = time.perf_counter()
            # Create visible points
            if accel is not None:
                vps = _camera_pass(ctx, k, state.direct_sum)
                # Direct light by shadow rays (the photons below leave it out)
                if vps.pixel.size and ctx.direct is not None:
                    hit = {"pos": vps.position, "ngf": vps.ng, "nsf": vps.ns, "d": -vps.wo,
                           "mat": vps.material, "eps": vps.eps, "thr": vps.weight,
                           "albedo": vps.albedo, "rows": vps.pixel}
                    direct_light.shade(ctx.direct, hit, vps.pixel,
                                       np.full(vps.pixel.size, k, np.int64), 0,
                                       state.direct_sum)
            else:
                vps = None
                if np.any(setup.world > 0) and scene.world.visible_to_camera:
                    state.direct_sum += setup.world
            t1 = time.perf_counter()
            # Trace photons and accumulate their contributions
            if vps is not None and vps.pixel.size:
                pos, flux, wdir, counters = tracing.trace_stored_photons(
                    setup, accel, ctx.sources, photons_per_pass, seed=pass_seed(ctx.seed, k),
                    max_bounces=ctx.max_bounces,
                    store_rule=scatter.STORE_NOT_DIRECT if ctx.direct else scatter.STORE_ALL)
                st["rays_photon"] += counters["rays"]
                t2 = time.perf_counter()
                phi, count = gather_photons(vps.position, vps.ng, vps.ns, vps.wo, vps.material,
                                            state.radius[vps.pixel], pos, flux, wdir, setup.mats,
                                            vps.albedo)
                _update(state, vps, phi, count, alpha)
                stored = int(pos.shape[0])
                st["photon_bytes_max"] = max(st["photon_bytes_max"],
                                             pos.nbytes + flux.nbytes + wdir.nbytes)
                del pos, flux, wdir
            else:
                t2 = time.perf_counter()
                stored = 0
            t3 = time.perf_counter()
            st["photons_emitted"] += photons_per_pass if ctx.sources else 0
            st["photons_stored"].append(stored)
            st["photons_alive_max"] = max(st["photons_alive_max"], stored)
            st["visible_points"].append(0 if vps is None else int(vps.pixel.size))
            st["time_camera"] += t1 - t0  # the shadow rays included
            if ctx.direct is not None:
                st["rays_shadow"] = int(ctx.direct.stats["rays_shadow"])
            st["time_photons"] += t2 - t1
            st["time_gather"] += t3 - t2
            state.passes = k + 1
            yield state
    finally:
        if accel is not None:
            accel.close()


def render_progressive(scene: Scene, settings: RenderSettings | None, passes: int,
                       photons_per_pass: int, *, alpha: float = 2.0 / 3.0,
                       initial_radius: float | None = None, progress: ProgressFn | None = None,
                       on_pass: PassFn | None = None,
                       time_budget: float | None = None,
                       direct: str = "shadow_rays") -> RenderOutput:
    """Render ``scene`` with ``passes`` SPPM passes of ``photons_per_pass`` photons each.

    alpha in (0, 1): the fraction of new photons kept per pass (radius shrink rate);
    initial_radius: metres, None = ``initial_radius_for`` (scale-invariant).
    on_pass(k, combined (H, W, 3) float32) is called after pass k (1-based) with the
    image so far; progress(fraction, message) is called after each pass, and returning
    True stops: the output then holds the k passes done and ``cancelled`` is True.
    time_budget: seconds, or None; ``passes`` is then an upper bound and the render stops
    (not cancelled) before the pass that would end past the budget, judged by the mean
    pass time so far (at least one pass is made); stats["stopped_by"] says why it ended.
    settings used: seed, threads, max_specular_depth, photon_max_bounces, light_samples.
    direct: "shadow_rays" or "photons" (DIRECT_MODES).

    Returns RenderOutput with passes {"combined": (H, W, 3) float32 radiance W/(m^2 sr)}
    and stats: passes, alpha, initial_radius, radius_min / radius_mean / radius_max
    (metres, final), photons_per_pass, photons_emitted, photons_stored (list, one count
    per pass), photons_alive_max (most photons held at once), photon_bytes_max,
    visible_points (list per pass), rays_photon, rays_shadow, time_camera / time_photons /
    time_gather / time_total (s).
    Raises SettingsError for bad passes / photons_per_pass / alpha / initial_radius and
    SceneError for a bad scene.
    """
    _check(passes, photons_per_pass, alpha, initial_radius)
    if time_budget is not None and (isinstance(time_budget, bool)
                                    or not isinstance(time_budget, (int, float))
                                    or not 0.0 < float(time_budget) < np.inf):
        raise SettingsError(f'"time_budget" must be a finite number of seconds > 0 or None, '
                            f'got {time_budget!r}')
    t_start = time.perf_counter()
    cancelled = False
    stopped_by = "passes"
    state = None
    runner = progressive_passes(scene, settings, photons_per_pass, alpha=alpha,
                                initial_radius=initial_radius, max_passes=passes, direct=direct)
    try:
        for state in runner:
            k = state.passes
            if on_pass is not None:
                on_pass(k, state.radiance())
            if progress is not None and progress(k / passes, f"Pass {k}/{passes}"):
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

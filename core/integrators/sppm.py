"""Progressive photon mapping in its probabilistic, pass-independent form (Knaus & Zwicker
2011, "Progressive photon mapping: a probabilistic approach"), with stochastic visible
points (SPPM): a render whose error goes to zero as passes accumulate, with the memory of
one photon pass, and whose passes can run in any order, anywhere.

Pass k = 0, 1, 2, ... (0-based; K&Z's pass i = k + 1) is a function of (scene, settings,
k) alone:

1. Visible points. One jittered camera ray per pixel (point k of a per-pixel Owen-scrambled
   Sobol sequence) follows mirrors and glass (``closure.sample_delta``, at the path's
   wavelength once it met a dispersive surface) to the first surface with a diffuse lobe:
   the pixel's visible point x_k, with path weight beta_k (the throughput, lobe value /
   probability). Emitters, visible lights and the background seen along the way are the
   pass's directly seen radiance D_k. At a material with both a diffuse and a delta lobe
   the path stops at the non-delta lobes with probability 1 - s, s the delta lobes' share
   of the closures' sample weights, and beta is divided by 1 - s (or by s when it goes
   on), so there is one visible point per pixel and pass. In a medium every camera
   segment adds its Volume Direct (shadow rays), beam estimate (this pass's volume
   photons, radii shrinking as r_k / r_1) and emission, and attenuates what lies behind
   (core/integrators/volume.py; docs/volumes.md).
   Direct light at the visible point comes from shadow rays to every light, emissive
   triangle and the world (``direct.shade``, the photon-map integrator's own estimator,
   ``light_samples`` per light and pass, sample index k of a set of
   ``progressive_passes``), added to D_k times beta_k.
1b. Narrow glossy lobes (issue 13). A visible point whose closures have a rough glossy
   lobe narrower than NARROW_ALPHA (GGX alpha; Roughness 0.45: ``narrow_points``) splits:
   its diffuse-like part gathers photons as below (f = f_d), and its glossy part goes on
   as the camera path: one direction sampled from the closures
   (``camera_paths.follow_bsdf``, the sampler photons scatter by: weight f_glossy |cos| /
   pdf, Russian roulette on the glossy share; a delta lobe sampled there ends it, the
   point standing for the non-singular lobes) to the next diffuse lobe, where a new
   visible point is made with weight beta_k times that (``camera_paths.visible_points``
   with a ``PathStart``). The split point's direct light weighs its glossy part by the
   power heuristic against that sampling, and the lights, emitters and world the path's
   first segment meets take the complementary weight; the new point gets direct light
   and photons of its own. So every photon is counted once: by the split point's diffuse
   part, or by a later point along the glossy path. Split points of the continuation
   split again, up to MAX_SPLITS; the last ones weigh photons by their whole closure.
   Only with shadow-ray direct light: in standard SPPM (``progressive_direct="photons"``)
   a point light's glossy reflection is carried by the photons at the point alone (no
   path can hit it), so there the points gather with their whole closure as before.
   Why: a lobe of alpha 0.01 (Roughness 0.1) holds about 4 alpha^2 of the photons of a
   gather disc, one in 200 passes of K0 = 12; its estimate was a few bright spikes (the
   artist scene's glossy floor, docs/sppm.md). A sampled direction finds the
   surface behind the lobe at once, where the photons are diffuse-weighted and smooth.
2. Photons. ``photons_per_pass`` photons are traced with the global map's rules
   (``tracing.trace_stored_photons``), stored at every diffuse hit except the first hit
   of a photon straight from its source (``scatter.STORE_NOT_DIRECT``: that light is the
   shadow rays'), so caustics (light -> specular -> diffuse) and indirect light come from
   photons; photon seed ``sampling.pass_seed(seed, k)``. Each stored photon p has flux
   Phi_p (watts, already divided by photons_per_pass) and incident direction w_p.
3. Gathering with the pass's radius from a global schedule (alpha in (0, 1)):
       r_k^2 = r_1^2 prod_{j=1}^{k} (j + alpha) / (j + 1)        (~ k^(alpha - 1))
   For every visible point, over the photons of this pass with |x_p - x| <= r_k on its
   visible side (n_g . w_p > 0, the front-side test; n_g faces the camera ray):
       Phi = sum_p f(w_o, w_p) Phi_p        (f = diffuse / pi + wide glossy lobes;
                                              split points: the diffuse part alone)
   (points whose diffuse-like lobes are not Lambert: f from their closures, photons of
   both sides counting; ``_gather_kernel``)
   and the pass's estimate is L_k = D_k + beta_k Phi / (pi r_k^2).
4. The image after n passes is the plain average: L = (1/n) sum_k L_k.

The per-pixel statistics of Hachisuka's SPPM (N, R, tau updated pass after pass) made
every pass depend on all the ones before; here the only state is a sum, so passes
[a, b) can be rendered anywhere (``PassRenderer.render_block``, a ``PassSums``) and
merged (``ImageSum``). The sum is made in a fixed order, so the image is the same bit for
bit wherever its passes ran: passes are grouped into blocks of ``progressive_block``
(blocks [0, B), [B, 2B), ..., the last one cut at the pass count); a block is summed from
zero in pass order (float64) and the blocks are added to the image sum in block order.
float64 addition is not associative, so this order is part of the definition of the
image; every order-dependent step is fixed by it, and every pass's own numbers come from
counter-based random numbers keyed by k.

Direct light by shadow rays, everything else by photons (a hybrid; standard SPPM counts
direct light by photons too, ``progressive_direct="photons"``): directly lit diffuse
surfaces are then exact in expectation from the first pass on, without the blotches of a
photon estimate; the photon estimate is left with the paths only photons find well
(caustics) and the smooth indirect light.

First-pass radius (when not given): r_1 = sqrt(K0 A_d / (pi photons_per_pass)) with A_d
the area of the triangles with a diffuse lobe and K0 = INITIAL_PHOTONS: about K0 photons
per disc if every photon stored once on a uniformly lit surface. It scales with the
scene (a scene scaled by s gets s r_1), so the image is scale-invariant.

Neighbour search: per pass, a hash grid over the pass's photons with cells as wide as the
pass's radius; each visible point scans the neighbouring cells (numba, parallel over
visible points, so no write races; exact: every photon within r_k is found once).
Memory: one pass's photons plus two (P, 3) float64 sums, whatever the number of passes.

Glossy-only surfaces (no diffuse lobe: metals) store no photons; camera paths go on
through them by BSDF sampling (``camera_paths.visible_points``).
Textures: the visible points carry the textured diffuse albedo of their hit; camera paths
pass cut-outs stochastically like the integrator's (core/materials/textures.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..materials import bsdf, closure, microfacet
from ..media import density
from ..passes import ProgressFn, RenderOutput, StopFn, TileFn
from ..photons.hash_grid import HashGrid, within
from ..photons.store import STORE_ALL, STORE_NOT_DIRECT
from ..photons.beam import VolumePhotonMap, photon_radii
from ..photons.estimate import BsdfHits
from ..photons.tracing import MIN_VOLUME_RADIUS, photon_sources, trace_stored_photons
from ..prepared import PreparedScene, prepare
from ..scene import camera
from ..scene.contract import Scene
from ..settings import (MAX_PHOTONS_PER_PASS, MAX_PROGRESSIVE_PASSES as MAX_PASSES,  # noqa: F401
                        RenderSettings, SettingsError)
from . import camera_paths
from . import denoise_features
from . import direct as direct_light
from . import volume

INITIAL_PHOTONS = 12.0
"""K0 of the automatic first-pass radius: photons expected in a disc on a uniformly lit
surface."""
MAX_RING = 4
"""Largest number of cell rings a visible point scans in the photon grid."""
NARROW_PHOTONS = 2.0
"""A glossy lobe is narrow (its visible points split, module doc step 1b) when fewer than
this many of the K0 = INITIAL_PHOTONS photons of a first-pass gather disc would arrive
inside it."""
NARROW_ALPHA = float(np.sqrt(NARROW_PHOTONS / (4.0 * INITIAL_PHOTONS)))
"""The GGX alpha below which a lobe is narrow (0.204: Roughness 0.45). Photons reach a disc
about cosine-distributed; half of a GGX lobe's mass lies within 2 alpha of its mirror
direction, a cone holding a share sin^2(2 alpha) ~ 4 alpha^2 of cosine-distributed
directions, so 4 alpha^2 K0 photons of a disc land in it: 2 at alpha 0.204. Below that the
lobe's photon estimate is a handful of spikes per pass (Roughness 0.1, alpha 0.01: one
photon in 200 passes), whereas a sampled direction finds the light behind it at once."""
MAX_SPLITS = 3
"""Camera-path continuations a pass follows from split points (a floor seen in a glossy
floor...); the points of the last one weigh photons by their whole closure (no energy
is dropped, only the noise of the old estimate is left there)."""

DIRECT_MODES = ("shadow_rays", "photons")
"""How the progressive mode gets direct light (``RenderSettings.progressive_direct``):
shadow rays (the default, the module doc) or photons (standard SPPM, kept to check the
hybrid against)."""


# --- kernels --------------------------------------------------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _gather_kernel(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, radius, ph_pos, ph_flux, ph_dir, cells,
                   start, order, lo, inv_h, mask, vp_albedo, specular, alpha, tab, vp_row,
                   vp_texel, vp_tan, vp_front, vp_lam, vp_bsdf, vp_split, phi, count):
    """phi[i] = sum f(wo, w_p) Phi_p and count[i] = M over this pass's photons within
    radius[i] of visible point i. Lambert points (vp_bsdf[i] False): photons of the visible
    side (n_g . w_p > 0), f = albedo / pi (+ the legacy table's glossy lobe). Points whose
    diffuse-like lobes are not Lambert (Oren-Nayar, sheen, Translucent) or sit beside a
    rough lobe (vp_bsdf[i] True): f is the closures' f_d + f_glossy at the photon's direction (``closure.hit_lobes`` / ``parts_at``, row
    vp_row[i] of tab, texel, tangent, front, wavelength lam nm), photons of both sides
    counting (a lobe that transmits sees the far side's), as
    ``estimate._bsdf_estimate_kernel`` weighs the photon-mapping integrator's photons.
    Split points (vp_split[i], ``narrow_points``): f is the closures' diffuse-like part
    f_d alone, their glossy part being the camera path's that goes on from there."""
    for i in prange(vp_pos.shape[0]):
        px, py, pz = vp_pos[i, 0], vp_pos[i, 1], vp_pos[i, 2]
        r2 = radius[i] * radius[i]
        m = vp_mat[i]
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        c = 0
        use_bsdf = vp_bsdf[i] or vp_split[i]
        glossy = 0.0 if vp_split[i] else 1.0  # split: the glossy part is the path's
        gx, gy, gz = vp_ng[i, 0], vp_ng[i, 1], vp_ng[i, 2]
        if use_bsdf:
            L, F = closure.hit_lobes(tab, vp_row[i], vp_texel[i, 0], vp_texel[i, 1],
                                     vp_texel[i, 2], vp_wo[i, 0], vp_wo[i, 1], vp_wo[i, 2],
                                     vp_ns[i, 0], vp_ns[i, 1], vp_ns[i, 2], gx, gy, gz,
                                     vp_tan[i, 0], vp_tan[i, 1], vp_tan[i, 2], vp_front[i],
                                     vp_lam[i])
        else:
            L, F = np.empty((0, closure.NL)), np.empty(12)
        ring = np.int64(np.ceil(radius[i] * inv_h))
        for k in within(px, py, pz, r2, ring, ph_pos, lo, inv_h, mask, cells, start, order):
            wx, wy, wz = ph_dir[k, 0], ph_dir[k, 1], ph_dir[k, 2]
            if use_bsdf:
                c += 1
                d0, d1, d2, g0, g1, g2, _ = closure.parts_at(L, F, wx, wy, wz, gx, gy, gz,
                                                             True, False)
                a0 += (d0 + glossy * g0) * ph_flux[k, 0]
                a1 += (d1 + glossy * g1) * ph_flux[k, 1]
                a2 += (d2 + glossy * g2) * ph_flux[k, 2]
                continue
            # Front-side test: the photon arrived on the side the camera sees.
            if gx * wx + gy * wy + gz * wz <= 0.0:
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


@njit(cache=True, parallel=True, error_model="numpy")
def _narrow_kernel(tab, rows, texel, wo, ns, ng, tan, front, lam, alpha_max, out):
    """out[i]: point i's closures (row rows[i] of tab) have a rough (non-singular)
    microfacet lobe of weight > 0 whose alpha sqrt(ax ay) is below alpha_max."""
    for i in prange(rows.shape[0]):
        L, _ = closure.hit_lobes(tab, rows[i], texel[i, 0], texel[i, 1], texel[i, 2],
                                 wo[i, 0], wo[i, 1], wo[i, 2], ns[i, 0], ns[i, 1], ns[i, 2],
                                 ng[i, 0], ng[i, 1], ng[i, 2], tan[i, 0], tan[i, 1], tan[i, 2],
                                 front[i], lam[i])
        found = False
        for j in range(L.shape[0]):
            t = int(L[j, closure.T])
            if t != closure.L_GGX and t != closure.L_DIELECTRIC and t != closure.L_THIN_T:
                continue
            if max(L[j, closure.W], max(L[j, closure.W + 1], L[j, closure.W + 2])) <= 0.0:
                continue
            ax, ay = L[j, closure.AX], L[j, closure.AY]
            if not microfacet.is_singular(ax, ay) and np.sqrt(ax * ay) < alpha_max:
                found = True
        out[i] = found


def narrow_points(hits: BsdfHits, ng, lam, alpha_max: float = None) -> np.ndarray:
    """(V,) bool: the visible points whose closures (``hits``; ng (V, 3) their geometric
    normals, lam (V,) float64 their wavelengths in nm) have a rough glossy lobe narrower
    than alpha_max (default NARROW_ALPHA): the points that split (module doc, step 1b)."""
    v = hits.material.shape[0]
    out = np.zeros(v, bool)
    if v:
        _narrow_kernel(hits.closures, np.ascontiguousarray(hits.material, np.int32),
                       np.ascontiguousarray(hits.texel, np.float64),
                       np.ascontiguousarray(hits.outgoing, np.float64),
                       np.ascontiguousarray(hits.shading_normal, np.float64),
                       np.ascontiguousarray(ng, np.float64), hits.tangents(),
                       np.ascontiguousarray(hits.front, np.bool_),
                       np.ascontiguousarray(lam, np.float64),
                       float(NARROW_ALPHA if alpha_max is None else alpha_max), out)
    return out


def gather_photons(vp_pos, vp_ng, vp_ns, vp_wo, vp_mat, radius, ph_pos, ph_flux, ph_dir, mats,
                   vp_albedo, hits: BsdfHits, bsdf_points, vp_lam, split=None):
    """Phi (V, 3) float64 and M (V,) int64 of step 3 for V visible points and one pass's
    photons (positions, flux, directions (P, 3) float32); mats: ``bsdf.material_table``;
    vp_albedo (V, 3): the points' (textured) diffuse albedo; hits: the points' closures
    (``estimate.BsdfHits``: rows, texel, tangent, front); bsdf_points (M,) bool per
    material (non-Lambert diffuse-like lobes, or a diffuse lobe beside a rough one:
    ``closure.lobe_masks``): those points weigh each photon by their closures
    (``_gather_kernel``); vp_lam (V,) float64 their wavelengths in nm (0: RGB); split
    (V,) bool or None: the points whose glossy part a camera path carries on
    (``narrow_points``), which weigh photons by their diffuse-like part only."""
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
                   hits.closures, np.ascontiguousarray(hits.material, np.int32),
                   np.ascontiguousarray(hits.texel, np.float64), hits.tangents(),
                   np.ascontiguousarray(hits.front, np.bool_),
                   np.ascontiguousarray(vp_lam, np.float64),
                   np.ascontiguousarray(bsdf_points[vp_mat], np.bool_),
                   np.zeros(v, np.bool_) if split is None else np.ascontiguousarray(split, np.bool_),
                   phi, count)
    return phi, count


@dataclass
class _Points:
    """One level of a pass's visible points: the points (``camera_paths.VisiblePoints``),
    their closures (``BsdfHits``) and which of them split ((V,) bool)."""

    vps: camera_paths.VisiblePoints
    hits: BsdfHits
    split: np.ndarray


def dim_split(level: int, j: int) -> int:
    """The random dimension of the continuation from split points of ``level``: j = 0 the
    direction (each pixel's Sobol sequence over the passes), 1 the lobe, 2 the roulette."""
    return sampling.stream(sampling.SPECULAR_CHOICE, level, sampling.PROGRESSIVE + 9, j)


# --- the radius schedule --------------------------------------------------------------------

def initial_radius_for(prepared: PreparedScene, photons_per_pass: int) -> float:
    """The automatic r_1 (metres) of the module doc; a scene with no diffuse area gets
    1e-3 of its size (no photon can be gathered there anyway)."""
    extent = prepared.extent
    area = prepared.diffuse_area
    if area <= 0.0 or photons_per_pass <= 0:
        return max(1e-3 * extent, 1e-30)
    r = np.sqrt(INITIAL_PHOTONS * area / (np.pi * photons_per_pass))
    return float(min(r, 0.25 * extent)) if extent > 0 else float(r)


def radius_schedule(r1: float, alpha: float, n: int) -> np.ndarray:
    """(n,) float64: the gather radius r_k of passes k = 0 .. n-1,
    r_k^2 = r_1^2 prod_{j=1}^{k} (j + alpha) / (j + 1) (one cumulative product in float64,
    the same on every machine)."""
    j = np.arange(1, max(int(n), 1), dtype=np.float64)
    ratio = np.concatenate(([1.0], (j + alpha) / (j + 1.0)))
    return float(r1) * np.sqrt(np.cumprod(ratio)[:int(n)])


# --- partial sums and their exact merge -----------------------------------------------------

def pass_blocks(passes: int, block: int) -> list[tuple[int, int]]:
    """The blocks [a, b) of a render of ``passes`` passes: [0, B), [B, 2B), ..., the last
    cut at ``passes``."""
    return [(a, min(a + block, passes)) for a in range(0, passes, block)]


def _new_stats() -> dict:
    return {"photons_emitted": 0, "photons_stored": [], "photons_alive_max": 0,
            "photon_bytes_max": 0, "visible_points": [], "rays_photon": 0, "rays_shadow": 0,
            "time_camera": 0.0, "time_photons": 0.0, "time_gather": 0.0, "glossy_points": 0}


def merge_stats(a: dict, b: dict) -> dict:
    """The counters of two consecutive runs of passes (a's before b's)."""
    out = {}
    for key, v in a.items():
        w = b.get(key, type(v)())
        out[key] = v + w if not key.endswith("_max") else max(v, w)
    return out


@dataclass
class PassSums:
    """What a block of passes [start, stop) leaves: ``radiance`` (P, 3) float64, the sum
    of the passes' estimates L_k summed from zero in pass order (P = width x height pixels,
    row-major, row 0 at the top), and the block's counters (``_new_stats`` keys). It is
    what a distributed task returns: 24 bytes per pixel plus the counters."""

    start: int
    stop: int
    radiance: np.ndarray
    stats: dict = field(default_factory=_new_stats)
    features: dict = field(default_factory=dict)
    """With settings.denoising_data: "denoising_albedo" / "denoising_normal" (P, 3) float64,
    the passes' features summed like ``radiance`` (denoise_features.py); else empty."""

    @property
    def passes(self) -> int:
        return self.stop - self.start


class ImageSum:
    """The exact merge: takes blocks of passes in any order and adds them to the image sum
    in pass order (a block waits until the blocks before it have arrived), so the sum is
    the same bit for bit whatever order the blocks arrived in. ``passes`` counts the
    passes merged: always a prefix [0, passes)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.total = np.zeros((self.width * self.height, 3))
        self.features: dict[str, np.ndarray] = {}  # PassSums.features, summed
        self.passes = 0
        self.stats = _new_stats()
        self._pending: dict[int, PassSums] = {}

    def add(self, sums: PassSums) -> int:
        """Merge ``sums`` (or hold it until its predecessors come); returns the passes merged."""
        if sums.start < self.passes or sums.start in self._pending:
            raise ValueError(f"passes [{sums.start}, {sums.stop}) merged twice")
        self._pending[sums.start] = sums
        while self.passes in self._pending:
            s = self._pending.pop(self.passes)
            self.total += s.radiance
            for name, value in s.features.items():
                self.features[name] = self.features.get(name, 0.0) + value
            self.stats = merge_stats(self.stats, s.stats)
            self.passes = s.stop
        return self.passes

    @property
    def waiting(self) -> int:
        """Blocks received but not merged yet (a block before them is still missing)."""
        return len(self._pending)

    def radiance(self, partial: PassSums | None = None) -> np.ndarray:
        """(H, W, 3) float32, W/(m^2 sr): the average of the merged passes (and of
        ``partial``, the running block that follows them, if given)."""
        return self._mean(self.total, None if partial is None else partial.radiance, partial)

    def feature(self, name: str, partial: PassSums | None = None) -> np.ndarray:
        """(H, W, 3) float32: the average of denoising feature ``name`` over the merged passes
        (and ``partial``), as ``radiance`` averages the image."""
        zero = np.zeros((self.width * self.height, 3))
        own = partial.features.get(name, zero) if partial is not None else None
        return self._mean(self.features.get(name, zero), own, partial)

    def _mean(self, total, more, partial) -> np.ndarray:
        n = self.passes
        if partial is not None and partial.passes:
            total, n = total + more, n + partial.passes
        img = total / max(n, 1)
        return img.reshape(self.height, self.width, 3).astype(np.float32)


# --- rendering passes -----------------------------------------------------------------------

class PassRenderer:
    """Renders any pass k of a progressive render of ``prepared`` with ``settings`` (which
    fix everything a pass depends on: seed, photons_per_pass, progressive_alpha,
    progressive_radius, progressive_direct, progressive_passes (the size of the shadow rays'
    sample set), light_samples, max_specular_depth, photon_max_bounces). The caller owns
    ``prepared`` (and closes it)."""

    def __init__(self, prepared: PreparedScene, settings: RenderSettings):
        self.prepared, self.settings = prepared, settings
        scene = prepared.scene
        self.width, self.height = int(scene.camera.width), int(scene.camera.height)
        self.photons_per_pass = int(settings.photons_per_pass)
        self.alpha = float(settings.progressive_alpha)
        self.direct = settings.progressive_direct
        self.r1 = (float(settings.progressive_radius) if settings.progressive_radius > 0
                   else initial_radius_for(prepared, self.photons_per_pass))
        self.has_geometry = scene.mesh.triangle_count > 0
        self.sources = photon_sources(prepared)
        self.shadow_rays = None
        if self.has_geometry and self.direct == "shadow_rays":
            # The sample index of the shadow rays' random numbers is the pass, in a set of
            # progressive_passes (a setting, so every pass's numbers are fixed by it).
            self.shadow_rays = direct_light.prepare(settings, prepared,
                                                    int(settings.progressive_passes), None,
                                                    prepared.medium)
        # Media: Volume Direct by shadow rays along the camera segments (with shadow-ray
        # direct light; else by photons), the rest by the pass's volume photons.
        self.media = volume.prepare(settings, prepared, int(settings.progressive_passes))
        if self.media is not None:
            self.media.single_scattering = self.shadow_rays is not None
        self.beam_k = int(settings.global_k)
        # Visible points that weigh photons by their closures (_gather_kernel): diffuse-like
        # lobes that are not Lambert (Oren-Nayar, sheen, Translucent), and a diffuse lobe
        # beside a rough one (a Principled BSDF's base under its specular layer): the
        # legacy Lambert + specular table has neither the layer's reflection nor the
        # base's loss to it (measured: a glossy Principled floor 10-25 % dark).
        lobes = prepared.lobes
        self.bsdf_points = lobes["non_lambert"] | (lobes["diffuse"] & lobes["rough"])
        self._radii = radius_schedule(self.r1, self.alpha, 1)
        self._clipping = {}  # the media's density clipping over this renderer's passes
        # Each continuation walks at most split_depth bounces, so that every depth of the
        # camera walk and of MAX_SPLITS continuations fits the random streams' 4096.
        depth = int(settings.max_specular_depth)
        self.split_depth = max(0, min(depth, (4095 - depth) // MAX_SPLITS - 1))

    def radius(self, k: int) -> float:
        """Pass k's gather radius r_k (metres)."""
        if k >= self._radii.size:
            self._radii = radius_schedule(self.r1, self.alpha, max(k + 1, 2 * self._radii.size))
        return float(self._radii[k])

    def new_sums(self, start: int) -> PassSums:
        return PassSums(start, start, np.zeros((self.width * self.height, 3)))

    def add_pass(self, sums: PassSums) -> None:
        """Render pass ``sums.stop`` and add its estimate to ``sums`` (which then ends one
        pass later)."""
        sums.radiance += self.render_pass(sums.stop, sums.stats, sums.features)
        sums.stop += 1

    def render_block(self, start: int, stop: int,
                     on_pass: Callable[[PassSums], object] | None = None) -> PassSums:
        """The sums of passes [start, stop) (summed from zero in pass order);
        on_pass(sums) after each pass."""
        sums = self.new_sums(start)
        while sums.stop < stop:
            self.add_pass(sums)
            if on_pass is not None:
                on_pass(sums)
        return sums

    def render_pass(self, k: int, st: dict, features: dict | None = None) -> np.ndarray:
        """Pass k's estimate L_k, (P, 3) float64, W/(m^2 sr); adds its counters to st and,
        with settings.denoising_data, its denoising features to ``features`` (name ->
        (P, 3) float64, made on first use)."""
        prepared, settings = self.prepared, self.settings
        scene = prepared.scene
        seed = int(settings.seed)
        image = np.zeros((self.width * self.height, 3))
        t0 = time.perf_counter()
        vps = None
        levels = []  # _Points of the visible points and of each glossy continuation
        traced = None
        if self.media is not None and self.has_geometry:
            # The beam estimate runs along the camera segments, so this pass's photons
            # come first (without media they follow the visible points, which may need none).
            traced = self.trace_pass(k, st)
            self.media.volume_map = self.beam_map(traced[3], k)
        t_media = time.perf_counter() - t0
        if self.has_geometry:
            acc = None
            if settings.denoising_data and features is not None:
                acc = denoise_features.FeatureAccumulator(
                    camera.region_pixels(scene.camera).shape[0],
                    camera.camera_frame(scene.camera)[1:])
            vps = camera_paths.visible_points(prepared, scene.camera, seed, k,
                                              int(settings.max_specular_depth), image, acc,
                                              self.media, st)
            if acc is not None:  # one sample per region pixel, in region_pixels order
                frame = camera.region_pixels(scene.camera)
                for name, value in (("denoising_albedo", acc.albedo),
                                    ("denoising_normal", acc.normal)):
                    total = features.setdefault(name, np.zeros_like(image))
                    total[frame] += value
            # Visible points, then (step 1b) the glossy paths that go on from the split ones
            level, cur = 0, vps
            while cur.pixel.size:
                points = self.shade_points(cur, k, level, image, st)
                levels.append(points)
                start = self.split_paths(points, k, level)  # None at MAX_SPLITS
                if start is None:
                    break
                level += 1
                cur = camera_paths.visible_points(prepared, scene.camera, seed, k,
                                                  self.split_depth, image, None, self.media, st,
                                                  start)
                st["glossy_points"] += int(cur.pixel.size)
        elif np.any(prepared.world > 0) and scene.world.visible_to_camera:
            image += prepared.world
        t1 = time.perf_counter()
        stored = 0
        if levels:
            if traced is None:
                traced = self.trace_pass(k, st)
            pos, flux, wdir = traced[:3]
            t2 = time.perf_counter()
            r = self.radius(k)
            for p in levels:  # within a level each pixel has one point at most
                v = p.vps
                phi, count = gather_photons(v.position, v.ng, v.ns, v.wo, v.material,
                                            np.full(v.pixel.size, r), pos, flux, wdir,
                                            prepared.materials, v.albedo, p.hits,
                                            self.bsdf_points, v.lam, p.split)
                s = np.flatnonzero(count > 0)
                # inside a dielectric the photons' estimate is physical radiance, ior^2
                # times what the camera path's weight carries (Cycles' convention)
                inv = np.pi * r * r if v.ior is None or np.all(v.ior[s] == 1.0) else \
                    (np.pi * r * r * v.ior[s] ** 2)[:, None]
                image[v.pixel[s]] += v.weight[s] * phi[s] / inv
            stored = int(pos.shape[0])
            st["photon_bytes_max"] = max(st["photon_bytes_max"],
                                         pos.nbytes + flux.nbytes + wdir.nbytes)
            del pos, flux, wdir
        else:
            t2 = time.perf_counter()
        t3 = time.perf_counter()
        traced = None
        if self.media is not None:
            self.media.volume_map = None  # one pass's photons held at a time
            t1 -= t_media  # the photons were traced first: their time is theirs
        st["photons_emitted"] += self.photons_per_pass if self.sources else 0
        st["photons_stored"].append(stored)
        st["photons_alive_max"] = max(st["photons_alive_max"], stored)
        st["visible_points"].append(0 if vps is None else int(vps.pixel.size))
        st["time_camera"] += t1 - t0  # the shadow rays included
        st["time_photons"] += t2 - t1
        st["time_gather"] += t3 - t2
        return image

    def shade_points(self, vps: camera_paths.VisiblePoints, k: int, level: int, image,
                     st: dict) -> "_Points":
        """Visible points' closures, which of them split (``narrow_points``, not at the last
        level) and their direct light by shadow rays (the glossy part weighed by MIS
        against the continuation where they split), added to image (P, 3)."""
        prepared = self.prepared
        if vps.closures is not None:  # as the walk shaded them (camera_paths)
            tab, rows = vps.closures, vps.rows
        else:
            tab, rows = prepared.hit_shader.closures_at(vps.prim, vps.u, vps.v, -vps.wo,
                                                        vps.material, vps.path)
        tangent = prepared.hit_shader.tangents(vps.prim, vps.position, tab, rows)
        hits = BsdfHits(tab, rows, vps.texel, vps.wo, vps.ns, vps.front, tangent=tangent)
        # Standard SPPM (photon direct light) does not split: a glossy path cannot reach a
        # point light, whose glossy reflection only the photons gathered here carry.
        split = (narrow_points(hits, vps.ng, vps.lam)
                 if level < MAX_SPLITS and self.shadow_rays is not None
                 else np.zeros(vps.pixel.size, bool))
        if self.shadow_rays is not None:
            # With programmed points, their own closures and the texel colour; else
            # the material's and shade's texel from the albedo (as before programs).
            programmed = rows is not vps.material
            points = direct_light.ShadingPoints(
                vps.position, vps.ng, vps.ns, -vps.wo, rows, vps.eps, vps.weight,
                vps.albedo, vps.pixel, texel=vps.texel if programmed else None,
                mis=split, closures=tab, front=vps.front,
                wavelength=vps.lam if np.any(vps.lam > 0) else None, tangent=tangent)
            before = int(self.shadow_rays.stats.get("rays_shadow", 0))
            direct_light.shade(self.shadow_rays, points, vps.pixel,
                               np.full(vps.pixel.size, k, np.int64), level, image)
            st["rays_shadow"] += int(self.shadow_rays.stats.get("rays_shadow", 0)) - before
        return _Points(vps, hits, split)

    def split_paths(self, points: "_Points", k: int, level: int):
        """The camera paths that go on from the split points of ``points`` (step 1b): one
        BSDF sample each (``camera_paths.follow_bsdf``: the glossy part of f |cos| / pdf,
        Russian roulette on its share); a delta lobe sampled there ends the path (the point
        stands for the non-singular lobes). A ``camera_paths.PathStart``, or None."""
        sel = np.flatnonzero(points.split)
        if sel.size == 0:
            return None
        prepared, v, hits = self.prepared, points.vps, points.hits
        seed = int(self.settings.seed)
        pix, smp = v.pixel[sel], np.full(sel.size, k, np.int64)
        # the direction stratified over the passes (each pixel's own Sobol sequence)
        frame = np.empty((self.width * self.height, 2))
        sampling.progressive2(np.int64(seed), np.int64(k), np.int64(dim_split(level, 0)), frame)
        u1, u2 = frame[pix, 0], frame[pix, 1]
        u_lobe = sampling.uniform(seed, pix, smp, dim_split(level, 1))
        u_rr = sampling.uniform(seed, pix, smp, dim_split(level, 2))
        rows = np.ascontiguousarray(hits.material[sel], np.int32)
        keep, o, d, thr, tr, pdf, delta, lam = camera_paths.follow_bsdf(
            prepared, np.ascontiguousarray(v.position[sel], np.float64),
            np.ascontiguousarray(v.ng[sel], np.float64), np.ascontiguousarray(v.ns[sel], np.float64),
            np.ascontiguousarray(-v.wo[sel], np.float64), np.ascontiguousarray(v.front[sel], np.bool_),
            rows, np.ascontiguousarray(v.eps[sel], np.float64),
            np.ascontiguousarray(v.texel[sel], np.float64), np.ascontiguousarray(v.weight[sel], np.float64),
            np.ascontiguousarray(v.lam[sel], np.float64), u_lobe, u1, u2, u_rr,
            closures=hits.closures, tangent=hits.tangents()[sel])
        g = np.flatnonzero(~delta)
        if g.size == 0:
            return None
        src = sel[keep[g]]
        return camera_paths.PathStart(
            v.pixel[src], o[g], d[g], thr[g], tr[g], lam[g], pdf[g],
            np.ascontiguousarray(v.ns[src], np.float64),
            closure.transmitting(hits.closures, hits.material[src]),
            int(self.settings.light_samples), self.depth0(level + 1))

    def depth0(self, level: int) -> int:
        """The first random-stream depth of the paths of continuation ``level`` >= 1 (past
        the camera walk's 0 .. max_specular_depth and the continuations before it)."""
        return int(self.settings.max_specular_depth) + 1 + (level - 1) * (self.split_depth + 1)

    def trace_pass(self, k: int, st: dict):
        """Pass k's photons: (positions, flux, directions (M, 3) float32, the volume photons
        (``trace_stored_photons(volume=True)``) or None)."""
        settings = self.settings
        out = trace_stored_photons(
            self.prepared, self.sources, self.photons_per_pass,
            seed=sampling.pass_seed(int(settings.seed), k),
            max_bounces=int(settings.photon_max_bounces),
            store_rule=STORE_NOT_DIRECT if self.shadow_rays is not None else STORE_ALL,
            volume=self.media is not None)
        st["rays_photon"] += out[3]["rays"]
        return out[0], out[1], out[2], (out[4] if self.media is not None else None)

    def beam_map(self, photons, k: int) -> VolumePhotonMap | None:
        """Pass k's volume photon map for the beam estimate along the camera segments:
        the photons (positions, flux, directions, camera flags) of ``trace_pass``, those for
        the camera only with shadow-ray Volume Direct (a light's first collisions are
        the shadow rays'), all of them with photon direct light. Radii: the distance to the
        ``global_k``-th nearest of the pass's photons (as the photon-mapping integrator's
        map; it adapts to the photon density) times the schedule's r_k / r_1, so the beam
        radius shrinks as the surface radius does: the estimate's 2-D kernel across the ray
        is the one Knaus & Zwicker's ratio (j + alpha) / (j + 1) of r^2 is made for
        (progressive photon beams, Jarosz et al. 2011, use it for their beam width)."""
        if photons is None:
            return None
        pos, flux, direction, camera_rows = photons
        sel = camera_rows if self.shadow_rays is not None else slice(None)
        pos, flux, direction = pos[sel], flux[sel], direction[sel]
        if pos.shape[0] < 2:
            return None
        scale = self.radius(k) / self.r1
        radii = np.maximum(photon_radii(pos, min(self.beam_k, pos.shape[0])),
                           MIN_VOLUME_RADIUS) * np.float32(scale)
        return VolumePhotonMap(pos, flux, direction, np.maximum(radii, MIN_VOLUME_RADIUS))

    def base_stats(self) -> dict:
        """The run's constants, for RenderOutput.stats."""
        return {"alpha": self.alpha, "initial_radius": self.r1,
                "photons_per_pass": self.photons_per_pass,
                "progressive_block": int(self.settings.progressive_block),
                "direct_light": "shadow rays at the visible points; photons for the rest"
                if self.direct == "shadow_rays" else "photons (standard SPPM: no shadow rays)"}

    def medium_warnings(self) -> list[str]:
        """The heterogeneous media's density clipping so far (over every pass this renderer
        made: ``DensityFields.take_clipping`` summed), as photon_mapping.render's
        stats["medium_warnings"]."""
        medium = self.prepared.medium
        if medium is None or medium.fields is None:
            return []
        density.merge_clipping(self._clipping, medium.fields.take_clipping())
        return density.clipping_warnings(self._clipping)


# --- one machine ----------------------------------------------------------------------------

@dataclass
class ProgressiveState:
    """A progressive run after ``passes`` passes: ``image`` (the merged blocks), ``block``
    (the running block after them), ``radius`` (the last pass's gather radius, metres)."""

    width: int
    height: int
    passes: int
    image: ImageSum
    block: PassSums
    radius: float
    stats: dict

    def radiance(self) -> np.ndarray:
        """(H, W, 3) float32 image, W/(m^2 sr): the average of the passes so far."""
        return self.image.radiance(self.block)


SPPMState = ProgressiveState
"""The former name (the viewport and ``core.progressive`` yield it)."""


def check_passes(max_passes) -> int:
    if (not isinstance(max_passes, (int, np.integer)) or isinstance(max_passes, bool)
            or not 1 <= max_passes <= MAX_PASSES):
        raise SettingsError(f'"progressive_passes" must be an integer in [1, {MAX_PASSES}], '
                            f'got {max_passes!r}')
    return int(max_passes)


def progressive_passes(scene: Scene, settings: RenderSettings | None = None,
                       max_passes: int | None = None) -> Iterator[ProgressiveState]:
    """Run passes 0, 1, ... on this machine, yielding the (live) state after each one.

    ``max_passes`` (default settings.progressive_passes) becomes the run's
    progressive_passes. Stops after it or when the caller stops iterating (the Accelerator
    is released when the generator is closed or garbage-collected).
    """
    scene.validate()
    settings = (settings or RenderSettings()).validated()
    max_passes = check_passes(settings.progressive_passes if max_passes is None else max_passes)
    settings = settings.with_values(progressive_passes=max_passes)
    prepared = prepare(scene, settings.threads, settings.seed)
    try:
        yield from _passes(PassRenderer(prepared, settings), max_passes)
    finally:
        prepared.close()


def _passes(renderer: PassRenderer, max_passes: int) -> Iterator[ProgressiveState]:
    image = ImageSum(renderer.width, renderer.height)
    state = ProgressiveState(renderer.width, renderer.height, 0, image, renderer.new_sums(0),
                             renderer.r1, renderer.base_stats())
    for a, b in pass_blocks(max_passes, int(renderer.settings.progressive_block)):
        state.block = renderer.new_sums(a)
        while state.block.stop < b:
            k = state.block.stop
            renderer.add_pass(state.block)
            state.radius = renderer.radius(k)
            if state.block.stop == b:  # the block joins the image, in block order
                image.add(state.block)
                state.block = renderer.new_sums(b)
            state.passes = k + 1
            state.stats.update(merge_stats(image.stats, state.block.stats))
            # Not a counter merge_stats adds: the fields count the clipping of every pass
            state.stats["medium_warnings"] = renderer.medium_warnings()
            yield state


def finish_stats(stats: dict, passes: int, radius: float, stopped_by: str,
                 time_budget: float | None, t_start: float) -> dict:
    stats = dict(stats)
    stats.update({"passes": passes, "stopped_by": stopped_by, "time_budget": time_budget,
                  "radius_min": radius, "radius_mean": radius, "radius_max": radius,
                  "time_total": time.perf_counter() - t_start})
    return stats


def render(scene: Scene, settings: RenderSettings | None = None,
           on_progress: ProgressFn | None = None, on_tile: TileFn | None = None,
           should_stop: StopFn | None = None) -> RenderOutput:
    """Render ``scene`` with ``settings.progressive_passes`` passes of
    ``settings.photons_per_pass`` photons each, on this machine.

    on_tile(k, {"combined": image}) after pass k (1-based) with the image so far, (H, W, 3)
    float32; on_progress(fraction, message) after each pass; should_stop() -> True stops
    after the pass: the output then holds the k passes done and ``cancelled`` is True
    (the same image as a render of k passes).
    settings.time_budget > 0 (seconds): ``progressive_passes`` is then an upper bound and
    the render stops (not cancelled) before the pass that would end past the budget,
    judged by the mean pass time so far (at least one pass is made); stats["stopped_by"]
    says why it ended.

    Returns RenderOutput with passes {"combined": (H, W, 3) float32 radiance W/(m^2 sr)}
    (with settings.denoising_data also "denoising_albedo" / "denoising_normal", the means
    over the passes' paths, core/integrators/denoise_features.py)
    and stats: passes, alpha, initial_radius (r_1), radius_min / radius_mean / radius_max
    (the last pass's radius, metres), photons_per_pass, progressive_block, photons_emitted,
    photons_stored (list, one count per pass), photons_alive_max (most photons held at
    once), photon_bytes_max, visible_points (list per pass), rays_photon, rays_shadow,
    time_camera / time_photons / time_gather / time_total (s). Raises SettingsError and
    SceneError on bad input.
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
                on_tile(k, {"combined": camera.crop_to_region(state.radiance(), scene.camera)})
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
    stats = finish_stats(state.stats, state.passes, state.radius, stopped_by, time_budget,
                         t_start)
    # A Render Region: visible points were traced for its pixels only
    # (camera_paths.visible_points); the per-pixel sums stay frame-sized.
    image = camera.crop_to_region(state.radiance(), scene.camera)
    passes = {"combined": image}
    if settings.denoising_data:  # not light: not in combined
        for name in denoise_features.FEATURES:
            passes[name] = camera.crop_to_region(state.image.feature(name, state.block),
                                                 scene.camera)
    return RenderOutput(passes=passes, stats=stats, cancelled=cancelled)

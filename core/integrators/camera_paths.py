"""Camera paths: the walk every integrator shares from the camera into the scene.

- ``intersect``: the nearest hits of a batch of camera-path rays, passing cut-outs
  (opacity < 1) stochastically (core/materials/textures.py) without counting a bounce;
- ``lights_along``: the light surfaces a batch of rays sees in front of the geometry (lights
  seen by the camera at the first bounce, in mirrors and through glass after it), and which
  rays escape to the world;
- ``pick_wavelengths``: the wavelength a path picks at its first dispersive surface
  (docs/dispersion.md), before the hit is shaded;
- ``follow_delta``: one mirror or glass lobe sampled per path (``closure.sample_delta``),
  the path weight divided by its probability, so paths never split;
- ``visible_points``: the progressive integrator's camera pass (one jittered ray per pixel
  and pass, through mirrors and glass to the first diffuse lobe), also the photon-importance
  pre-pass's view (``importance_prepass``).

The photon-mapping camera pass (core/integrators/photon_mapping.py) and final gathering
(core/integrators/gather.py) walk with ``intersect``, ``lights_along`` and ``follow_delta``
too, shading at every hit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..lights import light_set as lights
from ..materials import bsdf
from ..materials import closure
from ..photons.importance import VisibleView, prepass_resolution
from ..prepared import PreparedScene
from ..scene import camera, geometry
from ..scene.contract import Camera
from ..shading import light_path
from . import denoise_features, direct, volume


DIM_JITTER = sampling.stream(sampling.PIXEL_JITTER, sampling.PROGRESSIVE)
"""The random dimension of the progressive camera rays' pixel jitter."""
DIM_LENS = sampling.stream(sampling.PIXEL_JITTER, sampling.PROGRESSIVE + 1)
"""The random dimension of the progressive camera rays' point on the lens (depth of field)."""


def dim_lobe(depth: int) -> int:
    """The random dimension of the progressive camera paths' lobe choice at ``depth``."""
    return sampling.stream(sampling.SPECULAR_CHOICE, depth, sampling.PROGRESSIVE)


def intersect(prepared: PreparedScene, seed: int, origins, dirs, tmax, rows, pixel, sample,
              dim_of_layer: Callable[[int], int], path=None):
    """Nearest hits (core.scene.accel.Hits) of camera-path rays ``rows`` (indices into the
    per-sample ``pixel`` and ``sample`` counters), passing cut-outs: the choice at the
    layer-th cut-out crossed uses the random dimension dim_of_layer(layer); path: the
    rays' Light Path context for programmed cut-outs (``SurfaceTextures.intersect``)."""
    def uniforms(index, layer):
        r = rows[index]
        return sampling.uniform(seed, pixel[r], sample[r], dim_of_layer(layer))
    return prepared.surfaces.intersect(prepared.accel, prepared.tri_vertices,
                                       prepared.tri_normals, prepared.extent, origins, dirs,
                                       tmax, uniforms, path)


def lights_along(prepared: PreparedScene, first: bool, transmitted, origins, dirs, hits,
                 bsdf_pdf=None, light_samples: int = 1, medium=None):
    """The light surfaces a batch of rays passes in front of the geometry.

    first: the batch is the camera's own rays (lights visible to the camera), else rays
    after a mirror or glossy lobe (lights visible to glossy rays) or glass (``transmitted``:
    visible to transmission rays). Lights are not occluders, as in Cycles: a ray that
    passes a light goes on to the surface (or the world) behind it.
    bsdf_pdf (N,) / light_samples: the MIS weighting of ``lights.intersect_lights`` (rays
    sampled from a non-delta lobe at a vertex where direct light took light_samples).
    Returns (hit, miss, shown, radiance): hit (N,) bool, a surface is reached; miss (N,)
    bool, the ray escapes to the world; shown (N,) bool, the ray sees ``radiance`` (N, 3)
    W/(m^2 sr) from lights (light surfaces, sun discs on escaping rays), or None when no
    light can be seen. medium: the scene's media (core/media/regions.Medium) or None: the
    lights' radiance is attenuated to each light (``lights.intersect_lights``).
    """
    ls = prepared.light_set
    hit = hits.prim >= 0
    visible = ls.visible_camera if first else ls.visible_glossy | ls.visible_transmission
    if not np.any(visible & prepared.light_shows):
        return hit, ~hit, None, None
    n = hit.shape[0]
    geo_t = np.where(hit, hits.t.astype(np.float64), np.inf)
    pdf = np.zeros(n) if bsdf_pdf is None else bsdf_pdf
    seen = np.zeros(n, bool)
    light_l = np.zeros((n, 3))
    groups = [(slice(None), ls.visible_camera)] if first else [
        (np.flatnonzero(transmitted), ls.visible_transmission),
        (np.flatnonzero(~transmitted), ls.visible_glossy)]
    for sel, vis in groups:
        trans = None
        if medium is not None:
            o_s, d_s = origins[sel], dirs[sel]

            def trans(rows, t, o_s=o_s, d_s=d_s):
                return medium.transmittance(o_s[rows], d_s[rows], t)
        seen[sel], light_l[sel] = lights.intersect_lights(ls, vis, origins[sel], dirs[sel],
                                                          geo_t[sel], pdf[sel], light_samples,
                                                          trans)
    return hit, ~hit, seen, light_l


@njit(cache=True, parallel=True, error_model="numpy")
def _delta_kernel(tab, pos, ngf, nsf, tan, d, front, mat, eps, texel, thr, lam, u_lobe, u_pick,
                  new_o, new_d, new_thr, transmitted, ok):
    """One singular lobe per hit (``closure.sample_delta``) and the next ray: origin offset
    by eps along ngf to the side it leaves on, throughput thr times the delta lobes'
    weight; ok False where the path ends (no delta lobe, a failed sample, zero weight)."""
    for i in prange(pos.shape[0]):
        ox, oy, oz, w0, w1, w2, _, flags = closure.sample_delta(
            tab, mat[i], texel[i, 0], texel[i, 1], texel[i, 2], -d[i, 0], -d[i, 1], -d[i, 2],
            nsf[i, 0], nsf[i, 1], nsf[i, 2], ngf[i, 0], ngf[i, 1], ngf[i, 2],
            tan[i, 0], tan[i, 1], tan[i, 2], front[i], u_lobe[i], u_pick[i], u_pick[i], lam[i])
        t0, t1, t2 = thr[i, 0] * w0, thr[i, 1] * w1, thr[i, 2] * w2
        ok[i] = flags != 0 and (t0 > 0.0 or t1 > 0.0 or t2 > 0.0)
        transmitted[i] = _next_ray(pos, ngf, eps, i, ox, oy, oz, t0, t1, t2, new_o, new_d,
                                   new_thr)


@njit(cache=True, error_model="numpy", inline="always")
def _next_ray(pos, ngf, eps, i, ox, oy, oz, t0, t1, t2, new_o, new_d, new_thr):
    """Write hit i's next ray (origin offset by eps[i] along the geometric normal to the
    direction's side, direction o, throughput t); returns whether it goes through."""
    below = ox * ngf[i, 0] + oy * ngf[i, 1] + oz * ngf[i, 2] < 0.0
    side = -eps[i] if below else eps[i]
    new_o[i, 0] = pos[i, 0] + side * ngf[i, 0]
    new_o[i, 1] = pos[i, 1] + side * ngf[i, 1]
    new_o[i, 2] = pos[i, 2] + side * ngf[i, 2]
    new_d[i, 0], new_d[i, 1], new_d[i, 2] = ox, oy, oz
    new_thr[i, 0], new_thr[i, 1], new_thr[i, 2] = t0, t1, t2
    return below


def follow_delta(prepared: PreparedScene, pos, ngf, nsf, d, front, mat, eps, texel, u_lobe,
                 u_pick, thr, lam, closures=None, tangent=None):
    """Continue K paths through one sampled mirror or glass lobe each
    (``closure.sample_delta``, the closures' own Fresnel and tints, the IOR at each path's
    wavelength), the weight divided by the lobe's probability among the delta lobes.

    Inputs (K, ...) at the hits: pos, ngf, nsf (K, 3) (normals facing the arriving ray),
    d (K, 3) the arriving directions, front (K,) bool, mat (K,) int32 rows of ``closures``
    (None: the prepared table), eps (K,), texel (K, 3) the texel colour, u_lobe / u_pick
    (K,) uniforms, thr (K, 3), lam (K,) float64 nm (0: RGB); tangent (K, 3) or None.
    Returns (keep, origins, directions, throughput, transmitted, lam) of the paths that go
    on: keep (J,) indices into the K, then (J, 3) x 3, (J,) bool and (J,) float64.
    """
    k = pos.shape[0]
    new_o, new_d, new_thr = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    new_tr, ok = np.empty(k, bool), np.empty(k, bool)
    tab = prepared.closures if closures is None else closures
    tan = (closure.default_tangents(k) if tangent is None
           else np.ascontiguousarray(tangent, np.float64))
    _delta_kernel(tab, np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(ngf, np.float64),
                  np.ascontiguousarray(nsf, np.float64), tan, np.ascontiguousarray(d, np.float64),
                  np.ascontiguousarray(front, np.bool_), np.ascontiguousarray(mat, np.int32),
                  np.ascontiguousarray(eps, np.float64), np.ascontiguousarray(texel, np.float64),
                  np.ascontiguousarray(thr, np.float64), np.ascontiguousarray(lam, np.float64),
                  u_lobe, u_pick, new_o, new_d, new_thr, new_tr, ok)
    keep = np.flatnonzero(ok)
    return keep, new_o[keep], new_d[keep], new_thr[keep], new_tr[keep], lam[keep]


@njit(cache=True, parallel=True, error_model="numpy")
def _continue_kernel(tab, pos, ngf, nsf, tan, d, front, mat, eps, texel, thr, lam, u_lobe, u1,
                     u2, u_rr, new_o, new_d, new_thr, new_pdf, transmitted, delta, ok):
    """One BSDF sample per hit (``closure.sample_bsdf``) and the next ray of the path.

    lam (K,) float64: each path's wavelength in nm (0: RGB, ``pick_wavelengths``), at
    which the BSDF is sampled and evaluated.

    A delta lobe (mirror, smooth glass) goes on with its weight (pdf 0: nothing weighs the
    lights it sees against light sampling). A non-delta direction carries only the glossy
    part of f |cos| (``closure.eval_parts``: the rough microfacet lobes), the diffuse-like
    lobes' light being held by the photon maps and the shadow rays at this hit; it goes on
    with probability ``direct.continue_probability`` (Russian roulette on the glossy
    share), and new_pdf is the sampling pdf times that probability (for MIS). The hit's
    lobes are built once (``closure.hit_lobes_into``) for the sample and the glossy part."""
    n_points = pos.shape[0]
    size = closure.LOBE_BLOCK
    for block in prange((n_points + size - 1) // size):
        lobes = closure.lobe_buffer(tab)  # the block's scratch: no allocation per hit
        F = np.empty(12)
        for i in range(block * size, min(n_points, (block + 1) * size)):
            _continue_one(tab, lobes, F, pos, ngf, nsf, tan, d, front, mat, eps, texel, thr,
                          lam, u_lobe, u1, u2, u_rr, new_o, new_d, new_thr, new_pdf,
                          transmitted, delta, ok, i)


@njit(cache=True, error_model="numpy", inline="always")
def _continue_one(tab, lobes, F, pos, ngf, nsf, tan, d, front, mat, eps, texel, thr, lam,
                  u_lobe, u1, u2, u_rr, new_o, new_d, new_thr, new_pdf, transmitted, delta,
                  ok, i):
    """``_continue_kernel`` at hit i, its lobes built in ``lobes`` and F."""
    ok[i] = False
    delta[i] = False
    transmitted[i] = False
    new_pdf[i] = 0.0
    m = mat[i]
    wox, woy, woz = -d[i, 0], -d[i, 1], -d[i, 2]
    n = closure.hit_lobes_into(lobes, F, tab, m, texel[i, 0], texel[i, 1], texel[i, 2],
                               wox, woy, woz, nsf[i, 0], nsf[i, 1], nsf[i, 2], ngf[i, 0],
                               ngf[i, 1], ngf[i, 2], tan[i, 0], tan[i, 1], tan[i, 2],
                               front[i], lam[i])
    L = lobes[:n]
    ix, iy, iz, w0, w1, w2, pdf, flags = closure.sample_lobes(
        L, F, ngf[i, 0], ngf[i, 1], ngf[i, 2], u_lobe[i], u1[i], u2[i])
    if flags == 0:
        return
    if flags & closure.LOBE_DELTA:
        delta[i] = True
    else:
        f0, f1, f2 = w0 * pdf, w1 * pdf, w2 * pdf
        _, _, _, g0, g1, g2, _ = closure.parts_at(L, F, ix, iy, iz, ngf[i, 0], ngf[i, 1],
                                                  ngf[i, 2], False, True)
        q = direct.continue_probability(f0, f1, f2, g0, g1, g2)
        if not u_rr[i] < q:
            return
        k = 1.0 / (pdf * q)
        w0, w1, w2 = g0 * k, g1 * k, g2 * k
        new_pdf[i] = pdf * q
    t0, t1, t2 = thr[i, 0] * w0, thr[i, 1] * w1, thr[i, 2] * w2
    if not (t0 > 0.0 or t1 > 0.0 or t2 > 0.0):
        return
    transmitted[i] = _next_ray(pos, ngf, eps, i, ix, iy, iz, t0, t1, t2, new_o, new_d, new_thr)
    ok[i] = True


@njit(cache=True, parallel=True, error_model="numpy")
def _pick_kernel(tab, mat, u_lam, lam, thr):
    for i in prange(mat.shape[0]):
        lam[i], thr[i, 0], thr[i, 1], thr[i, 2] = closure.pick_wavelength(
            tab, mat[i], lam[i], u_lam[i], thr[i, 0], thr[i, 1], thr[i, 2])


def pick_wavelengths(tab, mat, u_lam, lam, thr) -> None:
    """Dispersion (docs/dispersion.md): each RGB path (lam 0) at a material with a
    dispersive transmission lobe (``closure.dispersive(tab, mat)``) picks its wavelength,
    ``spectral.sample_wavelength(u_lam)``, and its throughput is multiplied by that
    wavelength's RGB weight (mean (1, 1, 1) per channel): the photons' rule
    (core/photons/scatter.py). Called before the hit is shaded, so that its direct light
    (``direct.ShadingPoints.wavelength``) and its continuation (``follow_bsdf``) see the
    same IOR. mat (K,) int32 rows of the ClosureTable tab, u_lam (K,) uniforms; lam (K,)
    float64 nm and thr (K, 3) float64 updated in place (rows with no pick unchanged)."""
    _pick_kernel(tab, mat, u_lam, lam, thr)


def follow_bsdf(prepared: PreparedScene, pos, ngf, nsf, d, front, mat, eps, texel, thr, lam,
                u_lobe, u1, u2, u_rr, closures=None, tangent=None):
    """Continue K paths through one sampled lobe each (``_continue_kernel``): mirrors,
    glass, and the glossy part of rough lobes, the same sampler photons scatter by.

    Inputs (K, ...) at the hits: pos, ngf, nsf (K, 3), d (K, 3) the arriving directions,
    front (K,) bool, mat (K,) int32, eps (K,), texel (K, 3), thr (K, 3), lam (K,) float64
    the paths' wavelengths in nm (0: RGB; ``pick_wavelengths``); u_lobe, u1, u2, u_rr
    (K,) uniforms (lobe, direction, roulette). Returns (keep, origins,
    directions, throughput, transmitted, pdf, delta, lam) of the paths that go on: keep
    (J,) indices into the K, then (J, 3) x 3, (J,) bool, (J,) float64 the solid-angle pdf
    of the direction for MIS (0 after a delta lobe), (J,) bool a delta lobe was followed,
    (J,) float64 nm the wavelength each carries on. closures: the ClosureTable ``mat``
    indexes (None: the prepared one; ``HitShader.closures_at``); tangent (K, 3) float64
    the BSDF frames' tangents (``HitShader.tangents``; None: the default tangent).
    """
    k = pos.shape[0]
    new_o, new_d, new_thr = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    new_pdf, new_tr, delta, ok = np.empty(k), np.empty(k, bool), np.empty(k, bool), np.empty(k, bool)
    tab = prepared.closures if closures is None else closures
    tan = (closure.default_tangents(k) if tangent is None
           else np.ascontiguousarray(tangent, np.float64))
    _continue_kernel(tab, pos, ngf, nsf, tan, d, front, mat, eps, texel, thr, lam, u_lobe,
                     u1, u2, u_rr, new_o, new_d, new_thr, new_pdf, new_tr, delta, ok)
    keep = np.flatnonzero(ok)
    return (keep, new_o[keep], new_d[keep], new_thr[keep], new_tr[keep], new_pdf[keep],
            delta[keep], lam[keep])


def emission_weight(prepared: PreparedScene, prim, t, d, bsdf_pdf, light_samples: int):
    """(N,) power-heuristic weight of emission seen on triangles prim (N,) at distance t
    along unit directions d (N, 3), for rays BSDF-sampled with pdf bsdf_pdf (N,) (1 where
    0: not weighed), against ``light_samples`` samples of the emissive triangles."""
    w = np.ones(prim.shape[0])
    tris = prepared.emissive
    j = prepared.emissive_index[prim]
    sel = np.flatnonzero((bsdf_pdf > 0) & (j >= 0))
    if sel.size:
        js = j[sel]
        cos = np.abs(np.einsum("ij,ij->i", d[sel], tris.normal[js]))
        tt = t[sel].astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            pl = np.where(cos > 0, tris.probability[js] * tt * tt / (tris.area[js] * cos), 0.0)
        a = bsdf_pdf[sel]
        b = light_samples * pl
        w[sel] = a * a / (a * a + b * b)
    return w


def world_weight(bsdf_pdf, prev_ns, d, light_samples: int, prev_sphere=None):
    """(N,) power-heuristic weight of the world seen by rays BSDF-sampled with pdf
    bsdf_pdf (N,) (1 where 0) from points of shading normal prev_ns (N, 3) along d (N, 3),
    against ``light_samples`` cosine samples of the world (direct.py): about prev_ns, or
    where prev_sphere (N,) bool (the point's material transmits, ``closure.transmits``)
    over the whole sphere (``lights.kernels.world_pdf``)."""
    c = np.einsum("ij,ij->i", prev_ns, d)
    pl = np.maximum(c, 0.0) / np.pi
    if prev_sphere is not None and np.any(prev_sphere):
        pl = np.where(prev_sphere, np.abs(c) / (2.0 * np.pi), pl)
    b = light_samples * pl
    a = bsdf_pdf
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a > 0, a * a / (a * a + b * b), 1.0)


# --- the progressive integrator's visible points ------------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _path_kernel(pos, d, ng, ns, mat, eps, thr, u_vp, u_lobe, u_pick, has_diffuse, tab, tan,
                 sampled, texel, lam, vp, new_o, new_d, new_thr, go_on, transmitted, rows):
    """At each hit: stop at the non-singular lobes (vp) or follow one delta lobe (go_on),
    by the closures' sample weights (``closure.sample_delta``: the delta lobes' share s of
    the material's; the point stops with probability 1 - s where it has a diffuse lobe,
    thr / (1 - s), else follows a delta lobe with its weight / s). Materials with
    sampled[m] (rough glossy lobes and no diffuse one: no photon is stored there, so no
    visible point) go on through one lobe of ``closure.sample_bsdf``, weight f |cos| /
    pdf: the lights, emission and world the path meets count in full (no shadow rays are
    cast from such a hit). tab: the ClosureTable and rows (N,) int32 each hit's row in it
    (``HitShader.shade``: programmed hits have their own; mat indexes the per-material
    masks has_diffuse and sampled), tan (N, 3) the frames' tangents, texel
    (N, 3) the texel colour, lam (N,) float64 each path's wavelength in nm (0: RGB; the
    transmission lobes refract it at their IOR there, docs/dispersion.md).

    ng, ns: normals as computed from the winding (flipped here to face the ray). new_thr
    is the visible point's weight when vp, the next ray's throughput when go_on."""
    for i in prange(d.shape[0]):
        m = mat[i]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        entering = dx * ng[i, 0] + dy * ng[i, 1] + dz * ng[i, 2] < 0.0
        sg = 1.0 if entering else -1.0
        gx, gy, gz = sg * ng[i, 0], sg * ng[i, 1], sg * ng[i, 2]
        sx, sy, sz = sg * ns[i, 0], sg * ns[i, 1], sg * ns[i, 2]
        ng[i, 0], ng[i, 1], ng[i, 2] = gx, gy, gz
        ns[i, 0], ns[i, 1], ns[i, 2] = sx, sy, sz
        vp[i] = False
        go_on[i] = False
        transmitted[i] = False
        if sampled[m]:
            ox, oy, oz, w0, w1, w2, pdf, flags = closure.sample_bsdf(
                tab, rows[i], texel[i, 0], texel[i, 1], texel[i, 2], -dx, -dy, -dz, sx, sy,
                sz, gx, gy, gz, tan[i, 0], tan[i, 1], tan[i, 2], entering,
                u_lobe[i], u_pick[i], u_vp[i], lam[i])
        else:
            ox, oy, oz, w0, w1, w2, share, flags = closure.sample_delta(
                tab, rows[i], texel[i, 0], texel[i, 1], texel[i, 2], -dx, -dy, -dz, sx, sy, sz,
                gx, gy, gz, tan[i, 0], tan[i, 1], tan[i, 2], entering,
                u_lobe[i], u_pick[i], u_pick[i], lam[i])
            if not u_vp[i] < share:  # the non-singular lobes, probability 1 - share
                if has_diffuse[m]:
                    vp[i] = True
                    q = 1.0 - share
                    new_thr[i, 0], new_thr[i, 1], new_thr[i, 2] = (
                        thr[i, 0] / q, thr[i, 1] / q, thr[i, 2] / q)
                continue
            w0, w1, w2 = w0 / share, w1 / share, w2 / share
        t0, t1, t2 = thr[i, 0] * w0, thr[i, 1] * w1, thr[i, 2] * w2
        if flags == 0 or not (t0 > 0.0 or t1 > 0.0 or t2 > 0.0):
            continue
        tr = ox * gx + oy * gy + oz * gz < 0.0
        side = -eps[i] if tr else eps[i]
        new_o[i, 0] = pos[i, 0] + gx * side
        new_o[i, 1] = pos[i, 1] + gy * side
        new_o[i, 2] = pos[i, 2] + gz * side
        new_d[i, 0], new_d[i, 1], new_d[i, 2] = ox, oy, oz
        new_thr[i, 0], new_thr[i, 1], new_thr[i, 2] = t0, t1, t2
        go_on[i] = True
        transmitted[i] = tr


@dataclass
class VisiblePoints:
    """One pass's visible points (V of them), float64: pixel (V,) int64, position (V, 3)
    metres, ng / ns (V, 3) unit normals facing the viewer, wo (V, 3) unit towards the
    viewer, material (V,) int32, weight (V, 3) path throughput, albedo (V, 3) the
    diffuse albedo there (textured), eps (V,) metres, the ray offset there; texel (V, 3)
    the texel colour (``PreparedScene.texels``), prim (V,) int32, u, v (V,) float32 the
    triangle and barycentrics (``HitShader.closures_at`` at the points); lam (V,) float64
    the paths' wavelengths in nm (0: RGB, docs/dispersion.md); front (V,) bool, the point
    was reached from the front of the mesh's geometric normal; path (V, K) float32 the
    Light Path context of the rays that reached them (core/shading/light_path.py), or
    None when no program reads it; closures, rows: the points' closures as the walk
    shaded them (``HitShader.merge`` of its ``shade`` batches; rows (V,) int32 into the
    ClosureTable closures), or None when no point has a program (then the prepared
    table and material are their closures); ior (V,) float64 the IOR of the dielectric
    the point lies in (1: none; its photon estimate is physical radiance, ior^2 times
    what the weight carries there), None for no point."""

    pixel: np.ndarray
    position: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    wo: np.ndarray
    material: np.ndarray
    weight: np.ndarray
    albedo: np.ndarray
    eps: np.ndarray
    texel: np.ndarray
    prim: np.ndarray
    u: np.ndarray
    v: np.ndarray
    lam: np.ndarray
    front: np.ndarray
    path: np.ndarray | None = None
    closures: closure.ClosureTable | None = None
    rows: np.ndarray | None = None
    ior: np.ndarray | None = None


@dataclass
class PathStart:
    """Camera paths that go on from earlier vertices instead of the camera (the progressive
    integrator's split visible points, core/integrators/sppm.py): J paths, each pixel at
    most once. pixel (J,) int64 frame pixels; origins, directions (J, 3) float64 (the
    origins offset off the surface); throughput (J, 3); transmitted (J,) bool, the
    direction crossed the surface; lam (J,) float64 nm (0: RGB); pdf (J,) float64, the
    solid-angle pdf the directions were sampled with (``follow_bsdf``): the lights, emitters
    and world the first segment sees are weighed by the power heuristic against the
    ``light_samples`` light samples of the direct light at the vertex left (its shading
    normal ns (J, 3) and whether it transmits, sphere (J,) bool: ``world_weight``);
    depth0: the first random-stream depth of these paths (past every depth the walks
    before them used, so no pixel reuses a number)."""

    pixel: np.ndarray
    origins: np.ndarray
    directions: np.ndarray
    throughput: np.ndarray
    transmitted: np.ndarray
    lam: np.ndarray
    pdf: np.ndarray
    ns: np.ndarray
    sphere: np.ndarray
    light_samples: int
    depth0: int


def visible_points(prepared: PreparedScene, cam: Camera, seed: int, k: int, max_depth: int,
                   direct: np.ndarray,
                   features: denoise_features.FeatureAccumulator | None = None,
                   media: volume.VolumeTerms | None = None,
                   stats: dict | None = None, start: PathStart | None = None) -> VisiblePoints:
    """Pass k's visible points (one jittered camera ray per pixel of ``cam``'s region, sample k),
    adding the radiance seen on the way (emitters, lights, background) to direct (P, 3)
    float64 (see core/integrators/sppm.py, step 1).

    features: Cycles' denoising features of this pass's paths (one sample per region pixel,
    in ``camera.region_pixels`` order), written at their hits as the photon-mapping
    integrator writes them (denoise_features.py).

    media: the scene's media terms (core/integrators/volume.py) with this pass's volume
    photon map, or None (no medium): every segment of the paths adds its Volume Direct,
    beam estimate and emission to direct and attenuates what lies behind it (the visible
    points' weights included); stats receives the volume counters.

    start: walk on from these vertices (``PathStart``; SPPM's glossy continuation) instead
    of from the camera: the same walk to the first diffuse lobe, its first segment's
    lights, emission and world weighed against light sampling (MIS), random streams from
    depth start.depth0 on, no denoising features; a medium is taken to start in vacuum."""
    if start is not None:
        return _walk(prepared, seed, k, max_depth, direct, None, media, stats,
                     np.ascontiguousarray(start.pixel, np.int64), start.origins,
                     start.directions, None, np.array(start.throughput, np.float64),
                     np.array(start.transmitted, bool), np.array(start.lam, np.float64),
                     start)
    frame = int(cam.width) * int(cam.height)
    # The Render Region's pixels only (all of them without one), by frame index: each
    # pixel's numbers are those of a whole-frame render (the frame's sequence, indexed).
    pixel = camera.region_pixels(cam)
    n = pixel.shape[0]
    jitter = np.empty((frame, 2))
    sampling.progressive2(np.int64(seed), np.int64(k), np.int64(DIM_JITTER), jitter)
    jitter = jitter[pixel] if n < frame else jitter
    lens = None
    if camera.has_aperture(cam):  # depth of field: a point on the aperture, per pass
        lens = np.empty((frame, 2))
        sampling.progressive2(np.int64(seed), np.int64(k), np.int64(DIM_LENS), lens)
        lens = lens[pixel] if n < frame else lens
    rays = camera.generate_rays(cam, pixel, jitter, lens)
    return _walk(prepared, seed, k, max_depth, direct, features, media, stats, pixel,
                 rays.origins, rays.directions, rays.tmax, np.ones((n, 3)), np.zeros(n, bool),
                 np.zeros(n), None)  # lam: nm, 0 while RGB (picked at the first dispersive surface)


def _walk(prepared: PreparedScene, seed: int, k: int, max_depth: int, direct, features, media,
          stats, pixel, origins, dirs, tmax, thr, transmitted, lam,
          start: PathStart | None) -> VisiblePoints:
    """The walk of ``visible_points`` from rays (origins, dirs (n, 3), tmax (n,) or None)
    of the frame pixels ``pixel`` (n,) int64, throughput thr (n, 3), transmitted (n,),
    wavelengths lam (n,): from the camera (start None) or from ``start``'s vertices."""
    mats = prepared.materials
    n = pixel.shape[0]
    sample = np.full(n, k, np.int64)
    rows = np.arange(n, dtype=np.int64)  # into pixel / sample; pixel[rows] into direct
    d0 = 0 if start is None else int(start.depth0)  # the random streams' first depth
    # MIS of the first segment after a BSDF-sampled vertex (start): pdf 0 weighs nothing
    prev_pdf = np.zeros(n) if start is None else np.array(start.pdf, np.float64)
    prev_ns = None if start is None else np.asarray(start.ns, np.float64)
    prev_sphere = None if start is None else np.asarray(start.sphere, bool)
    k_light = 1 if start is None else int(start.light_samples)
    dispersive = bool(np.any(prepared.closures.abbe > 0))
    world = prepared.world
    out = []
    shaded = []  # (tab, rows) of the visible points of each depth, as shade gave them
    # The Light Path context, only when a program reads it: the bounces so far are
    # singular (a delta lobe) or glossy (a rough lobe followed by sampling), the
    # transmissions among them counted.
    lp_read = prepared.hit_shader.reads_light_path
    last_delta, n_trans = np.full(n, start is None), np.zeros(n)
    # The IOR of the dielectric each path is in (volume.add_segments, VisiblePoints.ior)
    n_inside = np.ones(n)
    iors = []
    if media is not None:
        seen_media = np.zeros((n, 3))  # per row of pixel: the media's light
        stats = {} if stats is None else stats
    for local in range(max_depth + 1):
        if rows.shape[0] == 0:
            break
        depth = d0 + local  # the random streams' depth
        first = depth == 0
        path = None
        if lp_read:  # Ray Length is set at the hits
            bounces = local + (start is not None)
            path = light_path.camera(np.zeros(rows.shape[0])) if first else \
                light_path.after_bounce(np.zeros(rows.shape[0]), np.where(
                    last_delta, light_path.BOUNCE_SINGULAR, light_path.BOUNCE_GLOSSY),
                    transmitted, bounces, glossy_depth=bounces, transmission_depth=n_trans)
        hits = intersect(prepared, seed, origins, dirs, tmax, rows, pixel, sample,
                         lambda layer, depth=depth: sampling.stream(sampling.CUTOUT_CHOICE, depth,
                                                                    layer, sampling.PROGRESSIVE),
                         path)
        thr_light = thr  # the lights along the rays are attenuated to themselves
        if media is not None:  # the segments' media: their light, then their transmittance
            thr = volume.add_segments(
                media, origins, dirs, np.where(hits.prim >= 0, hits.t, np.inf), thr, rows,
                pixel, sample, depth, seen_media, seen_media, seen_media, stats, n_inside,
                volume.surface_bounds(prepared, hits.prim, dirs))
        weigh = start is not None and local == 0  # MIS against the vertex's light samples
        hit, miss, shown, light_l = lights_along(prepared, first, transmitted, origins, dirs, hits,
                                                 prev_pdf if weigh else None, k_light,
                                                 medium=None if media is None else media.medium)
        if shown is not None:
            direct[pixel[rows[shown]]] += thr_light[shown] * light_l[shown]
        # Rays that escape see the world
        if np.any(world > 0) and np.any(miss) and (not first or prepared.scene.world.visible_to_camera):
            seen = thr[miss] * world
            if weigh:
                seen *= world_weight(prev_pdf[miss], prev_ns[miss], dirs[miss], k_light,
                                     prev_sphere[miss])[:, None]
            direct[pixel[rows[miss]]] += seen
        h = np.flatnonzero(hit)
        if h.size == 0:
            break
        rows, thr, d, transmitted, lam = rows[h], thr[h], dirs[h], transmitted[h], lam[h]
        if lp_read:
            path = path[h]
            path[:, light_path.RAY_LENGTH] = hits.t[h]
            last_delta, n_trans = last_delta[h], n_trans[h]
        n_inside = n_inside[h]
        sp = geometry.surface_points(prepared.tri_vertices, prepared.tri_normals,
                                     prepared.tri_material, hits.prim[h], hits.u[h], hits.v[h],
                                     d, prepared.extent)
        # Emission seen (two-sided, like Cycles' emission closure)
        emission = prepared.hit_shader.emission_at(
            hits.prim[h], hits.u[h], hits.v[h], d, sp.material, mats["emission"][sp.material],
            path)
        if weigh and prepared.emissive.count:
            emission = emission * emission_weight(prepared, hits.prim[h], hits.t[h], d,
                                                  prev_pdf[h], k_light)[:, None]
        direct[pixel[rows]] += thr * emission
        albedo = prepared.surfaces.albedo(hits.prim[h], hits.u[h], hits.v[h], sp.material)
        front = np.einsum("ij,ij->i", d, sp.geometric_normal) < 0.0
        ng, ns = sp.geometric_normal.copy(), sp.shading_normal.copy()
        # A shader program's normal (Normal Map, Bump; it faces the ray): given to the
        # kernel on the winding's side, which it flips to face the ray again.
        entering = np.einsum("ij,ij->i", d, ng) < 0.0
        facing = np.where(entering[:, None], ns, -ns)
        # the per-hit closures (programmed parameters and Mix weights), shaded once: they
        # choose the lobe, give the visible point's diffuse albedo and (VisiblePoints'
        # closures) its direct light and photon gathering in sppm
        tab, crow, bent = prepared.hit_shader.shade(hits.prim[h], hits.u[h], hits.v[h], d,
                                                    sp.material, facing, path)
        texel = prepared.texels.albedo(hits.prim[h], hits.u[h], hits.v[h], sp.material)
        albedo = prepared.hit_shader.diffuse_albedo(tab, crow, sp.material, texel, d,
                                                    sp.shading_normal, albedo)
        m = len(rows)
        pix, smp = pixel[rows], sample[rows]
        u_vp = sampling.uniform(seed, pix, smp, dim_lobe(depth))
        u_lobe, u_pick = sampling.uniform2(seed, pix, smp, dim_lobe(depth) + 1)
        if dispersive:  # the path's wavelength, before the hit is shaded (pick_wavelengths)
            u_lam = sampling.uniform(seed, pix, smp, sampling.stream(
                sampling.CAMERA_WAVELENGTH, depth, sampling.PROGRESSIVE))
            thr = np.array(thr)
            pick_wavelengths(prepared.closures, sp.material, u_lam, lam, thr)
        if bent is not facing:
            ns = np.where(entering[:, None], bent, -bent)
        vp, go_on, new_tr = np.empty(m, bool), np.empty(m, bool), np.empty(m, bool)
        new_o, new_d, new_thr = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        _path_kernel(sp.position, d, ng, ns, sp.material, sp.eps, thr, u_vp, u_lobe, u_pick,
                     prepared.has_diffuse, tab,
                     prepared.hit_shader.tangents(hits.prim[h], sp.position, tab, crow),
                     prepared.sampled_only, texel, lam, vp, new_o,
                     new_d, new_thr, go_on, new_tr, np.ascontiguousarray(crow, np.int32))
        if features is not None:  # ns now faces the ray, as the shading normal does there
            features.surface(rows, albedo, mats["specular"][sp.material],
                             mats["transmission"][sp.material], mats["alpha"][sp.material], ns)
        # Visible points: the first diffuse lobe on the path
        s = np.flatnonzero(vp)
        if s.size:
            out.append((pixel[rows[s]], sp.position[s], ng[s], ns[s], -d[s], sp.material[s], new_thr[s],
                        albedo[s], sp.eps[s], texel[s], hits.prim[h][s], hits.u[h][s],
                        hits.v[h][s], lam[s], front[s]) + ((path[s],) if lp_read else ()))
            shaded.append((tab, crow[s]))
            iors.append(n_inside[s])
        if local == max_depth:
            break
        g = np.flatnonzero(go_on)
        n_inside = index_after(prepared, n_inside[g], new_tr[g], front[g], sp.material[g])
        rows, origins, dirs, lam = rows[g], new_o[g], new_d[g], lam[g]
        thr, transmitted, tmax = new_thr[g], new_tr[g], None
        if lp_read:  # a delta lobe, unless the material's only glossy lobes are rough
            m_g = sp.material[g]
            last_delta = prepared.has_delta[m_g] & ~prepared.sampled_only[m_g]
            n_trans = n_trans[g] + transmitted
    if media is not None:
        direct[pixel] += seen_media
    if not out:
        z3 = np.zeros((0, 3))
        return VisiblePoints(np.zeros(0, np.int64), z3, z3, z3, z3, np.zeros(0, np.int32), z3, z3,
                             np.zeros(0), z3, np.zeros(0, np.int32), np.zeros(0, np.float32),
                             np.zeros(0, np.float32), np.zeros(0), np.zeros(0, bool))
    cols = [np.concatenate(c) for c in zip(*out)]
    vps = VisiblePoints(*[np.ascontiguousarray(c) for c in cols])
    vps.ior = np.concatenate(iors)
    if any(tab is not prepared.hit_shader.table for tab, _ in shaded):
        vps.closures, vps.rows = prepared.hit_shader.merge(shaded)
    return vps




def index_after(prepared: PreparedScene, n_inside, transmitted, front, material) -> np.ndarray:
    """(N,) float64 the IOR each of N camera paths is in after its bounce: the material's
    IOR where it was transmitted through a front face into a dielectric
    (``PreparedScene.refracts``), 1 where it left one by a back face, else n_inside (a
    thin wall's or a Translucent lobe's transmission leaves it where it was). n_inside
    (N,) float64, transmitted, front (N,) bool, material (N,) int."""
    refracted = transmitted & prepared.refracts[material]
    return np.where(refracted & front, prepared.materials["ior"][material],
                    np.where(refracted & ~front, 1.0, n_inside))


def importance_prepass(prepared: PreparedScene, seed: int, max_depth: int) -> VisibleView:
    """The photon-importance pre-pass (core/photons/importance.py, step 1): the visible
    points of a coarse grid over the film (about PREPASS_PIXELS rays, aspect kept)."""
    t0 = time.perf_counter()
    cam = prepared.scene.camera
    w, h = prepass_resolution(cam.width, cam.height)
    vps = visible_points(prepared, replace(cam, width=w, height=h, region=None), int(seed), 0,
                         int(max_depth), np.zeros((w * h, 3)))
    return VisibleView(np.ascontiguousarray(vps.position, np.float64),
                       np.ascontiguousarray(vps.ng, np.float64), w * h,
                       time.perf_counter() - t0)

"""What a photon does where it hits a surface: store, then Russian roulette on the lobes.

One numba kernel handles a whole wavefront (all photons of one bounce). Per photon:

1. Surface point and normals (``geometry.surface_point``), flipped to the side the photon
   arrives on.
2. Storage (the rules are core/photons/store.py's ``stores``): at a material with a diffuse
   lobe (albedo > 0), before the bounce is chosen (Jensen). Global map, by ``store_rule``: STORE_ALL always; STORE_BOUNCED only after at
   least one diffuse bounce; STORE_NOT_DIRECT always but at the first hit of a photon
   straight from its source (the light a shadow ray finds). Caustic map: only photons
   that made one or more specular/glossy bounces and no diffuse one (light -> S+ -> D);
   a caustic photon ends where it is stored, and one whose first surface has no specular
   lobe is dropped.
3. The bounce: the same sampler as camera paths (``closure.sample_bsdf``, one per lobe:
   Lambert, GGX by visible normals, mirror, smooth dielectric; photons carry flux, so no
   eta^2 factor), giving a direction and the weight w = f |cos| / pdf, f the BSDF with the
   viewer on the photon's outgoing side (``closure.adjoint_weight``). At a material with
   diffuse-like lobes beside glossy ones, f and pdf are those of the sampled lobe's class
   (``closure.class_weight``): the bounce's class decides which map the photon's light
   belongs to (below), so a glossy-class photon must not carry the diffuse lobes' light.
4. Russian roulette on the sampled weight: the photon survives with p = min(1, max w)
   and its flux is multiplied by w / p per channel: a grey surface of albedo a keeps the
   photon's flux unchanged and absorbs it with probability 1 - a.

Dispersion (docs/dispersion.md): a photon is RGB (wavelength 0) until it meets a material
with a dispersive transmission lobe (``closure.dispersive``); there, before its bounce, it
picks one wavelength (``spectral.sample_wavelength``, stream ``sampling.WAVELENGTH``), its
flux is multiplied by that wavelength's RGB weight (mean (1, 1, 1) per channel), and from
then on every transmission lobe it meets refracts it with the IOR at its wavelength. The
flux stored is that RGB, so the maps and estimates are unchanged.

Glossy bounces count as specular for the path type, like Jensen's caustic paths.
Textures: the texel colour multiplies the textured closures' colour (roulette and bounce
weight); storage depends on the material having a diffuse lobe, not on the texel.
Cut-outs (opacity a < 1): the photon is stored as usual, then passes straight through
with probability 1 - a (same flux, same path type, so never a caustic because of it), or
meets the surface (the roulette above) with probability a.
A new direction on the wrong side of the geometric normal (bent shading normals) is
absorbed for diffuse/glossy, and mirrored about the geometric normal for delta lobes
(the sampler's rules).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..materials import bsdf
from ..materials import closure
from ..scene import geometry
from .. import sampling

from .store import MODE_CAUSTIC, stores

DEFAULT_TANGENT = closure.DEFAULT_TANGENT
"""The tangent of photons without one (``scatter_kernel``'s tan of shape (0, 3))."""

# Photons per parallel task of scatter_kernel.
_BLOCK = 4096


@njit(cache=True, error_model="numpy")
def _max3(a, b, c):
    return max(a, max(b, c))


@njit(cache=True, error_model="numpy")
def _scatter_range(tri_v, tri_n, tri_mat, extent, tab, has_diffuse, has_specular, texel, rows,
                   tan, nrm, opacity, prim, hu, hv, d, flux, pid, n_diff, n_spec, lam, seed, dims,
                   bounce, mode, store_rule, last,
                   store, s_pos, s_flux, s_dir, alive, o_new, d_new, f_new, lo, hi):
    """Photons [lo, hi) of scatter_kernel, as a plain serial loop: numba compiles it
    about twice as fast as the same body inside a prange loop."""
    lobes = closure.lobe_buffer(tab)  # the block's scratch: no allocation per bounce
    for i in range(lo, hi):
        store[i] = False
        alive[i] = False
        t = prim[i]
        if t < 0:
            continue
        dx, dy, dz = np.float64(d[i, 0]), np.float64(d[i, 1]), np.float64(d[i, 2])
        px, py, pz, gx, gy, gz, sx, sy, sz = geometry.surface_point(
            tri_v, tri_n, t, np.float64(hu[i]), np.float64(hv[i]), dx, dy, dz)
        entering = dx * gx + dy * gy + dz * gz < 0.0
        sg = 1.0 if entering else -1.0
        gx, gy, gz = sg * gx, sg * gy, sg * gz
        sx, sy, sz = sg * sx, sg * sy, sg * sz
        if nrm.shape[0] and (nrm[i, 0] != 0.0 or nrm[i, 1] != 0.0 or nrm[i, 2] != 0.0):
            # a shader program's normal (Normal Map, Bump), already facing the photon
            sx, sy, sz = nrm[i, 0], nrm[i, 1], nrm[i, 2]
        m = tri_mat[t]
        if texel.shape[0]:
            c0, c1, c2 = texel[i, 0], texel[i, 1], texel[i, 2]
        else:
            c0, c1, c2 = 1.0, 1.0, 1.0
        nd = n_diff[i]
        ns = n_spec[i]
        f0, f1, f2 = flux[i, 0], flux[i, 1], flux[i, 2]
        u_rr = sampling.hash_uniform(seed, pid[i], bounce, dims[0])
        # Cut-out (opacity < 1): pass straight through with probability 1 - opacity, the
        # flux and the path type unchanged (not a bounce: a photon seen through a cut-out
        # is not a caustic). The surface itself receives the full flux (stored below):
        # the camera weights its shading by the opacity.
        through = False
        if opacity.shape[0]:
            op = opacity[i]
            if u_rr >= op:
                through = True
            else:
                u_rr = u_rr / op
        if mode == MODE_CAUSTIC and ns == 0 and not has_specular[m] and not through:
            continue  # first surface not specular: not a caustic path
        store[i] = stores(mode, store_rule, has_diffuse[m], nd, ns)
        if store[i]:
            s_pos[i, 0], s_pos[i, 1], s_pos[i, 2] = px, py, pz
            s_flux[i, 0], s_flux[i, 1], s_flux[i, 2] = f0, f1, f2
            s_dir[i, 0], s_dir[i, 1], s_dir[i, 2] = -dx, -dy, -dz
            if mode == MODE_CAUSTIC and not through:
                continue
        if last:
            continue
        if through:
            e = -geometry.offset_eps(px, py, pz, extent)
            o_new[i, 0], o_new[i, 1], o_new[i, 2] = px + e * gx, py + e * gy, pz + e * gz
            d_new[i, 0], d_new[i, 1], d_new[i, 2] = dx, dy, dz
            f_new[i, 0], f_new[i, 1], f_new[i, 2] = f0, f1, f2
            alive[i] = True
            continue
        row = rows[i] if rows.shape[0] else m
        # The first dispersive surface: the photon picks its wavelength, its flux
        # becomes that wavelength's RGB (E[weight] = 1 per channel: white stays white).
        li, f0, f1, f2 = closure.pick_wavelength(
            tab, row, lam[i], sampling.hash_uniform(seed, pid[i], bounce, dims[4]), f0, f1, f2)
        lam[i] = li
        u1 = sampling.hash_uniform(seed, pid[i], bounce, dims[1])
        u2 = sampling.hash_uniform(seed, pid[i], bounce, dims[2])
        u_lobe = sampling.hash_uniform(seed, pid[i], bounce, dims[3])
        # The bounce: the camera paths' sampler (one per lobe), wo towards where the
        # photon came from.
        if tan.shape[0]:
            tx, ty, tz = tan[i, 0], tan[i, 1], tan[i, 2]
        else:
            tx, ty, tz = DEFAULT_TANGENT
        ox, oy, oz, w0, w1, w2, pdf, flags = closure.sample_bsdf_into(
            lobes, tab, row, c0, c1, c2, -dx, -dy, -dz, sx, sy, sz, gx, gy, gz,
            tx, ty, tz, entering, u_lobe, u1, u2, li)
        if flags == 0:
            continue  # absorbed: no direction
        if flags & closure.LOBE_DIFFUSE:
            if mode == MODE_CAUSTIC:
                continue  # a diffuse bounce ends the caustic path
        if has_specular[m] and not flags & closure.LOBE_DELTA:
            # A glossy, rough-glass or layered material's reflection or transmission: the
            # light it sends on is its BSDF with the viewer on the outgoing side
            # (closure.adjoint_weight; Lambert and delta lobes are reciprocal). With
            # diffuse-like lobes beside the others, only the sampled class's
            # (closure.class_weight): the maps tell paths apart by the class of their bounces.
            if has_diffuse[m]:
                w0, w1, w2 = closure.class_weight(
                    lobes, tab, row, c0, c1, c2, -dx, -dy, -dz, ox, oy, oz, sx, sy, sz, gx,
                    gy, gz, tx, ty, tz, entering, bool(flags & closure.LOBE_DIFFUSE), li)
            else:
                w0, w1, w2 = closure.adjoint_weight(
                    lobes, tab, row, c0, c1, c2, -dx, -dy, -dz, ox, oy, oz, sx, sy, sz, gx,
                    gy, gz, tx, ty, tz, entering, pdf, li)
        # Russian roulette on the sampled weight: survive with p = min(1, max w), the flux
        # times w / p (a grey surface of albedo a keeps the flux, absorbs with 1 - a).
        p = min(1.0, _max3(w0, w1, w2))
        if not u_rr < p:
            continue
        if flags & closure.LOBE_DIFFUSE:
            n_diff[i] = nd + 1
        else:
            n_spec[i] = ns + 1
        ln = np.sqrt(ox * ox + oy * oy + oz * oz)
        if not ln > 0.0:
            continue
        ox, oy, oz = ox / ln, oy / ln, oz / ln
        nf0, nf1, nf2 = f0 * w0 / p, f1 * w1 / p, f2 * w2 / p
        if not (nf0 > 0.0 or nf1 > 0.0 or nf2 > 0.0):
            continue
        side = 1.0 if ox * gx + oy * gy + oz * gz >= 0.0 else -1.0
        e = side * geometry.offset_eps(px, py, pz, extent)
        o_new[i, 0], o_new[i, 1], o_new[i, 2] = px + e * gx, py + e * gy, pz + e * gz
        d_new[i, 0], d_new[i, 1], d_new[i, 2] = ox, oy, oz
        f_new[i, 0], f_new[i, 1], f_new[i, 2] = nf0, nf1, nf2
        alive[i] = True


@njit(cache=True, parallel=True, error_model="numpy")
def scatter_kernel(tri_v, tri_n, tri_mat, extent, tab, has_diffuse, has_specular, texel, rows,
                   tan, nrm, opacity, prim, hu, hv, d, flux, pid, n_diff, n_spec, lam, seed, dims,
                   bounce, mode, store_rule, last,
                   store, s_pos, s_flux, s_dir, alive, o_new, d_new, f_new):
    """Store and scatter one wavefront of N photons (see the module doc).

    Inputs: tab the ClosureTable (``PreparedScene.closures``); has_diffuse / has_specular
    (M,) bool, the material has a diffuse lobe (photons are stored there) / a mirror,
    glass or glossy lobe (a caustic path may start there); texel (N, 3) float64 the texel
    colour per photon, or (0, 3) for none; opacity (N,) float64 per photon, or (0,) for
    none (textures.SurfaceTextures.photon_albedo / photon_opacity); rows (N,) int32 each
    photon's material row in tab (``HitShader.closures_at``: programmed hits), or (0,)
    for the triangles' materials; tan (N, 3) float64 the BSDF frames' tangents
    (``HitShader.tangents``), or (0, 3) for ``closure.DEFAULT_TANGENT`` everywhere;
    nrm (N, 3) float64 the shading normal a shader program sets (``HitShader.shade``,
    facing where the photon came from; a zero row: the interpolated normal), or (0, 3);
    prim (N,) int32 (-1 =
    missed), hu, hv (N,) float32 barycentrics, d (N, 3) float32 unit directions of travel,
    flux (N, 3) float64 W, pid (N,) int64 photon ids (random counters), n_diff / n_spec
    (N,) int32 bounces so far, lam (N,) float64 each photon's wavelength in nm, 0 for RGB
    (all three updated in place), dims (5,) int64 random dimensions (roulette, the two
    direction uniforms, the lobe, the wavelength),
    bounce: this hit's index (the counter's "sample").
    Outputs: store (N,) bool with s_pos (N, 3), s_flux (N, 3) W, s_dir (N, 3) unit
    towards where the photon came from (float32); alive (N,) bool with the new origin
    o_new and direction d_new (float32, what Embree takes) and flux f_new (float64).
    """
    n = prim.shape[0]
    blocks = (n + _BLOCK - 1) // _BLOCK
    for b in prange(blocks):
        _scatter_range(tri_v, tri_n, tri_mat, extent, tab, has_diffuse, has_specular, texel, rows,
                       tan, nrm, opacity, prim, hu, hv, d, flux, pid, n_diff, n_spec, lam, seed, dims,
                       bounce, mode, store_rule, last, store, s_pos, s_flux, s_dir, alive, o_new,
                       d_new, f_new, b * _BLOCK, min(n, (b + 1) * _BLOCK))


@njit(cache=True, parallel=True, error_model="numpy")
def _gather_alive(idx, o, d, f, pid, n_diff, n_spec, lam, o_out, d_out, f_out, pid_out, nd_out,
                  ns_out, lam_out):
    for j in prange(idx.shape[0]):
        i = idx[j]
        for k in range(3):
            o_out[j, k] = o[i, k]
            d_out[j, k] = d[i, k]
            f_out[j, k] = f[i, k]
        pid_out[j] = pid[i]
        nd_out[j] = n_diff[i]
        ns_out[j] = n_spec[i]
        lam_out[j] = lam[i]


def compact_alive(alive, o, d, f, pid, n_diff, n_spec, lam):
    """The surviving photons' arrays, in order (one parallel pass instead of seven numpy
    boolean indexings, which cost ~30 ns per (N, 3) row)."""
    idx = np.flatnonzero(alive)
    m = idx.shape[0]
    out = (np.empty((m, 3), o.dtype), np.empty((m, 3), d.dtype), np.empty((m, 3), f.dtype),
           np.empty(m, pid.dtype), np.empty(m, n_diff.dtype), np.empty(m, n_spec.dtype),
           np.empty(m, lam.dtype))
    if m:
        _gather_alive(idx, o, d, f, pid, n_diff, n_spec, lam, *out)
    return out

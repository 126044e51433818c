"""Light sources: geometry, units, direct-light sampling and ray/light intersection.

Units match Cycles (kernel/light/*.h, scene/light.cpp; see docs/core_renderer.md):
- strength S = colour x power (W, or W/m^2 for the sun).
- Point / spot, radius 0: intensity I = S / (4 pi) W/sr.
- Point / spot, radius r > 0: a surface of radiance L = S / (4 pi^2 r^2) W/(m^2 sr), i.e.
  ``eval_fac = 1 / (pi * 4 pi r^2)``. With ``soft_falloff`` (Blender's default) the surface
  is a disk of radius r facing the shading point; without it, a sphere. Far away both
  give I / d^2, like the point light.
- Spot: the point light's emission times Cycles' ``spot_light_attenuation``:
  smoothstep((cos a - cos(size/2)) / ((1 - cos(size/2)) * blend)), a measured from -Z.
- Sun: irradiance S on a surface facing it. With angle > 0, a disc of half angle
  h = angle / 2 and radiance S / (pi sin^2 h), sampled uniformly in its cone.
- Area: one-sided Lambertian emitter along local -Z, radiance L = S / (pi A),
  A = size_x size_y (x pi/4 for an ellipse), sampled uniformly by area.
- Emissive triangles: two-sided, radiance = material emission; sampled by area x radiance.

``sample_direct`` returns, per shading point, a direction to the light, the distance (inf
for the sun), ``weight`` = incident radiance / pdf (solid angle) -- so the reflected
radiance estimate is f * |cos| * weight -- and the cosine at the light (for offsets).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from . import kernels as lk
from ..scene.contract import (AREA_ELLIPSE, LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, Lights, Materials, Mesh)


class DirectSample(NamedTuple):
    """Light samples for N shading points (float64).

    direction: (N, 3) unit vector from the point towards the light.
    distance: (N,) metres to the sampled light point, inf for the sun.
    weight: (N, 3) incident radiance / pdf(direction), W/m^2.
    cos_light: (N,) cosine at the light surface (1 for point, spot and sun).
    valid: (N,) bool, False where the sample carries no light.
    """

    direction: np.ndarray
    distance: np.ndarray
    weight: np.ndarray
    cos_light: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class LightSet:
    """Per-light constants derived once per render from ``scene.Lights`` (float64)."""

    kind: np.ndarray            # (L,) int32
    position: np.ndarray        # (L, 3) metres
    axis_x: np.ndarray          # (L, 3) unit local X
    axis_y: np.ndarray          # (L, 3) unit local Y
    axis_z: np.ndarray          # (L, 3) unit local Z (lights emit along -Z)
    strength: np.ndarray        # (L, 3) colour x power
    radiance: np.ndarray        # (L, 3) surface radiance (area, sphere/disk, sun disc), W/(m^2 sr)
    radius: np.ndarray          # (L,)
    sphere: np.ndarray          # (L,) bool: point/spot radius is a sphere (not a facing disk)
    spot_cos_half: np.ndarray   # (L,)
    spot_smooth: np.ndarray     # (L,) 1 / ((1 - cos_half) blend), inf = hard edge
    sun_one_minus_cos: np.ndarray  # (L,) 1 - cos(angle / 2)
    shape: np.ndarray           # (L,) int32
    size: np.ndarray            # (L, 2)
    area: np.ndarray            # (L,)
    visible_camera: np.ndarray
    visible_diffuse: np.ndarray
    visible_glossy: np.ndarray
    visible_transmission: np.ndarray
    cast_shadow: np.ndarray
    names: tuple
    params: np.ndarray          # (L, light_kernels.P_COUNT) the rows the kernels read

    @property
    def count(self) -> int:
        return int(self.kind.shape[0])

    @staticmethod
    def from_lights(lights: Lights) -> "LightSet":
        n = lights.count
        m = np.asarray(lights.to_world, np.float64).reshape(n, 4, 4)
        axes = []
        for k in range(3):
            a = m[:, :3, k]
            ln = np.linalg.norm(a, axis=1, keepdims=True)
            fallback = np.zeros_like(a)
            fallback[:, k] = 1.0
            axes.append(np.where(ln > 0, a / np.where(ln > 0, ln, 1.0), fallback))
        strength = lights.color.astype(np.float64) * lights.power.astype(np.float64)[:, None]
        radius = lights.radius.astype(np.float64)
        kind = lights.kind.astype(np.int32)
        radiance = np.zeros((n, 3))
        local = (kind == LIGHT_POINT) | (kind == LIGHT_SPOT)
        with np.errstate(divide="ignore", invalid="ignore"):
            r_ok = local & (radius > 0)
            radiance[r_ok] = strength[r_ok] / (4.0 * np.pi ** 2 * radius[r_ok, None] ** 2)
            cos_half = np.cos(lights.spot_size.astype(np.float64) / 2.0)
            denom = (1.0 - cos_half) * lights.spot_blend.astype(np.float64)
            smooth = np.where(denom > 0, 1.0 / np.where(denom > 0, denom, 1.0), np.inf)
            half = lights.angle.astype(np.float64) / 2.0
            sun_omc = 2.0 * np.sin(half / 2.0) ** 2
            sun = (kind == LIGHT_SUN) & (half > 0)
            radiance[sun] = strength[sun] / (np.pi * np.sin(half[sun, None]) ** 2)
            size = lights.size.astype(np.float64)
            area = size[:, 0] * size[:, 1] * np.where(lights.shape == AREA_ELLIPSE, np.pi / 4, 1.0)
            ar = (kind == LIGHT_AREA) & (area > 0)
            radiance[ar] = strength[ar] / (np.pi * area[ar, None])
        soft = lights.soft_falloff_mask()
        sphere = ~soft & (radius > 0)
        q = np.zeros((n, lk.P_COUNT))
        q[:, lk.P_POS:lk.P_POS + 3] = m[:, :3, 3]
        q[:, lk.P_AX:lk.P_AX + 3] = axes[0]
        q[:, lk.P_AY:lk.P_AY + 3] = axes[1]
        q[:, lk.P_AZ:lk.P_AZ + 3] = axes[2]
        q[:, lk.P_STRENGTH:lk.P_STRENGTH + 3] = strength
        q[:, lk.P_RADIANCE:lk.P_RADIANCE + 3] = radiance
        q[:, lk.P_RADIUS] = radius
        q[:, lk.P_SPHERE] = sphere
        q[:, lk.P_SPOT] = kind == LIGHT_SPOT
        q[:, lk.P_COS_HALF] = cos_half
        q[:, lk.P_SMOOTH] = smooth
        q[:, lk.P_SUN_OMC] = sun_omc
        q[:, lk.P_SIZE_X:lk.P_SIZE_Y + 1] = size
        q[:, lk.P_ELLIPSE] = lights.shape == AREA_ELLIPSE
        q[:, lk.P_AREA] = area
        q[:, lk.P_KIND] = kind
        return LightSet(
            kind=kind, position=m[:, :3, 3].copy(), axis_x=axes[0], axis_y=axes[1], axis_z=axes[2],
            strength=strength, radiance=radiance, radius=radius, sphere=sphere,
            spot_cos_half=cos_half, spot_smooth=smooth, sun_one_minus_cos=sun_omc,
            shape=lights.shape.astype(np.int32), size=size, area=area,
            visible_camera=lights.visible_to_camera.astype(bool),
            visible_diffuse=lights.flag_mask("visible_to_diffuse"),
            visible_glossy=lights.flag_mask("visible_to_glossy"),
            visible_transmission=lights.flag_mask("visible_to_transmission"),
            cast_shadow=lights.cast_shadow.astype(bool),
            names=tuple(lights.names), params=q)

    def emits(self, i: int) -> bool:
        """Does light i carry any energy (so it is worth shadow rays)?"""
        if not np.any(self.strength[i] > 0):
            return False
        if self.kind[i] == LIGHT_AREA:
            return bool(self.area[i] > 0)
        return True


# --- batch sampling -------------------------------------------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _sample_direct_kernel(q, p, u1, u2, o_dir, o_dist, o_w, o_cos, o_ok):
    for i in prange(p.shape[0]):
        (o_dir[i, 0], o_dir[i, 1], o_dir[i, 2], o_dist[i], o_w[i, 0], o_w[i, 1], o_w[i, 2],
         o_cos[i], o_ok[i]) = lk.sample_light(q, p[i, 0], p[i, 1], p[i, 2], u1[i], u2[i])


def _outputs(n):
    return (np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros(n, bool))


def sample_direct(lights: LightSet, i: int, points: np.ndarray, u1: np.ndarray,
                  u2: np.ndarray) -> DirectSample:
    """Sample light i as seen from points (N, 3) float64 with uniforms u1, u2 (N,)."""
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    out = _outputs(p.shape[0])
    if p.shape[0]:
        _sample_direct_kernel(lights.params[i], p, np.ascontiguousarray(u1, np.float64),
                              np.ascontiguousarray(u2, np.float64), *out)
    return DirectSample(*out)


# --- emissive triangles ---------------------------------------------------------------------

@dataclass(frozen=True)
class EmissiveTriangles:
    """Triangles whose material emits, as one light sampled by area x radiance.

    triangle: (K,) int32 indices into the mesh; v0, e1, e2: (K, 3) float64 corners/edges;
    normal: (K, 3) unit; area: (K,) m^2; radiance: (K, 3) W/(m^2 sr), both sides;
    cdf: (K,) float64 increasing to 1; probability: (K,) selection probability.
    textured: None, or (K,) bool: the triangle's emission comes from a shader program
    (docs/shading.md, "Textured emission"): its ``radiance`` is then the program's mean
    over the triangle (stratified points, floored above 0), what picks the triangle; the
    radiance at a sampled point is the program's there (``rescale``).
    """

    triangle: np.ndarray
    v0: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    radiance: np.ndarray
    cdf: np.ndarray
    probability: np.ndarray
    textured: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.triangle.shape[0])

    def points(self, u0, u1, u2):
        """(j, b1, b2): the triangle (row) and barycentrics ``lk.sample_triangles`` and the
        photon emission pick with uniforms u0 (pick), u1, u2 (N,), vectorised."""
        j = sampling.pick_many(self.cdf, u0)
        su = np.sqrt(u1)
        return j, su * (1.0 - u2), su * u2

    def rescale(self, flux, j, b1, b2, d, emission_at) -> None:
        """Multiply flux (N, 3) in place, sampled with the triangles' ``radiance`` on rows
        j (N,) at barycentrics (b1, b2), by (emission there) / radiance[j] where the
        triangle is textured. d (N, 3): the direction arriving at the point from where it
        is seen (program inputs Incoming, Backfacing); emission_at(prim, u, v, d) -> (n,
        3) the emitted radiance at triangle prim, Embree barycentrics (u, v) =
        (b1, b2)."""
        if self.textured is None:
            return
        sel = np.flatnonzero(self.textured[j] & np.any(flux != 0, axis=1))
        if sel.size == 0:
            return
        js = j[sel]
        em = emission_at(self.triangle[js], b1[sel], b2[sel], np.asarray(d)[sel])
        flux[sel] *= em / self.radiance[js]

    @property
    def power(self) -> np.ndarray:
        """(3,) emitted flux, W: pi L A per side, two sides."""
        return 2.0 * np.pi * np.sum(self.radiance * self.area[:, None], axis=0)

    @staticmethod
    def from_mesh(mesh: Mesh, materials: Materials, textured=None) -> "EmissiveTriangles":
        """The emissive triangles of the mesh: those whose material's constant emission
        is > 0, and ``textured`` = (triangles (K',) int32, mean radiance (K', 3)) those
        whose emission a program computes (their material's constant is not used)."""
        if mesh.triangle_count == 0 or materials.count == 0:
            idx = np.zeros(0, np.int32)
        else:
            em = materials.emission.astype(np.float64)[mesh.material_index]
            lit = np.any(em > 0, axis=1)
            if textured is not None:
                programmed = np.zeros(mesh.triangle_count, bool)
                programmed[textured[0]] = True
                lit = (lit & ~programmed) | programmed
            idx = np.flatnonzero(lit).astype(np.int32)
        tv = mesh.triangle_vertices()[idx].astype(np.float64).reshape(-1, 3, 3)
        v0 = tv[:, 0]
        e1 = tv[:, 1] - v0
        e2 = tv[:, 2] - v0
        cr = np.cross(e1, e2)
        ln = np.linalg.norm(cr, axis=1)
        keep = ln > 0
        idx, v0, e1, e2, cr, ln = idx[keep], v0[keep], e1[keep], e2[keep], cr[keep], ln[keep]
        area = 0.5 * ln
        radiance = materials.emission.astype(np.float64)[mesh.material_index[idx]].reshape(-1, 3)
        flags = None
        if textured is not None:
            row = np.full(mesh.triangle_count, -1, np.int64)
            row[textured[0]] = np.arange(len(textured[0]))
            r = row[idx]
            flags = r >= 0
            mean = np.asarray(textured[1], np.float64)[r[flags]]
            # A floor keeps every programmed triangle pickable (a texture that the
            # stratified points miss still emits somewhere: the estimator stays unbiased).
            level = float(np.sum(mean * area[flags, None]) / max(area[flags].sum(), 1e-300))
            radiance[flags] = np.maximum(mean, max(1e-3 * level / 3.0, 1e-12))
        w = area * radiance.sum(axis=1)
        total = w.sum()
        prob = w / total if total > 0 else w
        cdf = np.cumsum(prob)
        if cdf.size:
            cdf[-1] = 1.0
        return EmissiveTriangles(idx, v0, e1, e2, cr / ln[:, None] if ln.size else cr, area,
                                 radiance, cdf, prob, flags)


@njit(cache=True, parallel=True, error_model="numpy")
def _sample_triangles_kernel(p, u0, u1, u2, cdf, prob, v0, e1, e2, nrm, area, radiance,
                             o_dir, o_dist, o_w, o_cos, o_ok):
    for i in prange(p.shape[0]):
        (o_dir[i, 0], o_dir[i, 1], o_dir[i, 2], o_dist[i], o_w[i, 0], o_w[i, 1], o_w[i, 2],
         o_cos[i], o_ok[i]) = lk.sample_triangles(cdf, prob, v0, e1, e2, nrm, area, radiance,
                                                  p[i, 0], p[i, 1], p[i, 2], u0[i], u1[i], u2[i])


def sample_emissive(tris: EmissiveTriangles, points: np.ndarray, u0: np.ndarray,
                    u1: np.ndarray, u2: np.ndarray) -> DirectSample:
    """Sample the emissive triangles from points (N, 3) with uniforms u0 (pick), u1, u2."""
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    out = _outputs(p.shape[0])
    if p.shape[0] and tris.count:
        _sample_triangles_kernel(p, np.ascontiguousarray(u0, np.float64),
                                 np.ascontiguousarray(u1, np.float64),
                                 np.ascontiguousarray(u2, np.float64), tris.cdf, tris.probability,
                                 tris.v0, tris.e1, tris.e2, tris.normal, tris.area, tris.radiance,
                                 *out)
    return DirectSample(*out)


# --- rays hitting lights (camera and specular paths) -----------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _intersect_kernel(q, o, d, tmax, bsdf_pdf, n_light, seen, l_out, t_out):
    """Add light q's radiance to every ray that meets it before tmax (lights are not
    occluders: a ray passes through every light in front of the geometry), weighted
    against light sampling by the power heuristic where the ray was BSDF-sampled with
    solid-angle pdf bsdf_pdf > 0 (n_light light samples per light at that vertex);
    t_out[i] the distance to the light where it is met."""
    for i in prange(o.shape[0]):
        t, l0, l1, l2 = lk.intersect_light(q, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2])
        if not t < tmax[i]:
            continue
        w = 1.0
        if bsdf_pdf[i] > 0.0:
            pl = lk.light_pdf(q, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t)
            w = lk.power_heuristic(1.0, bsdf_pdf[i], n_light, pl)
        seen[i] = True
        t_out[i] = t
        l_out[i, 0] += w * l0
        l_out[i, 1] += w * l1
        l_out[i, 2] += w * l2


@njit(cache=True, parallel=True, error_model="numpy")
def _sun_disc_kernel(q, d, escaped, bsdf_pdf, n_light, seen, acc):
    """The sun disc of light q on the rays that escape the geometry within it."""
    one_minus_cos = q[lk.P_SUN_OMC]
    for i in prange(d.shape[0]):
        if not escaped[i]:
            continue
        # 1 - cos(angle to the sun's direction) <= 1 - cos(half angle), without cancellation.
        one_minus = 1.0 - (d[i, 0] * q[lk.P_AZ] + d[i, 1] * q[lk.P_AZ + 1]
                           + d[i, 2] * q[lk.P_AZ + 2])
        if one_minus <= one_minus_cos:
            w = 1.0
            if bsdf_pdf[i] > 0.0:
                w = lk.power_heuristic(1.0, bsdf_pdf[i], n_light,
                                       1.0 / (2.0 * np.pi * one_minus_cos))
            seen[i] = True
            acc[i, 0] += w * q[lk.P_RADIANCE]
            acc[i, 1] += w * q[lk.P_RADIANCE + 1]
            acc[i, 2] += w * q[lk.P_RADIANCE + 2]


def intersect_lights(lights: LightSet, which: np.ndarray, origins: np.ndarray,
                     directions: np.ndarray, tmax: np.ndarray, bsdf_pdf: np.ndarray | None = None,
                     light_samples: int = 1, transmittance=None) -> tuple[np.ndarray, np.ndarray]:
    """The light surfaces each ray passes in front of the geometry (tmax) and their
    radiance: lights are not occluders, as in Cycles (a ray goes on through an area
    light's quad to the ceiling behind it), so every light in front counts.

    which: (L,) bool, the lights this kind of ray may see (camera / glossy / transmission).
    tmax: (N,) distance to the nearest geometry (inf on a miss). bsdf_pdf: (N,) solid-angle
    pdf with which each ray's direction was BSDF-sampled, 0 (or None) where the ray is not
    weighed against light sampling (camera rays, delta lobes); where > 0, each light's
    radiance is weighted by the power heuristic against ``light_samples`` samples of
    ``lk.light_pdf``. Returns seen (N,) bool and radiance (N, 3) float64 W/(m^2 sr) (0
    where none is seen). Point and spot lights of radius 0 are never hit; a sun disc only
    by rays that escape the geometry.

    transmittance: None (vacuum) or a function (rows (K,) int64, t (K,) float64 metres)
    -> (K, 3) the transmittance of the rays' media from their origins to distance t (inf:
    a sun disc): each light's radiance is attenuated to the light itself, not to the
    geometry behind it.
    """
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    tm = np.ascontiguousarray(tmax, np.float64)
    n = o.shape[0]
    seen = np.zeros(n, bool)
    l_out = np.zeros((n, 3))
    if n == 0:
        return seen, l_out
    pdf = np.zeros(n) if bsdf_pdf is None else np.ascontiguousarray(bsdf_pdf, np.float64)
    escaped = np.isinf(tm)
    t_light = np.full(n, np.inf)
    for i in range(lights.count):
        if not which[i] or not np.any(lights.radiance[i] > 0):
            continue
        # Through a medium each light goes to a buffer of its own, attenuated to its distance.
        s_i, l_i = (seen, l_out) if transmittance is None else (np.zeros(n, bool), np.zeros((n, 3)))
        if int(lights.kind[i]) == LIGHT_SUN:
            _sun_disc_kernel(lights.params[i], d, escaped, pdf, float(light_samples), s_i, l_i)
            t_light[:] = np.inf
        else:
            _intersect_kernel(lights.params[i], o, d, tm, pdf, float(light_samples), s_i, l_i,
                              t_light)
        if transmittance is not None:
            rows = np.flatnonzero(s_i)
            if rows.size:
                seen[rows] = True
                l_out[rows] += l_i[rows] * transmittance(rows, t_light[rows])
    return seen, l_out


# --- world -----------------------------------------------------------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _sample_world_kernel(radiance, n_s, u1, u2, o_dir, o_dist, o_w, o_cos, o_ok):
    for i in prange(n_s.shape[0]):
        (o_dir[i, 0], o_dir[i, 1], o_dir[i, 2], o_dist[i], o_w[i, 0], o_w[i, 1], o_w[i, 2],
         o_cos[i], o_ok[i]) = lk.sample_world(radiance[0], radiance[1], radiance[2], n_s[i, 0],
                                              n_s[i, 1], n_s[i, 2], u1[i], u2[i])


def sample_world(radiance: np.ndarray, normals: np.ndarray, u1: np.ndarray,
                 u2: np.ndarray) -> DirectSample:
    """Cosine-weighted directions about unit normals (N, 3) towards a uniform background.

    weight = L pi / cos (the cosine pdf), so f |cos| weight = f L pi. Distance inf.
    """
    ns = np.ascontiguousarray(normals, np.float64).reshape(-1, 3)
    out = _outputs(ns.shape[0])
    if ns.shape[0]:
        _sample_world_kernel(np.asarray(radiance, np.float64).reshape(3), ns,
                             np.ascontiguousarray(u1, np.float64),
                             np.ascontiguousarray(u2, np.float64), *out)
    return DirectSample(*out)

"""Photon emission: where photons leave the lights, in which direction, with what flux.

Units are those of lights.py (Cycles'): strength S = colour x power.

- Point / spot, radius r: intensity I(w) = S / (4 pi) x spot falloff(w) in every direction
  w. Radius r > 0 is emitted as what it is seen as from direction w: the disk of radius r
  perpendicular to w (Blender's soft falloff), or, for a sphere, the same disk lifted onto
  the sphere's front surface; uniform points on that disk and uniform w give exactly a
  Lambertian sphere of radiance S / (4 pi^2 r^2). Total flux S (point),
  S / (4 pi) x integral of the falloff over the cone (spot).
- Soft falloff (radius r > 0, not a sphere): Cycles' light, and the shadow rays'
  (``lights.kernels``), is a disk of radius r and the same radiance L = S / (4 pi^2 r^2)
  centred on the light's centre c and facing the receiving point X, which sees it under
  atan(r / d), d = |X - c|, where the rays above (a sphere's field) reach X from
  asin(r / d). Those rays hold every ray of the facing disk, with density known in ray
  space (dA_perp dw), so a photon keeps its ray and flux and is tested at its first event
  X: does its line cross the plane through c perpendicular to X - c within r of c? With
  h the line's distance from c and a = (X - c) . w the event's distance along the line
  past the foot of c (its distance t along the ray: the origin is that foot), the
  crossing lies d h / a from c, so the test is a >= near = h^2 / sqrt(r^2 - h^2): the
  photon carries nothing when its first event is closer than ``near`` and its flux
  unchanged beyond (the radiances are equal and its spot falloff, by w, is what the
  shadow ray from X takes towards the same disk point). Later events inherit it. The
  disk point lies h^2 / t behind the origin, inside the light's ball, and the photon
  takes that stretch's transmittance at its first event (core/photons/tracing.py).
  Share of the rays reaching a point at d = r that pass: 0.29 (0.79 at 2 r, 0.96 at 5 r).
- Spot: directions uniform in the cone of half angle spot_size / 2 about -Z, each photon
  weighted by Cycles' smoothstep falloff.
- Sun: directions uniform in the sun's cone; for each, a point uniform on the disc of the
  scene's bounding sphere perpendicular to it (radius R), the photon starting where that
  ray crosses a plane beyond the sphere on the sun's side. The flux is the radiance over
  the cone times pi R^2: S pi R^2 x 2 / (1 + cos h) (S pi R^2 for a point-like sun: the
  irradiance S on a surface facing the sun times the disc's area).
- Area: one-sided, uniform on the rectangle / ellipse, cosine-weighted about -Z; flux S.
- Emissive triangles: picked by area x radiance (``lights.EmissiveTriangles``), uniform
  on the triangle, either side with probability 1/2, cosine-weighted; flux 2 pi L A.
- World background: uniform directions, origins on a disc of the scene's bounding
  sphere's radius perpendicular to the direction, flux L x pi R^2 x 4 pi.

Every photon carries flux (3,) watts = (emitted radiance x cosine) / (pdf x photons of
the light), so the flux of a light's photons sums, in expectation, to the light's power.

Aimed emission (the projection map, for caustic photons): the same lights emit only
towards a set of target spheres (bounding spheres of specular objects). A target is picked
with a fixed probability p_j, a direction uniform in the cone subtending it (sun: a point
uniform on its cross-section perpendicular to the sampled direction), and the flux is divided by the mixture pdf
sum_k p_k pdf_k, so overlapping targets are not counted twice and the estimate stays
unbiased for every direction the cones cover.

A point or spot light of radius r > 0 aims lines, not directions (its photons' origins
spread over r, so a direction aimed from its centre mostly misses a small target: 1-4 %
hit a 0.25 m sphere under a 1 m light). A line c + h + t w (c the light's centre, h its
offset, perpendicular to w) is sampled as: a target j (centre T_j, radius R_j) by its
cdf; w uniform in the narrower of the cone subtending the target grown by r from c
(every direction when c lies inside it; every ray from the light's ball into the target
lies in it) and the spot's cone; the line's point uniform on the target's cross-section
perpendicular to w (the disk of radius R_j about T_j), or on the light's (radius r about
c) when the target is larger. A line more than r from c carries nothing (no unaimed
photon lies on it). The photon starts where the unaimed photon on the same line does
(the sphere's front surface, or the soft-falloff foot c + h with near / lead of
|h|^2), and carries L x att / (pdf x N) with L = S / (4 pi^2 r^2) the radiance per line
of the unaimed emission (density pdf_dir / (pi r^2) in dA_perp dw) and pdf the mixture
sum over the targets k whose cone holds w and whose disk holds the line of
p_k / (2 pi (1 - cos) x pi min(R_k, r)^2) (``_line_pdf_mix``).

Random numbers: scrambled Sobol pairs (``sampling.stratified2``) over each light's photons
for the position and direction, and counter hashes for the discrete picks; a photon's
numbers depend only on (seed, map, light, photon index).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..scene import geometry
from ..lights import kernels as lk
from .. import sampling
from ..lights.light_set import EmissiveTriangles, LightSet
from ..scene.bounds import Targets
from ..scene.contract import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN

# Source ids after the analytic lights (index L) for emissive triangles and the world.
SOURCE_TRIANGLES = -1
SOURCE_WORLD = -2
# Bounding spheres are grown by this fraction so float rounding never clips a photon.


@dataclass(frozen=True)
class Source:
    """One emitter: an analytic light (index >= 0), the emissive triangles or the world.

    power: (3,) float64 W, total flux it emits (aimed: the flux towards the targets,
    an estimate used only to share photons); name: for stats.
    """

    index: int
    power: np.ndarray
    name: str


@dataclass(frozen=True)
class Emitted:
    """A batch of photons leaving the lights (float64).

    origin: (N, 3) metres; direction: (N, 3) unit; flux: (N, 3) watts per photon.
    near, lead: (N,) float64 or None, the photons of a soft-falloff light (module doc,
    "Soft falloff"): a photon's first event (surface hit or collision in a medium) at a
    distance t < near[i] metres along its first ray carries nothing; at t >= near[i] the
    point of the facing disk its light comes from lies lead[i] / t metres behind its
    origin (lead = h^2 m^2, h the line's distance from the light's centre), a stretch
    whose transmittance the photon takes at that event.
    """

    origin: np.ndarray
    direction: np.ndarray
    flux: np.ndarray
    near: np.ndarray | None = None
    lead: np.ndarray | None = None


def boxes_in_front(targets: Targets, point, normal, slack: float = 0.0) -> np.ndarray:
    """(K,) bool: does any corner of each target's box lie strictly in front of the plane
    through ``point`` with unit ``normal`` (by more than -slack)? When no corner does, the
    whole box (their convex hull) is behind: nothing emitted into the front half-space
    can reach it. Without boxes, the spheres are tested."""
    p = np.asarray(point, np.float64)
    n = np.asarray(normal, np.float64)
    if targets.lo is None:
        return (targets.centre - p) @ n + targets.radius > -slack
    corners = np.stack([np.where(np.array([(c >> k) & 1 for k in range(3)], bool),
                                 targets.hi, targets.lo) for c in range(8)], axis=1)
    return np.any((corners - p) @ n > -slack, axis=1) & (targets.radius >= 0)


# --- light power ----------------------------------------------------------------------------

def spot_cone_integral(cos_half: float, smooth: float) -> float:
    """integral over cos(angle) in [cos_half, 1] of Cycles' smoothstep falloff.

    With x = (c - cos_half) smooth and X = (1 - cos_half) smooth: integral of
    smoothstep(x) dx / smooth, = X^3 - X^4 / 2 below 1 and X - 1/2 above.
    """
    width = 1.0 - cos_half
    if not np.isfinite(smooth):
        return width
    x = width * smooth
    return (x ** 3 - 0.5 * x ** 4) / smooth if x < 1.0 else (x - 0.5) / smooth


def cone_hits_sphere(apex, axis, cos_half: float, centre, radius) -> np.ndarray:
    """(K,) bool: does the cone (apex (3,), unit axis (3,), half angle acos(cos_half))
    reach any of the spheres (K, 3), (K,)? Conservative (may say yes when no)."""
    v = np.asarray(centre, np.float64) - np.asarray(apex, np.float64)
    d = np.linalg.norm(v, axis=1)
    radius = np.asarray(radius, np.float64)
    inside = d <= radius
    with np.errstate(invalid="ignore", divide="ignore"):
        ang = np.arccos(np.clip(v @ axis / np.where(d > 0, d, 1.0), -1.0, 1.0))
        spread = np.arcsin(np.clip(radius / np.where(d > 0, d, 1.0), 0.0, 1.0))
    half = np.arccos(np.clip(cos_half, -1.0, 1.0))
    return (inside | (ang - spread <= half + 1e-9)) & (radius >= 0)


def sun_plane(light_set: LightSet, i: int, centre, radius: float) -> np.ndarray:
    """A point of the plane, perpendicular to sun i's axis, from which its photons start:
    just outside the sphere (centre, radius) on the sun's side, so no geometry lies
    between the plane and the sun."""
    return np.asarray(centre, np.float64) + light_set.axis_z[i] * (1.05 * radius + 1e-9)


def sun_power(light_set: LightSet, i: int, radius: float) -> np.ndarray:
    """(3,) W the sun sends through a sphere of the given radius: for each direction of
    its cone, radiance L across the sphere's cross-section pi R^2, i.e.
    L x 2 pi (1 - cos h) x pi R^2 = S pi R^2 x 2 / (1 + cos h) (S for a point sun)."""
    omc = float(light_set.sun_one_minus_cos[i])
    return light_set.strength[i] * np.pi * radius ** 2 * 2.0 / (2.0 - omc)


def source_powers(light_set: LightSet, emissive: EmissiveTriangles, world_radiance,
                  scene_centre, scene_radius: float, geometry_spheres: Targets | None,
                  with_world: bool) -> list[Source]:
    """The sources that emit photons, with their total flux (W, RGB).

    Zero-power lights are left out, and so are lights that provably reach no geometry:
    a spot whose cone misses every object's bounding sphere, an area light with every
    object behind its plane.
    """
    out = []
    for i in range(light_set.count):
        k = int(light_set.kind[i])
        s = light_set.strength[i]
        if not np.any(s > 0):
            continue
        name = light_set.names[i] if i < len(light_set.names) else f"light {i}"
        if k == LIGHT_POINT:
            power = s.copy()
        elif k == LIGHT_SPOT:
            frac = spot_cone_integral(light_set.spot_cos_half[i], light_set.spot_smooth[i]) / 2.0
            power = s * frac
            if geometry_spheres is not None:
                reach = cone_hits_sphere(
                    light_set.position[i], -light_set.axis_z[i], light_set.spot_cos_half[i],
                    geometry_spheres.centre, geometry_spheres.radius + light_set.radius[i])
                if light_set.spot_cos_half[i] >= 0.0:
                    # A cone of at most 90 degrees lies in front of the plane through
                    # its apex: boxes wholly behind it are out of reach.
                    reach &= boxes_in_front(geometry_spheres, light_set.position[i],
                                            -light_set.axis_z[i], light_set.radius[i])
                if not np.any(reach):
                    continue
        elif k == LIGHT_SUN:
            power = sun_power(light_set, i, scene_radius)
        elif k == LIGHT_AREA:
            if light_set.area[i] <= 0:
                continue
            power = s.copy()
            # One-sided: it lights only the half-space in front of its plane.
            if geometry_spheres is not None and not np.any(boxes_in_front(
                    geometry_spheres, light_set.position[i], -light_set.axis_z[i])):
                continue
        else:
            continue
        if np.any(power > 0):
            out.append(Source(i, power, name))
    if emissive.count:
        out.append(Source(SOURCE_TRIANGLES, emissive.power, "emissive triangles"))
    w = np.asarray(world_radiance, np.float64).reshape(3)
    if with_world and np.any(w > 0) and scene_radius > 0:
        out.append(Source(SOURCE_WORLD, w * 4.0 * np.pi * np.pi * scene_radius ** 2, "world"))
    return out


def allocate(weights: np.ndarray, total: int) -> np.ndarray:
    """Split ``total`` photons in proportion to weights (largest remainder), int64."""
    w = np.asarray(weights, np.float64)
    if total <= 0 or w.size == 0 or w.sum() <= 0:
        return np.zeros(w.size, np.int64)
    exact = w / w.sum() * total
    n = np.floor(exact).astype(np.int64)
    rest = total - int(n.sum())
    order = np.argsort(-(exact - n), kind="stable")
    n[order[:rest]] += 1
    return n


# --- kernels ------------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _target_cone(px, py, pz, tx, ty, tz, r):
    """The cone a sphere (centre t, radius r, metres) subtends from the point p: v = t - p
    (metres, the cone's axis unnormalised), its length dn (metres) and 1 - cos(half
    angle); (v, 0, 2) when p lies inside the sphere (every direction)."""
    vx, vy, vz = tx - px, ty - py, tz - pz
    d2 = vx * vx + vy * vy + vz * vz
    r2 = r * r
    if d2 <= r2:
        return vx, vy, vz, 0.0, 2.0
    return vx, vy, vz, np.sqrt(d2), lk.sin_sqr_to_one_minus_cos(r2 / d2)


@njit(cache=True, error_model="numpy")
def _disk_offset(u1, u2, dx, dy, dz, rho):
    """A point uniform on the disk of radius rho (metres) about the origin perpendicular to
    the unit d: its offset (metres) and the unit-disk point (x, y) it came from."""
    x, y = sampling.concentric_disk(u1, u2)
    tx, ty, tz, bx, by, bz = sampling.basis(dx, dy, dz)
    return rho * (x * tx + y * bx), rho * (x * ty + y * by), rho * (x * tz + y * bz), x, y


@njit(cache=True, error_model="numpy")
def _cone_pdf_mix(px, py, pz, dx, dy, dz, tc, tr, tp):
    """Mixture pdf (1/sr) of direction d from point p over the target cones."""
    pdf = 0.0
    for k in range(tr.shape[0]):
        if tp[k] <= 0.0:
            continue
        vx, vy, vz, dn, omc = _target_cone(px, py, pz, tc[k, 0], tc[k, 1], tc[k, 2], tr[k])
        if omc >= 2.0:
            pdf += tp[k] / (4.0 * np.pi)
            continue
        c = (vx * dx + vy * dy + vz * dz) / dn
        if 1.0 - c <= omc:
            pdf += tp[k] / (2.0 * np.pi * omc)
    return pdf


@njit(cache=True, error_model="numpy")
def _aim(px, py, pz, tc, tr, tcdf, u0, u1, u2):
    """Pick a target by its cdf and a direction uniform in the cone it subtends from p."""
    j = sampling.pick(tcdf, u0)
    vx, vy, vz, dn, omc = _target_cone(px, py, pz, tc[j, 0], tc[j, 1], tc[j, 2], tr[j])
    if omc >= 2.0:
        return sampling.uniform_sphere(u1, u2)
    x, y, z = sampling.uniform_cone(u1, u2, omc)
    return sampling.to_world(x, y, z, vx / dn, vy / dn, vz / dn)


@njit(cache=True, error_model="numpy")
def facing_disk_near(h2, r2):
    """The least distance a (metres) past the foot of the light's centre c at which a
    point X of a line at squared distance h2 from c sees that line cross the disk of
    squared radius r2 through c facing X: h^2 / sqrt(r^2 - h^2) (module doc, "Soft
    falloff"); inf when the line misses every such disk (h >= r)."""
    if h2 >= r2:
        return np.inf
    return h2 / np.sqrt(r2 - h2)


@njit(cache=True, error_model="numpy")
def _line_cone(cx, cy, cz, tx, ty, tz, grown, spot, omc_spot, azx, azy, azz):
    """The cone a line aimed at one target takes its direction from (module doc, "Aimed
    emission"): the cone subtending the target's sphere, centre t (metres), grown by the
    light's radius (``grown`` metres), from the light's centre c (every direction when c
    lies inside it), or the spot's cone about -Z (1 - cos = omc_spot) when that one is
    narrower. Returns its unit axis and 1 - cos(half angle) (2: the whole sphere)."""
    vx, vy, vz, dn, omc = _target_cone(cx, cy, cz, tx, ty, tz, grown)
    ax, ay, az = 0.0, 0.0, 1.0
    if omc < 2.0:
        ax, ay, az = vx / dn, vy / dn, vz / dn
    if spot and omc_spot < omc:
        return -azx, -azy, -azz, omc_spot
    return ax, ay, az, omc


@njit(cache=True, error_model="numpy")
def _aim_line(q, tc, tr, tcdf, u0, u1, u2, u3, u4):
    """One aimed line of a point or spot light of radius r > 0 (metres): a target j by
    its cdf, a direction uniform in its ``_line_cone``, and the line's offset uniform on
    the target's cross-section perpendicular to it (on the light's disk, radius r about
    its centre c, when the target is larger). Returns j, the unit direction and the
    line's offset h from c (metres, perpendicular to the direction: the line is
    c + h + t w)."""
    cx, cy, cz = q[lk.P_POS], q[lk.P_POS + 1], q[lk.P_POS + 2]
    radius = q[lk.P_RADIUS]
    j = sampling.pick(tcdf, u0)
    ax, ay, az, omc = _line_cone(cx, cy, cz, tc[j, 0], tc[j, 1], tc[j, 2], tr[j] + radius,
                                 q[lk.P_SPOT] > 0.0, 1.0 - q[lk.P_COS_HALF],
                                 q[lk.P_AZ], q[lk.P_AZ + 1], q[lk.P_AZ + 2])
    x, y, z = sampling.uniform_cone(u1, u2, omc)
    dx, dy, dz = sampling.to_world(x, y, z, ax, ay, az)
    if tr[j] <= radius:
        px, py, pz, rho = tc[j, 0] - cx, tc[j, 1] - cy, tc[j, 2] - cz, tr[j]
    else:
        px, py, pz, rho = 0.0, 0.0, 0.0, radius
    ox, oy, oz, _, _ = _disk_offset(u3, u4, dx, dy, dz, rho)
    px += ox
    py += oy
    pz += oz
    along = px * dx + py * dy + pz * dz
    return j, dx, dy, dz, px - along * dx, py - along * dy, pz - along * dz


@njit(cache=True, error_model="numpy")
def _line_pdf_mix(q, j, dx, dy, dz, hx, hy, hz, tc, tr, tp):
    """Mixture pdf, 1 / (m^2 sr) (line measure dA_perp dw), of the line c + h + t d
    sampled by ``_aim_line`` for target j: the sum over the targets k whose cone and
    disk hold it of p_k / (solid angle of the cone x area of the disk). Target j holds it
    by construction (no rounding test)."""
    cx, cy, cz = q[lk.P_POS], q[lk.P_POS + 1], q[lk.P_POS + 2]
    radius = q[lk.P_RADIUS]
    spot = q[lk.P_SPOT] > 0.0
    omc_spot = 1.0 - q[lk.P_COS_HALF]
    pdf = 0.0
    for k in range(tr.shape[0]):
        if tp[k] <= 0.0:
            continue
        ax, ay, az, omc = _line_cone(cx, cy, cz, tc[k, 0], tc[k, 1], tc[k, 2], tr[k] + radius,
                                     spot, omc_spot, q[lk.P_AZ], q[lk.P_AZ + 1], q[lk.P_AZ + 2])
        rho = min(tr[k], radius)
        if rho <= 0.0:
            continue
        if k != j:
            if omc < 2.0 and 1.0 - (dx * ax + dy * ay + dz * az) > omc:
                continue
            if tr[k] <= radius:
                # The line's squared distance from the target's centre.
                ex, ey, ez = tc[k, 0] - cx - hx, tc[k, 1] - cy - hy, tc[k, 2] - cz - hz
                along = ex * dx + ey * dy + ez * dz
                if ex * ex + ey * ey + ez * ez - along * along > tr[k] * tr[k] * (1.0 + 1e-9):
                    continue
        pdf += tp[k] / (2.0 * np.pi * omc * np.pi * rho * rho)
    return pdf


@njit(cache=True, parallel=True, error_model="numpy")
def _emit_local(q, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f, near, lead):
    """Point and spot lights (see module doc); aimed when there are targets (a light of
    radius > 0: ``_aim_line``). near, lead (N,): written for a soft-falloff light of
    radius > 0 (``Emitted``), else left."""
    cx, cy, cz = q[lk.P_POS], q[lk.P_POS + 1], q[lk.P_POS + 2]
    azx, azy, azz = q[lk.P_AZ], q[lk.P_AZ + 1], q[lk.P_AZ + 2]
    radius = q[lk.P_RADIUS]
    r2 = radius * radius
    spot = q[lk.P_SPOT] > 0.0
    sphere = q[lk.P_SPHERE] > 0.0
    omc_spot = 1.0 - q[lk.P_COS_HALF]
    aimed = tr.shape[0] > 0
    for i in prange(o.shape[0]):
        # The line c + h + t d, and (sphere) how far along it the origin is lifted.
        hx, hy, hz, h2, lift = 0.0, 0.0, 0.0, 0.0, 0.0
        if aimed and radius > 0.0:
            j, dx, dy, dz, hx, hy, hz = _aim_line(q, tc, tr, tcdf, u0[i], u1[i], u2[i],
                                                  u3[i], u4[i])
            h2 = hx * hx + hy * hy + hz * hz
            # As a pdf of the direction times the light's disk area pi r^2 (that of
            # unaimed emission): a line off the light's disk carries nothing.
            pdf = 0.0
            if h2 <= r2:
                pdf = np.pi * r2 * _line_pdf_mix(q, j, dx, dy, dz, hx, hy, hz, tc, tr, tp)
            if sphere:
                lift = np.sqrt(max(0.0, r2 - h2))
        else:
            if aimed:
                dx, dy, dz = _aim(cx, cy, cz, tc, tr, tcdf, u0[i], u1[i], u2[i])
                pdf = _cone_pdf_mix(cx, cy, cz, dx, dy, dz, tc, tr, tp)
            elif spot:
                x, y, z = sampling.uniform_cone(u1[i], u2[i], omc_spot)
                dx, dy, dz = sampling.to_world(x, y, z, -azx, -azy, -azz)
                pdf = 1.0 / (2.0 * np.pi * omc_spot)
            else:
                dx, dy, dz = sampling.uniform_sphere(u1[i], u2[i])
                pdf = 1.0 / (4.0 * np.pi)
            if radius > 0.0:
                hx, hy, hz, x, y = _disk_offset(u3[i], u4[i], dx, dy, dz, radius)
                h2 = r2 * (x * x + y * y)
                if sphere:
                    lift = radius * np.sqrt(max(0.0, 1.0 - x * x - y * y))
        att = 1.0
        if spot:
            att = lk.spot_attenuation(-(dx * azx + dy * azy + dz * azz), q[lk.P_COS_HALF],
                                      q[lk.P_SMOOTH])
        w = 0.0 if pdf <= 0.0 else att * inv_n / (4.0 * np.pi * pdf)
        f[i, 0] = q[lk.P_STRENGTH] * w
        f[i, 1] = q[lk.P_STRENGTH + 1] * w
        f[i, 2] = q[lk.P_STRENGTH + 2] * w
        d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz
        ox, oy, oz = cx, cy, cz
        if radius > 0.0:
            # The origin of the unaimed photon on the same line: on the sphere's front
            # surface, or (soft falloff) the foot of c.
            ox += hx + lift * dx
            oy += hy + lift * dy
            oz += hz + lift * dz
            if not sphere:
                lead[i] = h2
                near[i] = facing_disk_near(h2, r2)
        o[i, 0], o[i, 1], o[i, 2] = ox, oy, oz


@njit(cache=True, parallel=True, error_model="numpy")
def _emit_area(q, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f):
    """Area light: uniform point, cosine about -Z (or aimed at the targets)."""
    azx, azy, azz = q[lk.P_AZ], q[lk.P_AZ + 1], q[lk.P_AZ + 2]
    sx, sy = q[lk.P_SIZE_X], q[lk.P_SIZE_Y]
    aimed = tr.shape[0] > 0
    for i in prange(o.shape[0]):
        if q[lk.P_ELLIPSE] > 0.0:
            x, y = sampling.concentric_disk(u3[i], u4[i])
            x *= 0.5 * sx
            y *= 0.5 * sy
        else:
            x = (u3[i] - 0.5) * sx
            y = (u4[i] - 0.5) * sy
        px = q[lk.P_POS] + x * q[lk.P_AX] + y * q[lk.P_AY]
        py = q[lk.P_POS + 1] + x * q[lk.P_AX + 1] + y * q[lk.P_AY + 1]
        pz = q[lk.P_POS + 2] + x * q[lk.P_AX + 2] + y * q[lk.P_AY + 2]
        if aimed:
            dx, dy, dz = _aim(px, py, pz, tc, tr, tcdf, u0[i], u1[i], u2[i])
            cos = -(dx * azx + dy * azy + dz * azz)
            pdf = _cone_pdf_mix(px, py, pz, dx, dy, dz, tc, tr, tp)
            # L cos / (pdf_area pdf_dir) with L = S / (pi A), pdf_area = 1 / A.
            w = cos / (np.pi * pdf) if cos > 0.0 and pdf > 0.0 else 0.0
        else:
            lx, ly, lz = sampling.cosine_hemisphere(u1[i], u2[i])
            dx, dy, dz = sampling.to_world(lx, ly, lz, -azx, -azy, -azz)
            w = 1.0 if lz > 0.0 else 0.0
        w *= inv_n
        f[i, 0] = q[lk.P_STRENGTH] * w
        f[i, 1] = q[lk.P_STRENGTH + 1] * w
        f[i, 2] = q[lk.P_STRENGTH + 2] * w
        o[i, 0], o[i, 1], o[i, 2] = px, py, pz
        d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz


@njit(cache=True, parallel=True, error_model="numpy")
def _emit_triangles(cdf, prob, v0, e1, e2, nrm, area, radiance, u0, u1, u2, u3, u4, u5, inv_n,
                    tc, tr, tp, tcdf, extent, o, d, f):
    """Emissive triangles, two-sided Lambertian (or aimed at the targets). Origins are
    moved off the triangle by ``geometry.offset_eps`` on the side the photon leaves
    towards: the triangle is geometry, and must not stop its own photons."""
    aimed = tr.shape[0] > 0
    for i in prange(o.shape[0]):
        j = sampling.pick(cdf, u5[i])
        b1, b2 = sampling.uniform_triangle(u3[i], u4[i])
        px = v0[j, 0] + b1 * e1[j, 0] + b2 * e2[j, 0]
        py = v0[j, 1] + b1 * e1[j, 1] + b2 * e2[j, 1]
        pz = v0[j, 2] + b1 * e1[j, 2] + b2 * e2[j, 2]
        nx, ny, nz = nrm[j, 0], nrm[j, 1], nrm[j, 2]
        if prob[j] <= 0.0:
            w = 0.0
            dx, dy, dz = nx, ny, nz
        elif aimed:
            dx, dy, dz = _aim(px, py, pz, tc, tr, tcdf, u0[i], u1[i], u2[i])
            cos = abs(dx * nx + dy * ny + dz * nz)
            pdf = _cone_pdf_mix(px, py, pz, dx, dy, dz, tc, tr, tp)
            w = cos * area[j] / (prob[j] * pdf) if pdf > 0.0 else 0.0
        else:
            # u0 picks the side; both sides emit, so the side pdf 1/2 doubles the flux.
            s = 1.0 if u0[i] < 0.5 else -1.0
            lx, ly, lz = sampling.cosine_hemisphere(u1[i], u2[i])
            dx, dy, dz = sampling.to_world(lx, ly, lz, s * nx, s * ny, s * nz)
            w = 2.0 * np.pi * area[j] / prob[j] if lz > 0.0 else 0.0
        w *= inv_n
        f[i, 0] = radiance[j, 0] * w
        f[i, 1] = radiance[j, 1] * w
        f[i, 2] = radiance[j, 2] * w
        e = geometry.offset_eps(px, py, pz, extent)
        if dx * nx + dy * ny + dz * nz < 0.0:
            e = -e
        o[i, 0], o[i, 1], o[i, 2] = px + e * nx, py + e * ny, pz + e * nz
        d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz


@njit(cache=True, parallel=True, error_model="numpy")
def _emit_sun(q, plane, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f):
    """Sun: a direction w uniform in the cone, then a target sphere (the scene's bounding
    sphere when unaimed) and a point uniform on its cross-section perpendicular to w; the
    photon starts where that ray crosses the emission plane. Flux: L dw dA_perp divided
    by the mixture pdf of the cross-sections the ray goes through."""
    azx, azy, azz = q[lk.P_AZ], q[lk.P_AZ + 1], q[lk.P_AZ + 2]
    omc = q[lk.P_SUN_OMC]
    for i in prange(o.shape[0]):
        if omc > 0.0:
            lx, ly, lz = sampling.uniform_cone(u1[i], u2[i], omc)
            dx, dy, dz = sampling.to_world(lx, ly, lz, -azx, -azy, -azz)
            # Radiance over the cone, pdf 1 / (2 pi omc).
            w0 = q[lk.P_RADIANCE] * 2.0 * np.pi * omc
            w1 = q[lk.P_RADIANCE + 1] * 2.0 * np.pi * omc
            w2 = q[lk.P_RADIANCE + 2] * 2.0 * np.pi * omc
        else:
            dx, dy, dz = -azx, -azy, -azz
            w0, w1, w2 = q[lk.P_STRENGTH], q[lk.P_STRENGTH + 1], q[lk.P_STRENGTH + 2]
        j = sampling.pick(tcdf, u0[i])
        ex, ey, ez, _, _ = _disk_offset(u3[i], u4[i], dx, dy, dz, tr[j])
        yx, yy, yz = tc[j, 0] + ex, tc[j, 1] + ey, tc[j, 2] + ez
        pdf = 0.0
        for k in range(tr.shape[0]):
            ex, ey, ez = yx - tc[k, 0], yy - tc[k, 1], yz - tc[k, 2]
            along = ex * dx + ey * dy + ez * dz
            perp2 = ex * ex + ey * ey + ez * ez - along * along
            if perp2 <= tr[k] * tr[k] * (1.0 + 1e-9):
                pdf += tp[k] / (np.pi * tr[k] * tr[k])
        # Back along the ray to the plane (d . az < 0, the point is below the plane).
        cos_p = dx * azx + dy * azy + dz * azz
        t = ((yx - plane[0]) * azx + (yy - plane[1]) * azy + (yz - plane[2]) * azz) / cos_p
        s = inv_n / pdf if pdf > 0.0 and cos_p < 0.0 else 0.0
        f[i, 0], f[i, 1], f[i, 2] = w0 * s, w1 * s, w2 * s
        o[i, 0], o[i, 1], o[i, 2] = yx - t * dx, yy - t * dy, yz - t * dz
        d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz


@njit(cache=True, parallel=True, error_model="numpy")
def _emit_world(radiance, centre, radius, u1, u2, u3, u4, inv_n, o, d, f):
    """Uniform background: uniform direction, origin on the disc of the bounding sphere
    perpendicular to it, placed on the side the light comes from."""
    w = 4.0 * np.pi * np.pi * radius * radius * inv_n
    for i in prange(o.shape[0]):
        dx, dy, dz = sampling.uniform_sphere(u1[i], u2[i])
        ex, ey, ez, _, _ = _disk_offset(u3[i], u4[i], dx, dy, dz, radius)
        back = 1.05 * radius
        o[i, 0] = centre[0] - back * dx + ex
        o[i, 1] = centre[1] - back * dy + ey
        o[i, 2] = centre[2] - back * dz + ez
        d[i, 0], d[i, 1], d[i, 2] = dx, dy, dz
        f[i, 0], f[i, 1], f[i, 2] = radiance[0] * w, radiance[1] * w, radiance[2] * w


# --- driver -------------------------------------------------------------------------------

def _uniforms(seed: int, map_id: int, source_slot: int, first: int, count: int, n_total: int):
    """Six (count,) float64 uniforms for photons [first, first + count) of one source:
    two scrambled Sobol pairs over the source's n_total photons (direction u1, u2 and
    position u3, u4) and two hashes for the discrete picks (u0, u5)."""
    idx = np.arange(first, first + count, dtype=np.int64)
    pix = np.full(count, map_id * 4096 + source_slot, np.int64)
    u1, u2 = sampling.stratified2(seed, pix, idx, n_total, sampling.stream(sampling.PHOTON, 0, 1))
    u3, u4 = sampling.stratified2(seed, pix, idx, n_total, sampling.stream(sampling.PHOTON, 0, 2))
    u0 = sampling.uniform(seed, pix, idx, sampling.stream(sampling.PHOTON, 0, 3))
    u5 = sampling.uniform(seed, pix, idx, sampling.stream(sampling.PHOTON, 0, 4))
    return u0, u1, u2, u3, u4, u5


def _cdf(p):
    c = np.cumsum(p)
    if c.size:
        c[-1] = 1.0
    return c


def emit(source: Source, light_set: LightSet, emissive: EmissiveTriangles, world_radiance,
         scene_centre, scene_radius: float, n_total: int, first: int, count: int, *,
         seed: int, map_id: int, source_slot: int, targets: Targets | None = None,
         target_prob: np.ndarray | None = None, extent: float = 0.0,
         emission_points=None) -> Emitted:
    """Photons [first, first + count) of the n_total photons of one source.

    Each photon's flux is already divided by n_total, so the flux of all n_total photons
    sums to the source's power (aimed: to the power it sends towards the targets).
    targets / target_prob (K,): the projection map's spheres and pick probabilities
    (None or empty = unaimed). source_slot (< 4096) and map_id separate random streams.
    extent: the scene's size (metres) for the offset of photons leaving emissive
    triangles (``geometry.offset_eps``). emission_points: ``HitShader.emission_points``,
    the radiance of textured emitters at a point (``EmissiveTriangles.rescale``: a
    photon's flux is the program's emission where it leaves, the pick stays by the
    triangle's mean).
    """
    o = np.zeros((count, 3))
    d = np.zeros((count, 3))
    f = np.zeros((count, 3))
    if count == 0:
        return Emitted(o, d, f)
    u0, u1, u2, u3, u4, u5 = _uniforms(seed, map_id, source_slot, first, count, n_total)
    inv_n = 1.0 / n_total
    if targets is None or targets.count == 0:
        tc, tr, tp = np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    else:
        tc, tr = targets.centre.astype(np.float64), targets.radius.astype(np.float64)
        tp = np.asarray(target_prob, np.float64)
    tcdf = _cdf(tp)
    if source.index == SOURCE_TRIANGLES:
        e = emissive
        _emit_triangles(e.cdf, e.probability, e.v0, e.e1, e.e2, e.normal, e.area, e.radiance,
                        u0, u1, u2, u3, u4, u5, inv_n, tc, tr, tp, tcdf, float(extent), o, d, f)
        if e.textured is not None and emission_points is not None:
            j, b1, b2 = e.points(u5, u3, u4)
            e.rescale(f, j, b1, b2, -d, emission_points)
    elif source.index == SOURCE_WORLD:
        _emit_world(np.asarray(world_radiance, np.float64).reshape(3),
                    np.asarray(scene_centre, np.float64), float(scene_radius),
                    u1, u2, u3, u4, inv_n, o, d, f)
    else:
        i = source.index
        q = light_set.params[i]
        k = int(light_set.kind[i])
        if k == LIGHT_SUN:
            plane = sun_plane(light_set, i, scene_centre, scene_radius)
            if tr.size == 0:
                tc = np.asarray(scene_centre, np.float64).reshape(1, 3)
                tr = np.array([float(scene_radius)])
                tp = np.ones(1)
                tcdf = np.ones(1)
            _emit_sun(q, plane, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f)
        elif k == LIGHT_AREA:
            _emit_area(q, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f)
        else:
            near, lead = np.zeros(count), np.zeros(count)
            _emit_local(q, u0, u1, u2, u3, u4, inv_n, tc, tr, tp, tcdf, o, d, f, near, lead)
            if light_set.radius[i] > 0 and not light_set.sphere[i]:
                return Emitted(o, d, f, near, lead)
    return Emitted(o, d, f)


def aimed_power(source: Source, light_set: LightSet, emissive: EmissiveTriangles,
                targets: Targets, scene_centre, scene_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Estimated flux (3,) W a source sends towards the targets, and the targets' pick
    probabilities (K,). Only shares photons between sources: the flux weights of the
    photons are exact whatever these estimates are. Zero when no target is reachable."""
    k_t = targets.count
    if k_t == 0 or source.index == SOURCE_WORLD:
        return np.zeros(3), np.zeros(k_t)
    if source.index == SOURCE_TRIANGLES:
        # From the emitters' centre: fraction of the two-sided emission within each cone.
        w = emissive.area * emissive.radiance.sum(axis=1)
        apex = (np.sum(emissive.v0 * w[:, None], axis=0) / max(w.sum(), 1e-300))
        frac = _solid_fraction(apex, targets.centre, targets.radius + np.sqrt(emissive.area.sum()))
        p = frac / frac.sum() if frac.sum() > 0 else frac
        return source.power * min(1.0, float(frac.sum())), p
    i = source.index
    kind = int(light_set.kind[i])
    if kind == LIGHT_SUN:
        a = np.pi * np.maximum(targets.radius, 0.0) ** 2
        p = a / a.sum() if a.sum() > 0 else a
        cover = min(1.0, float(a.sum()) / (np.pi * max(scene_radius, 1e-300) ** 2))
        return source.power * cover, p
    if kind == LIGHT_AREA:
        reach = 0.5 * np.hypot(*light_set.size[i])
        frac = _solid_fraction(light_set.position[i], targets.centre, targets.radius + reach)
        front = (targets.centre - light_set.position[i]) @ (-light_set.axis_z[i])
        frac = np.where(front + targets.radius + reach > 0, frac, 0.0)
        p = frac / frac.sum() if frac.sum() > 0 else frac
        # The cosine-weighted hemisphere puts up to twice the uniform share in a cone.
        return source.power * min(1.0, 2.0 * float(frac.sum())), p
    r = targets.radius + light_set.radius[i]
    frac = _solid_fraction(light_set.position[i], targets.centre, r)
    if kind == LIGHT_SPOT:
        ok = cone_hits_sphere(light_set.position[i], -light_set.axis_z[i],
                              light_set.spot_cos_half[i], targets.centre, r)
        frac = np.where(ok, frac, 0.0)
        p = frac / frac.sum() if frac.sum() > 0 else frac
        cone = spot_cone_integral(light_set.spot_cos_half[i], light_set.spot_smooth[i]) / 2.0
        return light_set.strength[i] * min(cone, float(frac.sum())), p
    p = frac / frac.sum() if frac.sum() > 0 else frac
    return source.power * min(1.0, float(frac.sum())), p


def _solid_fraction(apex, centre, radius) -> np.ndarray:
    """(K,) fraction of the full sphere of directions each sphere subtends from apex."""
    v = np.asarray(centre, np.float64) - np.asarray(apex, np.float64)
    d2 = np.sum(v * v, axis=1)
    r2 = np.asarray(radius, np.float64) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        s2 = np.where(d2 > r2, r2 / np.where(d2 > 0, d2, 1.0), 1.0)
        omc = s2 / (1.0 + np.sqrt(np.maximum(0.0, 1.0 - s2)))
    omc = np.where(d2 > r2, omc, 2.0)
    return np.where(np.asarray(radius) >= 0, omc / 2.0, 0.0)

"""The media the renderer integrates and which of them fill each stretch of a ray: the
World's volume (all space) and media inside closed meshes.

The volume stack (Cycles' rule, docs/volumes.md "Volume stack"): a point lies in the
World's medium and in every mesh medium whose closed boundary holds it, and all of them are
active: coefficients and emission add, the phase function is one Henyey-Greenstein lobe of
the sigma_s-weighted mean g (Cycles mixes the lobes themselves; the mean g is this
renderer's approximation, as for an Add or Mix of volume shaders).

Which meshes hold a point is found by point location along the ray's line, not by a stack
carried along the path: ``stretches`` walks the boundary triangles (``Media.boundary``) from
a segment's origin along its direction to infinity; a mesh medium whose *first* crossing
is a back face (the ray leaves it) holds the origin, and every crossing toggles it after
that (front face: enter, back face: leave). That first-crossing rule is the one Cycles'
``integrator_volume_stack_init`` uses for the camera's initial stack (a ray cast from the
camera: objects met first at a back face enclose it); for closed, non-self-intersecting
meshes it gives the same stack Cycles tracks along the path (entered at front faces, left
at back faces), so camera rays, shadow rays, photon paths and final-gather rays all know
their medium without a per-path state, and a camera or light inside a medium mesh starts in
it. Where a mesh is open or a ray grazes an edge between two triangles, the two rules can
differ (Cycles' stack then keeps or drops the medium for the rest of that path, this one
only along that line).

A World volume of varying density (docs/volumes.md) fills a box around the scene
(``DensityFields.boxes``, core/prepared.py ``world_medium_box``) and nothing outside it:
the box's faces are one more boundary (bit WORLD_BOX_BIT of a stretch's mask), so a
stretch of it is finite as the trackers need, and light from infinity (the sun, the
World's light) reaches the box unattenuated.

Units: metres; coefficients in 1/m, emission in W/(m^3 sr).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..scene import geometry
from ..scene.accel import Accelerator
from ..scene.checks import SceneError
from ..scene.media import WORLD, Media
from .density import DensityFields
from .tracking import ratio_tracking_batch

MAX_MESH_MEDIA = 62
"""Mesh media a scene may hold: a stretch's set of media is a bit mask in an int64."""

WORLD_BOX_BIT = MAX_MESH_MEDIA
"""The mask bit of the stretches inside the box of a World volume of varying density."""

COINCIDENT = 1e-5
"""A crossing within this fraction of (t_end + the scene's extent) past a segment's end is
the surface that ends it (a glass sphere holding smoke is one mesh: its crossing and its
hit differ by rounding)."""

MAX_CROSSINGS = 256
"""Boundary crossings a walk follows along one ray before it raises (a mesh made of more
layers along one line than this is not a closed medium boundary the renderer expects)."""


class Stretches(NamedTuple):
    """The homogeneous stretches of N segments, S rows ordered by segment then distance.

    ray: (S,) int64 the segment of each stretch; start: (N + 1,) int64, segment i's
    stretches are rows start[i]:start[i + 1] (at least one per segment of length > 0);
    t0, t1: (S,) float64 metres along the segment (t1 inf for an escaping one);
    sigma_a, sigma_s, emission: (S, 3) float64 the summed coefficients (1/m, W/(m^3 sr));
    g: (S,) float64 the anisotropy; before: (S, 3) float64 the transmittance from the
    segment's origin to t0; through: (N, 3) float64 the transmittance of the whole segment.
    Heterogeneous media (docs/volumes.md): sigma_a, sigma_s above are the stretch's
    homogeneous part; field (S,) int64 the heterogeneous medium row active there (-1 none,
    at most one), het_a, het_s (S, 3) its coefficients at density 1, majorant (S,) its
    density's bound on the stretch (the largest majorant-grid cell it crosses); before and
    through then include ratio-tracking estimates (unbiased, not exact) of its
    transmittance.
    bound0, bound1: (S,) float64 |cos| between the ray and the plane where the scattering
    ends at the stretch's start / end (a medium boundary with no scattering medium beyond,
    or the opaque surface that ends the segment: ``stretches``' end_cos), NaN where the
    scattering goes on (the beam estimate's boundary correction, photons/beam.py).
    """

    ray: np.ndarray
    start: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    sigma_a: np.ndarray
    sigma_s: np.ndarray
    emission: np.ndarray
    g: np.ndarray
    before: np.ndarray
    through: np.ndarray
    field: np.ndarray | None = None
    het_a: np.ndarray | None = None
    het_s: np.ndarray | None = None
    majorant: np.ndarray | None = None
    bound0: np.ndarray | None = None
    bound1: np.ndarray | None = None

    @property
    def sigma_t(self) -> np.ndarray:
        return self.sigma_a + self.sigma_s

    @property
    def length(self) -> np.ndarray:
        return self.t1 - self.t0


class Medium:
    """The scene's media as the renderer takes them (module doc). ``world``: the World's
    row or -1; ``world_sigma_t`` (3,) float64 (0 without a World medium); ``scatters``:
    some medium scatters; ``emits``: some medium emits; ``names``; ``close()`` releases
    the boundary's Embree scene."""

    def __init__(self, media: Media, extent: float, threads: int = 0,
                 fields: DensityFields | None = None, seed: int = 0):
        self.names = tuple(media.names[i] if i < len(media.names) else f"medium {i}"
                           for i in range(media.count))
        self.world = media.world
        self.extent = float(extent)
        # The render seed: the ratio-tracking walks of ``stretches`` follow it
        self.seed = int(seed)
        mesh_rows = np.flatnonzero(media.bounds != WORLD)
        self.mesh_rows = mesh_rows
        tri = np.ascontiguousarray(media.boundary, np.float32)
        self.boundary = tri
        self.boundary_medium = np.asarray(media.boundary_medium, np.int64)
        # Bit b of a stretch's mask: the mesh media bit_rows[b]. Rows bounded by the same
        # triangles (a varying density and the homogeneous rest of its Add / Mix,
        # photon_engine/export_volumes.py) share a bit, and their triangles are walked
        # once: coincident triangles would hide each other from ``_crossings``.
        bit_of = np.full(media.count, -1, np.int64)
        walked = np.ones(tri.shape[0], bool)
        first_of = {}
        self.bit_rows: list[list[int]] = []
        for r in mesh_rows:
            own = np.flatnonzero(self.boundary_medium == r)
            key = tri[own].tobytes()
            if key in first_of:
                bit_of[r] = first_of[key]
                walked[own] = False
                self.bit_rows[first_of[key]].append(int(r))
            else:
                first_of[key] = bit_of[r] = len(self.bit_rows)
                self.bit_rows.append([int(r)])
        if len(self.bit_rows) > MAX_MESH_MEDIA:
            raise SceneError(f"{len(self.bit_rows)} media inside meshes; at most "
                             f"{MAX_MESH_MEDIA} are supported")
        self.bit_of = bit_of
        self.sigma_a = media.sigma_a.astype(np.float64)
        self.sigma_s = media.sigma_s.astype(np.float64)
        self.emission = media.emission.astype(np.float64)
        self.g = media.anisotropy.astype(np.float64)
        if not walked.all():
            tri = np.ascontiguousarray(tri[walked])
        self.tri_bit = np.ascontiguousarray(bit_of[self.boundary_medium[walked]], np.int64)
        e1 = tri[:, 1].astype(np.float64) - tri[:, 0]
        e2 = tri[:, 2].astype(np.float64) - tri[:, 0]
        self.tri_normal = np.ascontiguousarray(np.cross(e1, e2))
        length = np.linalg.norm(self.tri_normal, axis=1)
        self.tri_normal_length = np.where(length > 0, length, 1.0)
        self.accel = Accelerator(tri, threads=threads) if tri.shape[0] else None
        self.scatters = bool(np.any(self.sigma_s > 0))
        self.emits = bool(np.any(self.emission > 0))
        # Heterogeneous rows: their coefficients scale with rho(x) (``fields``)
        self.fields = fields
        self.het = media.density_texture >= 0
        if self.het.any() and fields is None:
            raise ValueError("regions.Medium: heterogeneous media need their DensityFields")
        self.heterogeneous = bool(self.het.any())
        w = self.world
        # A World of varying density fills its box only (module doc): nothing extinguishes
        # the rays from infinity outside it
        self.world_box = fields.boxes[w] if w >= 0 and self.het[w] else None
        self.world_sigma_t = (self.sigma_a[w] + self.sigma_s[w]) \
            if w >= 0 and self.world_box is None else np.zeros(3)

    def close(self) -> None:
        if self.accel is not None:
            self.accel.close()

    @property
    def name(self) -> str:
        """The media's names for messages ("'Fog', 'Smoke in Sphere'")."""
        return ", ".join(f"'{n}'" for n in self.names)

    def _crossings(self, o, d):
        """Every boundary crossing of N rays from o along unit d to infinity: (N, C)
        float64 distances (inf padded), (N, C) int64 medium bits, (N, C) bool front face,
        (N, C) float64 |cos| between the ray and the crossed triangle's plane."""
        n = o.shape[0]
        ts, bits, fronts, coss = [], [], [], []
        if self.accel is None or n == 0:
            return (np.full((n, 0), np.inf), np.zeros((n, 0), np.int64), np.zeros((n, 0), bool),
                    np.zeros((n, 0)))
        o64 = np.asarray(o, np.float64)
        d64 = np.asarray(d, np.float64)
        t_acc = np.zeros(n)
        cur = o64.copy()
        active = np.arange(n)
        for _ in range(MAX_CROSSINGS + 1):
            if active.size == 0:
                break
            if len(ts) == MAX_CROSSINGS:
                raise SceneError(f"a ray crosses the boundaries of media {self.name} more than "
                                 f"{MAX_CROSSINGS} times; are they closed meshes?")
            hits = self.accel.intersect(cur[active], d64[active])
            hit = hits.prim >= 0
            col_t = np.full(n, np.inf)
            col_b = np.zeros(n, np.int64)
            col_f = np.zeros(n, bool)
            col_c = np.zeros(n)
            idx = active[hit]
            prim = hits.prim[hit]
            t_acc[idx] += hits.t[hit].astype(np.float64)
            col_t[idx] = t_acc[idx]
            col_b[idx] = self.tri_bit[prim]
            cos = np.einsum("ij,ij->i", self.tri_normal[prim], d64[idx])
            col_f[idx] = cos < 0.0
            col_c[idx] = np.minimum(np.abs(cos) / self.tri_normal_length[prim], 1.0)
            ts.append(col_t)
            bits.append(col_b)
            fronts.append(col_f)
            coss.append(col_c)
            # Go on from just past the crossing (the offset scales with the scene).
            p = o64[idx] + t_acc[idx, None] * d64[idx]
            eps = geometry.OFFSET_SCALE * (np.abs(p).max(axis=1) + self.extent)
            t_acc[idx] += eps
            cur[idx] = o64[idx] + t_acc[idx, None] * d64[idx]
            active = idx
        return np.stack(ts, 1), np.stack(bits, 1), np.stack(fronts, 1), np.stack(coss, 1)

    def holds(self, row: int, origins, directions) -> np.ndarray:
        """(N,) bool: does mesh medium ``row`` hold each origin (N, 3) metres, by the
        first-crossing rule along its unit direction (N, 3) (module doc; the rule every
        stretch walk from that origin along that direction applies)?"""
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        bit = int(self.bit_of[row]) if 0 <= row < self.bit_of.shape[0] else -1
        if bit < 0 or o.shape[0] == 0:
            return np.zeros(o.shape[0], bool)
        ct, cb, cf, _ = self._crossings(o, np.ascontiguousarray(directions, np.float64).reshape(-1, 3))
        mine = (cb == bit) & np.isfinite(ct)
        first = np.argmax(mine, axis=1)
        return mine.any(axis=1) & ~cf[np.arange(o.shape[0]), first]

    def stretches(self, origins, directions, t_end, end_cos=None) -> Stretches:
        """The homogeneous stretches of N segments (Stretches): origins, unit directions
        (N, 3) metres, t_end (N,) metres (inf: the ray escapes); end_cos (N,) float64 |cos|
        between the ray and the surface that ends it where that surface bounds the medium
        (opaque), NaN where not, or None: none does (``surface_bounds``)."""
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
        n = o.shape[0]
        t_end = np.ascontiguousarray(np.broadcast_to(np.asarray(t_end, np.float64), (n,)))
        ct, cb, cf, cc = self._crossings(o, d)
        if self.world_box is not None:
            ct, cb, cf, cc = _with_box_crossings(ct, cb, cf, cc, o, d, *self.world_box)
        count = np.empty(n, np.int64)
        _count_kernel(ct, t_end, count)
        start = np.zeros(n + 1, np.int64)
        np.cumsum(count, out=start[1:])
        s = int(start[-1])
        ray, t0, t1, mask = (np.empty(s, np.int64), np.empty(s), np.empty(s),
                             np.empty(s, np.int64))
        c0, c1, beyond = np.empty(s), np.empty(s), np.empty(s, np.int64)
        _stretch_kernel(ct, cb, cf, cc, t_end, COINCIDENT * (t_end + self.extent), start, ray,
                        t0, t1, mask, c0, c1, beyond)
        sa, ss, em, g, fld, ha, hs, maj = self._coefficients(mask)
        bound0, bound1 = self._bounds(start, ss, hs, c0, c1, beyond, end_cos)
        before = np.empty((s, 3))
        through = np.ones((n, 3))
        _before_kernel(start, t0, t1, sa + ss, before, through)
        if self.heterogeneous:
            het = np.flatnonzero(fld >= 0)
            if het.size:
                if not np.all(np.isfinite(t1[het])):
                    raise SceneError(f"a ray escapes through the heterogeneous media "
                                     f"{self.name}; only closed meshes may vary in density")
                # Each stretch's majorant: the largest of the grid cells it crosses
                maj[het] = self.fields.segment_majorant(fld[het], o[ray[het]], d[ray[het]],
                                                        t0[het], t1[het])
                # Each walk's stream is keyed by its segment's origin and direction bits
                # and its stretch's place along the ray, never by its place in the batch:
                # the same whatever runs before or beside it (photon chunks run in
                # threads, the camera pass's tiles adapt to their time)
                T = ratio_tracking_batch(self.fields.along(fld[het], maj[het], ha[het], hs[het]),
                                         o[ray[het]],
                                         d[ray[het]], t0[het], t1[het], np.arange(het.size),
                                         ha[het] + hs[het], maj[het], self.seed,
                                         sampling.stream(sampling.MEDIUM_TRANSMITTANCE),
                                         index=_walk_keys(o[ray[het]], d[ray[het]], het - start[ray[het]]))
                factor = np.ones((s, 3))
                factor[het] = T
                _het_before_kernel(start, factor, before, through)
        return Stretches(ray, start, t0, t1, sa, ss, em, g, before, through, fld, ha, hs, maj,
                         bound0, bound1)

    def _bounds(self, start, ss, hs, c0, c1, beyond, end_cos):
        """``Stretches.bound0`` / ``bound1`` from the kernel's crossing cosines c0, c1 (S,)
        (NaN: the stretch starts / ends elsewhere than at a crossing) and masks ``beyond``
        (S,) (-1: none): a crossing bounds the scattering where the medium on its other
        side scatters nothing; the segment's last stretch takes ``end_cos`` where no
        crossing ends it."""
        scatters = np.any(ss > 0, axis=1) | np.any(hs > 0, axis=1)
        bound0 = c0.copy()
        first = start[:-1][start[:-1] < start[1:]]
        after = np.ones(c0.shape[0], bool)
        after[first] = False  # a segment's first stretch: no stretch before it
        prev = np.flatnonzero(after)
        bound0[prev[scatters[prev - 1]]] = np.nan
        bound1 = c1.copy()
        has = np.flatnonzero(beyond >= 0)
        if has.size:
            _, b_ss, _, _, _, _, b_hs, _ = self._coefficients(beyond[has])
            far = np.any(b_ss > 0, axis=1) | np.any(b_hs > 0, axis=1)
            bound1[has[far]] = np.nan
        if end_cos is not None:
            last = start[1:][start[:-1] < start[1:]] - 1
            seg = np.flatnonzero(start[:-1] < start[1:])
            open_end = np.isnan(bound1[last])
            bound1[last[open_end]] = np.asarray(end_cos, np.float64)[seg[open_end]]
        return bound0, bound1

    def _coefficients(self, mask):
        """Summed coefficients of the World's medium and the mesh media of each mask."""
        keys, inv = np.unique(mask, return_inverse=True)
        k = keys.shape[0]
        sa, ss, em, gs = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
        fld, ha, hs, maj = np.full(k, -1, np.int64), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
        for j, key in enumerate(keys):
            world = self.world >= 0 and (self.world_box is None
                                         or (int(key) >> WORLD_BOX_BIT) & 1)
            rows = [self.world] if world else []
            rows += [r for b in range(len(self.bit_rows)) if (int(key) >> b) & 1
                     for r in self.bit_rows[b]]
            for r in rows:
                if self.het[r]:
                    if fld[j] >= 0:
                        raise SceneError(f"the heterogeneous media '{self.names[fld[j]]}' and "
                                         f"'{self.names[r]}' overlap; at most one medium of "
                                         f"varying density per point is supported")
                    fld[j], ha[j], hs[j] = r, self.sigma_a[r], self.sigma_s[r]
                    maj[j] = self.fields.majorant[r]
                else:
                    sa[j] += self.sigma_a[r]
                    ss[j] += self.sigma_s[r]
                em[j] += self.emission[r]
            # The phase mix weights a heterogeneous medium by its sigma_s at density 1
            w = np.array([self.sigma_s[r].mean() for r in rows])
            if rows and w.sum() > 0:
                gs[j] = float(np.dot(w, self.g[rows]) / w.sum())
        inv = inv.reshape(-1)
        return sa[inv], ss[inv], em[inv], gs[inv], fld[inv], ha[inv], hs[inv], maj[inv]

    def transmittance(self, origins, directions, t_end) -> np.ndarray:
        """exp(-integral of sigma_t) (N, 3) float64 along N segments (``stretches``'
        arguments; an escaping one is 0 in every channel the World's medium extinguishes)."""
        return self.stretches(origins, directions, t_end).through

    def attenuate(self, contrib, need, origins, directions, length) -> None:
        """contrib[need] *= the transmittance of the shadow segments (origins, unit
        directions (N, 3), length (N,) metres; the sun's and world's 3e38 m cross the
        World's medium to infinity) in place."""
        idx = np.flatnonzero(need)
        if idx.size:
            contrib[idx] *= self.transmittance(origins[idx], directions[idx],
                                               np.asarray(length)[idx].astype(np.float64))


def renderable(media: Media, extent: float, threads: int = 0,
               fields: DensityFields | None = None, seed: int = 0) -> Medium | None:
    """The Medium of ``media`` as the renderer takes it, or None when there is no medium or
    none has an effect (every coefficient and emission 0: the scene then renders exactly as
    without media). ``fields``: the densities of the heterogeneous media (core/prepared.py
    binds their programs); ``seed``: the render seed of the ratio-tracking walks."""
    if not (np.any(media.sigma_a > 0) or np.any(media.sigma_s > 0)
            or np.any(media.emission > 0)):
        return None
    return Medium(media, extent, threads, fields, seed)


def emitted(emission, sigma_t, length) -> np.ndarray:
    """A homogeneous medium's emission integrated along stretches: the integral of
    exp(-sigma_t s) emission ds over [0, length], (S, 3) W/(m^2 sr) for emission,
    sigma_t (S, 3) and length (S,) metres (inf allowed)."""
    t = np.asarray(length, np.float64)[:, None]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        decay = np.where(sigma_t > 0, -np.expm1(-sigma_t * t) / np.where(sigma_t > 0, sigma_t, 1.0),
                         t)
        return np.where(emission > 0, emission * decay, 0.0)


@njit(cache=True, error_model="numpy")
def _count_kernel(ct, t_end, count):
    for i in range(ct.shape[0]):
        c = 1
        for j in range(ct.shape[1]):
            if ct[i, j] < t_end[i]:
                c += 1
        count[i] = c


@njit(cache=True, error_model="numpy")
def _stretch_kernel(ct, cb, cf, cc, t_end, tol, start, ray, t0, t1, mask, c0, c1, beyond):
    """The stretches' rays, bounds and masks (module doc: first crossing at a back face =
    inside at the origin; every crossing toggles); c0 / c1 the cosine cc of the crossing
    that starts / ends each stretch (NaN: none) and beyond the mask past its end crossing
    (-1: none). A segment's last stretch ends at a crossing too where one lies within
    tol (N,) metres past t_end (a surface that is also a medium's boundary)."""
    for i in range(ct.shape[0]):
        seen = np.int64(0)
        m = np.int64(0)
        for j in range(ct.shape[1]):
            if ct[i, j] == np.inf:
                break
            bit = np.int64(1) << cb[i, j]
            if (seen & bit) == 0:
                seen |= bit
                if not cf[i, j]:
                    m |= bit
        k = start[i]
        a = 0.0
        c_start = np.nan
        for j in range(ct.shape[1] + 1):
            b = ct[i, j] if j < ct.shape[1] else np.inf
            last = not (b < t_end[i])
            ray[k] = i
            t0[k] = a
            t1[k] = t_end[i] if last else b
            mask[k] = m
            c0[k] = c_start
            c1[k] = np.nan
            beyond[k] = -1
            if last and not (b - t_end[i] <= tol[i]):
                break
            bit = np.int64(1) << cb[i, j]
            after = (m | bit) if cf[i, j] else (m & ~bit)
            c1[k] = cc[i, j]
            beyond[k] = after
            if last:
                break
            k += 1
            m = after
            c_start = cc[i, j]
            a = b


@njit(cache=True, error_model="numpy")
def _before_kernel(start, t0, t1, sigma_t, before, through):
    """Transmittance to each stretch's start and through each segment; a clear channel
    adds no optical depth even over an infinite stretch (0 x inf)."""
    for i in range(start.shape[0] - 1):
        tau0 = 0.0
        tau1 = 0.0
        tau2 = 0.0
        for k in range(start[i], start[i + 1]):
            before[k, 0] = np.exp(-tau0)
            before[k, 1] = np.exp(-tau1)
            before[k, 2] = np.exp(-tau2)
            ln = t1[k] - t0[k]
            if sigma_t[k, 0] > 0.0:
                tau0 += sigma_t[k, 0] * ln
            if sigma_t[k, 1] > 0.0:
                tau1 += sigma_t[k, 1] * ln
            if sigma_t[k, 2] > 0.0:
                tau2 += sigma_t[k, 2] * ln
        through[i, 0] = np.exp(-tau0)
        through[i, 1] = np.exp(-tau1)
        through[i, 2] = np.exp(-tau2)


@njit(cache=True, error_model="numpy")
def _het_before_kernel(start, factor, before, through):
    """Multiply each stretch's ``before`` by the heterogeneous transmittance factors (S, 3)
    of the stretches before it on its segment, and ``through`` by all of them."""
    for i in range(start.shape[0] - 1):
        c0 = 1.0
        c1 = 1.0
        c2 = 1.0
        for k in range(start[i], start[i + 1]):
            before[k, 0] *= c0
            before[k, 1] *= c1
            before[k, 2] *= c2
            c0 *= factor[k, 0]
            c1 *= factor[k, 1]
            c2 *= factor[k, 2]
        through[i, 0] *= c0
        through[i, 1] *= c1
        through[i, 2] *= c2


def _with_box_crossings(ct, cb, cf, cc, o, d, lo, hi):
    """``Medium._crossings``' (N, C) distances, bits, front flags and cosines with the
    crossings of the box [lo, hi] (3,) metres added (bit WORLD_BOX_BIT; entering: a front
    face; cosine NaN: the box is no boundary of the beam estimate), each row in order of
    distance (inf padded): the slab test of the rays o + t d, t > 0."""
    inside = (o >= lo) & (o <= hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - o) / d, (hi - o) / d
    flat = d == 0.0
    near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb)).max(axis=1)
    far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb)).min(axis=1)
    hit = far > np.maximum(near, 0.0)
    t_in = np.where(hit & (near > 0.0), near, np.inf)
    t_out = np.where(hit, far, np.inf)
    n = ct.shape[0]
    ct = np.concatenate([ct, t_in[:, None], t_out[:, None]], axis=1)
    cb = np.concatenate([cb, np.full((n, 2), WORLD_BOX_BIT, np.int64)], axis=1)
    cf = np.concatenate([cf, np.ones((n, 1), bool), np.zeros((n, 1), bool)], axis=1)
    cc = np.concatenate([cc, np.full((n, 2), np.nan)], axis=1)
    order = np.argsort(ct, axis=1, kind="stable")
    return (np.take_along_axis(ct, order, 1), np.take_along_axis(cb, order, 1),
            np.take_along_axis(cf, order, 1), np.take_along_axis(cc, order, 1))


def _walk_keys(o, d, stretch) -> np.ndarray:
    """(N,) int64 random-stream keys of N walks: a hash of the float64 bits of their
    origins, directions (N, 3) and their stretches' places along their rays (N,) int64,
    then of each key's rank among equal keys in the batch (identical segments, as in the
    tests' tiled rays, still get independent walks; a render's rays are all distinct, so
    its keys do not depend on how its rays are batched)."""
    bits = np.concatenate([np.ascontiguousarray(o, np.float64).view(np.uint64),
                           np.ascontiguousarray(d, np.float64).view(np.uint64),
                           np.asarray(stretch, np.int64).astype(np.uint64)[:, None]], axis=1)
    key = np.zeros(bits.shape[0], np.uint64)
    for k in range(bits.shape[1]):
        key = _mix(key, bits[:, k])
    order = np.argsort(key, kind="stable")
    ranked = key[order]
    first = np.r_[True, ranked[1:] != ranked[:-1]]
    rank = np.empty(key.shape[0], np.uint64)
    at = np.arange(key.shape[0])
    rank[order] = (at - np.maximum.accumulate(np.where(first, at, 0))).astype(np.uint64)
    return _mix(key, rank).view(np.int64)


def _mix(key, bits) -> np.ndarray:
    """One round of the walk-key hash: (N,) uint64 keys mixed with (N,) uint64 bits."""
    with np.errstate(over="ignore"):
        key = (key ^ bits) * np.uint64(0x9E3779B97F4A7C15)
        return key ^ (key >> np.uint64(29))

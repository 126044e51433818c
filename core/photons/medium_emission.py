"""Emissive media as photon sources (docs/volumes.md, "Emissive media").

Units (Cycles', ``svm_node_principled_volume`` and ``volume_emission_setup``): a medium's
emission epsilon (``Media.emission``, (3,) W/(m^3 sr)) is radiance added per metre of
path, Emission Strength x Emission Color, **not** multiplied by the density. A
homogeneous-emission medium inside a closed mesh of volume V therefore emits
4 pi epsilon V watts per channel, isotropically from every point inside it (a varying
density changes where the light is absorbed and scattered, not where it is emitted).

Photons: positions uniform in the medium's mesh (rejection in the boundary triangles' box,
each candidate tested with ``regions.Medium.holds`` along the photon's own direction, the
rule its flight applies, so a photon accepted here starts inside the medium for the
flight too), directions uniform on the sphere; flux 4 pi epsilon V / n_total. The
photons then fly through the media like any other (their first flight starts inside the
emitter: self-absorption and scattering by the free flights).

No shadow ray samples a medium, so a medium's direct light is its photons': they start
with one diffuse-like bounce counted (``FIRST_BOUNCES``), so every store rule keeps their
first surface hits and first collisions (the preview's indirect map, SPPM's
shadow-ray-direct map) and no caustic map takes them (their light -> specular -> diffuse
paths land in the global map, blurred like indirect light).

The World's volume emission (docs/volumes.md, "World volume emission") fills all space,
which has no finite power; its photons come from the **scene's bounding sphere**
(``PreparedScene.centre`` / ``radius``, the geometry's sphere 1 % wider, the region the
sun's and the world background's photons already start on): power 4 pi epsilon
(4/3 pi R^3), positions uniform in the ball. Light the World's volume emits farther out
lights nothing (in an absorbing World medium it is attenuated by at least exp(-sigma_t d)
over the distance d from the sphere to a surface); camera rays still see the emission
along their whole length. Photons that start inside an opaque closed object land on its
inner faces, which no estimate reads (photons count only from the front of a surface).
V of a mesh medium comes from the divergence theorem over the boundary triangles, exact
for the closed meshes media are; an open boundary is reported by the exporter.

Random numbers: direction from a scrambled Sobol pair over the source's photons
(``sampling.stratified2``), candidate positions from counter hashes of (seed, map,
source, photon, round) in the stream ``sampling.MEDIUM_EMISSION``: a photon's numbers do
not depend on chunks or threads.
"""

from __future__ import annotations

import numpy as np

from .. import sampling
from ..media.regions import Medium
from .emission import Emitted, Source

SOURCE_MEDIUM = -3
"""Source index of medium row r: SOURCE_MEDIUM - r (after emission.SOURCE_WORLD)."""

FIRST_BOUNCES = 1
"""Diffuse-like bounces a medium's photon starts with (module doc: its direct light is
the photons')."""

MAX_ROUNDS = 4096
"""Rejection rounds before the photons still outside are dropped (their flux with them;
counted in ``Emitted``-side stats by the caller). A closed mesh filling 1 % of its box
leaves exp(-41) of them."""


def is_medium(index: int) -> bool:
    """Is a source index an emissive medium's?"""
    return index <= SOURCE_MEDIUM


def medium_row(index: int) -> int:
    """The medium row of a medium source's index."""
    return SOURCE_MEDIUM - index


def volume(tri) -> float:
    """The volume (m^3) a closed triangle mesh (B, 3, 3) metres encloses (divergence
    theorem: |sum of v0 . (v1 x v2)| / 6)."""
    t = np.asarray(tri, np.float64)
    if t.shape[0] == 0:
        return 0.0
    return abs(float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum())) / 6.0


def sources(medium: Medium | None, centre=None, radius: float = 0.0
            ) -> tuple[list[Source], list[str]]:
    """The emissive media of a scene as photon sources (power (3,) W = 4 pi epsilon V) and
    the decisions' lines about them. The World's volume emission is a source over the
    scene's bounding sphere (``centre`` (3,) metres, ``radius`` metres; module doc); without
    a sphere (radius 0) it is named in the notes and emits no photons."""
    out, notes = [], []
    if medium is None or not medium.emits:
        return out, notes
    for r in range(len(medium.names)):
        eps = medium.emission[r]
        if not np.any(eps > 0):
            continue
        if r == medium.world:
            if centre is None or not radius > 0.0:
                notes.append(f"World volume emission of '{medium.names[r]}': no photons (the "
                             f"scene has no geometry to bound it); seen along camera rays only")
                continue
            v = 4.0 / 3.0 * np.pi * float(radius) ** 3
            notes.append(f"World volume emission of '{medium.names[r]}': photons from the "
                         f"scene's bounding sphere (radius {float(radius):.4g} m, "
                         f"{v:.4g} m^3); light it emits farther out lights nothing")
        else:
            v = volume(medium.boundary[medium.boundary_medium == r])
        power = 4.0 * np.pi * eps * v
        if np.any(power > 0):
            out.append(Source(SOURCE_MEDIUM - r, power, f"emissive medium '{medium.names[r]}'"))
    return out, notes


def emit(source: Source, medium: Medium, n_total: int, first: int, count: int, *,
         seed: int, map_id: int, source_slot: int, centre=None,
         radius: float = 0.0) -> tuple[Emitted, int]:
    """Photons [first, first + count) of the n_total photons of one emissive medium
    (module doc); returns (Emitted float64, how many were dropped after MAX_ROUNDS
    rejection rounds, flux 0). The World's medium takes the scene's bounding sphere
    (``centre`` (3,), ``radius`` metres, as ``sources``)."""
    r = medium_row(source.index)
    o = np.zeros((count, 3))
    d = np.zeros((count, 3))
    f = np.zeros((count, 3))
    if count == 0:
        return Emitted(o, d, f), 0
    idx = np.arange(first, first + count, dtype=np.int64)
    pix = np.full(count, map_id * 4096 + source_slot, np.int64)
    u1, u2 = sampling.stratified2(seed, pix, idx, n_total,
                                  sampling.stream(sampling.MEDIUM_EMISSION, 0))
    z = 1.0 - 2.0 * u1
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    d[:] = np.stack([s * np.cos(2.0 * np.pi * u2), s * np.sin(2.0 * np.pi * u2), z], axis=1)
    # Per photon, its own counter: the candidate of round k is the same whatever the chunk
    key = (np.int64(map_id) * 4096 + source_slot) * (1 << 40) + idx
    if r == medium.world:
        # Uniform in the ball: radius R cbrt(u), direction uniform (no rejection)
        u = [sampling.uniform(seed, key, np.zeros(count, np.int64),
                              sampling.stream(sampling.MEDIUM_EMISSION, 1 + j)) for j in range(3)]
        zz = 1.0 - 2.0 * u[1]
        ss = np.sqrt(np.maximum(0.0, 1.0 - zz * zz))
        w = np.stack([ss * np.cos(2.0 * np.pi * u[2]), ss * np.sin(2.0 * np.pi * u[2]), zz], 1)
        o[:] = np.asarray(centre, np.float64) + (float(radius) * np.cbrt(u[0]))[:, None] * w
        f[:] = source.power / n_total
        return Emitted(o, d, f), 0
    tri = medium.boundary[medium.boundary_medium == r].reshape(-1, 3).astype(np.float64)
    lo, hi = tri.min(axis=0), tri.max(axis=0)
    pending = np.arange(count)
    for k in range(MAX_ROUNDS):
        if pending.size == 0:
            break
        u = np.stack([sampling.uniform(seed, key[pending], np.full(pending.size, k, np.int64),
                                       sampling.stream(sampling.MEDIUM_EMISSION, 1 + j))
                      for j in range(3)], axis=1)
        p = lo + u * (hi - lo)
        inside = medium.holds(r, p, d[pending])
        o[pending[inside]] = p[inside]
        pending = pending[~inside]
    ok = np.ones(count, bool)
    ok[pending] = False
    f[ok] = source.power / n_total
    return Emitted(o, d, f), int(pending.size)

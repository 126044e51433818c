"""The figures docs/volumes.md and docs/dispersion.md quote: accuracy of the media kernels
against closed forms, and their speed (after a warm-up call, so numba's compile is not
counted).

    .venv/bin/python benchmarks/bench_media.py [--photons 400000] [--rays 20000]
        [--fog-photons 100000]

``fog`` renders tests/core/scenes.py's caustic scene (glass sphere over a floor, point
light) in World fog and without (the baseline in the same run): volume photons stored per
second of photon pass, bytes per volume photon, and the render times' ratio.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core import spectral  # noqa: E402
from core.materials import dispersion  # noqa: E402
from core import sampling  # noqa: E402
from core.media import free_flight, phase, regions, single_scatter, tracking  # noqa: E402
from core.media.density import DensityFields  # noqa: E402
from core.scene import shapes  # noqa: E402
from core.photons import beam  # noqa: E402
from core.integrators import photon_mapping  # noqa: E402
from core.scene.media import Media  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import caustic_scene  # noqa: E402


def trapezoid(y, x, axis=0):
    """The trapezoid rule (np.trapezoid is numpy >= 2 only; CI also runs numpy 1.26)."""
    y = np.moveaxis(np.asarray(y, float), axis, 0)
    dx = np.diff(np.asarray(x, float)).reshape((-1,) + (1,) * (y.ndim - 1))
    return np.sum(0.5 * (y[1:] + y[:-1]) * dx, axis=0)


def timed(fn, *args):
    fn(*args)  # warm-up (compile)
    t = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t


def slab(photons: int, rays: int):
    """The uniformly lit slab of tests/core/photons/test_beam.py, bigger."""
    rng = np.random.default_rng(1)
    sigma_a, sigma_s, g, depth, width, e = 0.25, 0.75, 0.5, 1.0, 2.0, 3.0
    sigma_t = sigma_a + sigma_s
    z = -np.log1p(-rng.random(photons)) / sigma_t
    keep = z < depth
    pos = np.column_stack([rng.uniform(-1, 1, (photons, 2)), z])[keep].astype(np.float32)
    flux = np.full((pos.shape[0], 3), e * width ** 2 / photons * sigma_s / sigma_t, np.float32)
    dirs = np.tile(np.float32([0, 0, 1]), (pos.shape[0], 1))
    t = time.perf_counter()
    radii = beam.photon_radii(pos, 64)
    vmap = beam.VolumePhotonMap(pos, flux, dirs, radii)
    build = time.perf_counter() - t
    o = np.column_stack([rng.uniform(-0.45, 0.45, (rays, 2)), np.zeros(rays)])
    d = np.tile([0.0, 0.0, 1.0], (rays, 1))
    out, dt = timed(vmap.radiance, o, d, np.full(rays, depth), np.full(3, sigma_t), g)
    want = sigma_s * phase.phase_values(g, [-1.0])[0] * e * (1 - math.exp(-2 * depth)) / 2
    print(f"beam estimate, slab: {pos.shape[0]} volume photons (radii k=64 + tree: "
          f"{build:.2f} s, {vmap.nbytes / len(vmap):.0f} B/photon), {rays} rays in {dt:.3f} s "
          f"({rays / dt / 1e3:.0f} k rays/s); mean {out[:, 0].mean():.5f} vs analytic "
          f"{want:.5f} ({100 * (out[:, 0].mean() / want - 1):+.2f} %), per-ray spread "
          f"{100 * out[:, 0].std() / want:.1f} %")


def inscatter():
    sa, ss, intensity = np.array([0.05, 0.2, 0.4]), np.array([0.5, 0.3, 0.1]), np.ones(3) * 10
    n, samples = 4096, 16
    o = np.tile([0.0, -3.0, 0.2], (n, 1))
    d = np.tile([0.0, 1.0, 0.0], (n, 1))
    light = np.array([0.1, 0.0, 0.5])
    out = np.empty((n, 3))
    _, dt = timed(single_scatter.inscatter_rays, o, d, np.full(n, 6.0), light, intensity, sa,
                  ss, 0.0, samples, 1, out)
    t = np.linspace(0, 6, 2_000_001)
    x = o[0] + t[:, None] * d[0]
    r = np.linalg.norm(x - light, axis=1)
    f = np.exp(-np.outer(t + r, sa + ss)) * ss * intensity / (4 * math.pi * r[:, None] ** 2)
    want = trapezoid(f, t, axis=0)
    print(f"single scattering, equiangular, {samples} samples per ray: {n} rays in {dt:.4f} s "
          f"({n * samples / dt / 1e6:.1f} M samples/s); mean / trapezoid - 1 = "
          f"{np.array2string(100 * (out.mean(axis=0) / want - 1), precision=3)} %, "
          f"per-ray relative spread {100 * np.mean(out.std(axis=0) / want):.2f} %")


def flights():
    n = 1_000_000
    rng = np.random.default_rng(2)
    u1, u2 = rng.random(n), rng.random(n)
    _, dt = timed(free_flight.sample_distances, [0.2, 0.5, 1.5], [1.0, 0.6, 0.1], 1.3, u1, u2)
    print(f"free flight: {n / dt / 1e6:.1f} M samples/s (one thread, the array wrapper)")


def spectra():
    u = np.random.default_rng(3).random(1_000_000)
    (lam, _, w), dt = timed(spectral.sample_wavelengths, u)
    total = spectral.BASIS.sum(0) * spectral.BIN_WIDTH
    print(f"white through wavelength sampling, 1e6 samples: RGB "
          f"{np.array2string(w.mean(0), precision=5)} (exact table integral "
          f"{np.array2string(total, precision=12)}), {1e6 / dt / 1e6:.0f} M samples/s")
    apex, inc = math.radians(60), math.radians(50)
    for nm in (450, 550, 650):
        n = dispersion.ior(1.5168, 64.17, [nm])[0]
        inner = apex - math.asin(math.sin(inc) / n)
        dev = math.degrees(inc + math.asin(n * math.sin(inner)) - apex)
        print(f"BK7 prism 60 deg, incidence 50 deg, {nm} nm: n = {n:.5f}, deviation {dev:.4f} deg")


def fog(photons: int):
    clear = caustic_scene(width=32, height=32)
    foggy = dataclasses.replace(clear, media=Media.from_list([
        {"sigma_a": [0.02] * 3, "sigma_s": [0.15] * 3, "anisotropy": 0.2, "name": "Fog"}]))
    st = RenderSettings(samples=4, adaptive_threshold=0.0, global_photons=photons,
                        caustic_photons=photons,
                        indirect_mode="preview", threads=0, seed=3)
    photon_mapping.render(clear, st.with_values(global_photons=2000, caustic_photons=2000))
    photon_mapping.render(foggy, st.with_values(global_photons=2000, caustic_photons=2000))
    times = {}
    for name, scene in (("clear", clear), ("fog", foggy)):
        out = photon_mapping.render(scene, st)
        times[name] = out.stats
    s = times["fog"]
    pm = s["photon_maps"]
    stored = pm["volume_stored"] + pm["volume_caustic_stored"]
    print(f"fog (caustic scene, 32x32, 4 spp, {photons:,} + {photons:,} photons, preview): "
          f"{stored:,} volume photons for the camera ({pm['volume_stored']:,} global, "
          f"{pm['volume_caustic_stored']:,} caustic) in a {s['time_photons']:.2f} s photon pass "
          f"= {stored / s['time_photons']:,.0f} volume photons/s (clear scene's photon pass "
          f"{times['clear']['time_photons']:.2f} s, ratio {s['time_photons'] / times['clear']['time_photons']:.2f}); "
          f"camera pass {s['time_render']:.2f} s vs {times['clear']['time_render']:.2f} s "
          f"(ratio {s['time_render'] / times['clear']['time_render']:.2f}); "
          f"beam estimate {s.get('time_volume_beam', 0.0):.2f} s, Volume Direct "
          f"{s.get('time_volume', 0.0):.2f} s")
    print(f"bytes per volume photon: {beam.VolumePhotonMap(np.zeros((4, 3)), np.ones((4, 3)), np.tile([0, 0, 1.0], (4, 1)), np.ones(4)).nbytes / 4:.0f}")


SPARSE_CENTRE, SPARSE_R, SPARSE_RHO, SPARSE_SIGMA = np.array([0.3, 0.0, -0.1]), 0.3, 20.0, 2.0


def sparse_density(points, field=None):
    """A sparse field in the box [-1, 1]^3: rho = 20 (1 - |p - c|^2 / 0.3^2) inside a
    0.3 m ball at c = (0.3, 0, -0.1), 0 elsewhere (1.4 % of the box)."""
    q = np.asarray(points, np.float64) - SPARSE_CENTRE
    return SPARSE_RHO * np.maximum(0.0, 1.0 - (q * q).sum(axis=1) / SPARSE_R ** 2)


def sparse_optical_depth(x, z):
    """The exact optical depth along +y through the ball at (x, z): sigma rho0 (4/3)
    (R^2 - r^2)^(3/2) / R^2, r the distance of the line from the ball's centre."""
    r2 = (x - SPARSE_CENTRE[0]) ** 2 + (z - SPARSE_CENTRE[2]) ** 2
    return SPARSE_SIGMA * SPARSE_RHO * 4.0 / 3.0 * np.maximum(SPARSE_R ** 2 - r2, 0.0) ** 1.5 \
        / SPARSE_R ** 2


def sparse_medium():
    """regions.Medium of the sparse field (absorbing, sigma_a 2/m at rho 1) in a 2 m box."""
    box = shapes.box([-1.0] * 3, [1.0] * 3)
    media = Media.from_list([{"bounds": 0, "name": "Puff", "boundary": box.corners,
                              "sigma_a": np.full(3, SPARSE_SIGMA), "density_texture": 0}])
    fields = DensityFields({0: sparse_density}, {0: (np.full(3, -1.0), np.full(3, 1.0))},
                           ("Puff",))
    return regions.Medium(media, 2.0, 1, fields, seed=1)


def sparse(rays: int):
    """Ratio tracking (``Medium.transmittance``) and delta tracking of ``rays`` rays along
    +y through the sparse box: time, tentative collisions per ray, and the transmittance
    against exp(-optical depth)."""
    rng = np.random.default_rng(3)
    xz = rng.uniform(-1, 1, (rays, 2))
    o = np.column_stack([xz[:, 0], np.full(rays, -3.0), xz[:, 1]])
    d = np.tile([0.0, 1.0, 0.0], (rays, 1))
    med = sparse_medium()
    exact = np.exp(-sparse_optical_depth(xz[:, 0], xz[:, 1]))
    T, dt = timed(lambda: med.transmittance(o, d, np.full(rays, 10.0)))
    st = med.stretches(o, d, np.full(rays, 10.0))
    het = np.flatnonzero(st.field >= 0)
    calls = []

    def counting(points, field):
        calls.append(len(points))
        return (med.fields.along(st.field[het], st.majorant[het]) if hasattr(med.fields, "along")
                else med.fields)(points, field)
    fld = np.arange(het.size) if hasattr(med.fields, "along") else st.field[het]
    start = time.perf_counter()
    tracking.ratio_tracking_batch(counting, o[st.ray[het]], d[st.ray[het]], st.t0[het], st.t1[het],
                                  fld, st.het_a[het] + st.het_s[het], st.majorant[het], 1,
                                  sampling.stream(sampling.MEDIUM_TRANSMITTANCE))
    t_ratio = time.perf_counter() - start
    ratio_points = sum(calls)
    calls.clear()
    start = time.perf_counter()
    _, _, w = tracking.delta_tracking_batch(counting, o[st.ray[het]], d[st.ray[het]], st.t0[het],
                                            st.t1[het], fld, 0.0, 0.0, st.het_a[het], st.het_s[het],
                                            st.majorant[het], 1, sampling.stream(
                                                sampling.MEDIUM_TRACKING, 0, 0, 0))
    t_delta = time.perf_counter() - start
    print(f"sparse heterogeneous box ({rays} rays, majorant {med.fields.majorant[0]:.4g}, "
          f"stretch majorants mean {st.majorant[het].mean():.4g}): "
          f"Medium.transmittance {dt:.2f} s ({rays / dt / 1e3:.1f} k rays/s); "
          f"ratio tracking {ratio_points / rays:.2f} density evaluations per ray, {t_ratio:.2f} s; "
          f"delta tracking {sum(calls) / rays:.2f} per ray, {t_delta:.2f} s; "
          f"mean T {T[:, 0].mean():.5f} +- {T[:, 0].std() / np.sqrt(rays):.5f}, exact "
          f"{exact.mean():.5f}; delta tracking's passing weight {w[:, 0].mean():.5f}")
    med.close()


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--photons", type=int, default=400_000)
    p.add_argument("--rays", type=int, default=20_000)
    p.add_argument("--fog-photons", type=int, default=100_000)
    p.add_argument("--only", choices=["sparse"], default=None,
                   help="run one benchmark only")
    a = p.parse_args()
    if a.only == "sparse":
        sparse(a.rays)
        return
    fog(a.fog_photons)
    slab(a.photons, a.rays)
    inscatter()
    flights()
    spectra()
    sparse(a.rays)


if __name__ == "__main__":
    main()

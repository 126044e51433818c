"""Photons per second: the photon pass against raw Embree on the same scene, in the same run.

    .venv/bin/python benchmarks/bench_photons.py [--global-photons 1000000]
        [--caustic-photons 200000] [--rounds 2]

The scene: the demo's Cornell box (examples/cornell_box.py) built as arrays: white floor,
ceiling and back wall, red and green side walls, open front, a mirror and a glass sphere
(64 x 32 segments), a 0.5 m square area light of 50 W under the ceiling.

Figures (every timing is the best of --rounds, the machine is shared):
- photon pass: photons emitted per second of emission + tracing, and photon rays
  (path segments) per second;
- raw embreex, 2 threads on halves: 2 M incoherent rays (random origins in the box,
  random directions), and exactly the photon pass's own batches replayed;
- time per stage: emission, tracing (Embree + scatter kernels), balancing (PhotonMap);
- memory: tracemalloc's peak of Python/numpy allocations during trace_photons (numpy
  reports its buffers to tracemalloc; Embree's BVH and numba's thread stacks are not
  included) for the full run and for a run with a quarter of the photons: the difference
  divided by the difference in photons is the memory per million photons (the part that
  grows with the count), the rest is fixed (chunk buffers). Also the growth of the
  process's peak RSS (resource.getrusage ru_maxrss) over a first, small run, which
  includes everything (numba, Embree, the allocator's slack).
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import resource
import sys
import tracemalloc

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core.scene import shapes  # noqa: E402
from core.prepared import prepare  # noqa: E402
from core.integrators.photon_terms import trace_maps  # noqa: E402
from core.photons import tracing  # noqa: E402
from core.scene.accel import Accelerator  # noqa: E402
from core.scene.contract import LIGHT_AREA, Lights, Materials, Scene  # noqa: E402
from core.settings import RenderSettings  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_rays  # noqa: E402
from bench_rays import RecordingAccelerator, replay_raw  # noqa: E402


def demo_scene() -> Scene:
    q = shapes.quad
    walls = [
        (q([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0),        # floor, facing +Z
        (q([0, 0, 2], [0, 1, 0], [1, 0, 0]), 0),        # ceiling, facing -Z
        (q([0, 1, 1], [1, 0, 0], [0, 0, 1]), 0),        # back, facing -Y
        (q([-1, 0, 1], [0, 1, 0], [0, 0, 1]), 1),       # left (red), facing +X
        (q([1, 0, 1], [0, 0, 1], [0, 1, 0]), 2),        # right (green), facing -X
    ]
    r = 0.38
    parts = walls + [(shapes.uv_sphere([-0.45, 0.35, r], r, 32, 64), 3),
                     (shapes.uv_sphere([0.45, -0.35, r], r, 32, 64), 4)]
    mesh = shapes.assemble(parts)
    mats = Materials.from_list([
        {"diffuse": [0.725, 0.71, 0.68]}, {"diffuse": [0.63, 0.065, 0.05]},
        {"diffuse": [0.14, 0.45, 0.091]}, {"specular": [0.9, 0.9, 0.9]},
        {"transmission": [1.0, 1.0, 1.0], "ior": 1.5}])
    lights = Lights.from_list([{"kind": LIGHT_AREA, "position": [0, 0, 1.98], "power": 50.0,
                                "size": [0.5, 0.5]}])
    cam = shapes.pinhole([0, -3, 1], [0, 0, 1], 320, 240, np.radians(54.4))
    return Scene(mesh, mats, lights, cam).validate()


def raw_embree(scene: Scene, n_rays: int, seed: int = 0) -> float:
    """Raw embreex INTERSECT rate on incoherent rays in the box, 2 threads (rays/s)."""
    rates = bench_rays.raw_embree(scene, n_rays, seed,
                                  box=((-0.95, -0.95, 0.05), (0.95, 0.95, 1.95)))
    return rates["intersect_2threads"]


def trace(scene, settings, accel=None):
    """The render's photon maps of ``scene`` (``photon_terms.trace_maps``), traced with
    ``accel`` instead of the prepared scene's own when given."""
    with prepare(scene, settings.threads) as prepared:
        if accel is not None:
            prepared.close()
            prepared = dataclasses.replace(prepared, accel=accel)
        return trace_maps(prepared, settings)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--global-photons", type=int, default=1_000_000)
    ap.add_argument("--caustic-photons", type=int, default=200_000)
    ap.add_argument("--bounces", type=int, default=8)
    ap.add_argument("--rays", type=int, default=2_000_000)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()

    scene = demo_scene()
    settings = RenderSettings(global_photons=args.global_photons,
                              caustic_photons=args.caustic_photons,
                              photon_max_bounces=args.bounces, threads=2)
    n_photons = args.global_photons + args.caustic_photons
    print(f"scene: demo Cornell box, {scene.mesh.triangle_count} triangles; "
          f"{args.global_photons} global + {args.caustic_photons} caustic photons, "
          f"{args.bounces} bounces, 2 threads, best of {args.rounds} rounds")
    # Compile / load the kernels and measure the RSS baseline of a small run.
    trace(scene, settings.with_values(global_photons=20_000, caustic_photons=5000))
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    best, raw, replay, peak = None, 0.0, np.inf, 0
    for rnd in range(args.rounds):
        raw = max(raw, raw_embree(scene, args.rays))
        acc = RecordingAccelerator(Accelerator(scene.mesh, threads=2)) if rnd == 0 else \
            Accelerator(scene.mesh, threads=2)
        if rnd == 0:
            tracemalloc.start()
        maps = trace(scene, settings, accel=acc)
        if rnd == 0:
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            replay = replay_raw(scene, acc.batches)
            acc.batches.clear()
        else:
            st = maps.stats
            if best is None or st["time_tracing"] + st["time_emission"] < \
                    best["time_tracing"] + best["time_emission"]:
                best = st
        acc.close()
    if best is None:
        best = maps.stats
    # Split the full run's peak: tracing (chunks + stored float32 photons) vs the
    # PhotonMap construction (balancing) that follows.
    real_map, split = tracing.PhotonMap, {"tracing": 0, "build": 0}

    class MeasuredMap(real_map):
        """The tracer builds its maps with ``PhotonMap.from_parts``: measured here."""

        @classmethod
        def from_parts(cls, *a, **kw):
            if not split["tracing"]:  # the first build: both maps are traced by then
                split["tracing"] = tracemalloc.get_traced_memory()[1]
            tracemalloc.reset_peak()
            pm = real_map.from_parts(*a, **kw)
            split["build"] = max(split["build"], tracemalloc.get_traced_memory()[1])
            return pm

    tracing.PhotonMap = MeasuredMap  # the tracer's maps, built through the measuring one
    tracemalloc.start()
    try:
        trace(scene, settings)
    finally:
        tracemalloc.stop()
        tracing.PhotonMap = real_map
    quarter = settings.with_values(global_photons=args.global_photons // 4,
                                   caustic_photons=args.caustic_photons // 4)
    tracemalloc.start()
    trace(scene, quarter)
    peak_q = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    n_q = args.global_photons // 4 + args.caustic_photons // 4
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    st = best
    t_pass = st["time_emission"] + st["time_tracing"]
    photon_rate = n_photons / t_pass
    ray_rate = st["photon_rays"] / t_pass
    print(f"maps: global {st['global_stored']} photons stored, caustic {st['caustic_stored']}; "
          f"{st['photon_rays'] / n_photons:.2f} rays per emitted photon")
    print(f"stages: emission {st['time_emission']:.3f} s, tracing {st['time_tracing']:.3f} s "
          f"(Embree {st['time_intersect']:.3f} s, scatter {st['time_scatter']:.3f} s), "
          f"balancing {st['time_balancing']:.3f} s, whole pass {st['time_photons']:.3f} s")
    print(f"photon pass: {photon_rate / 1e6:.3f} M photons/s, {ray_rate / 1e6:.3f} M photon rays/s")
    print(f"raw embreex, 2 threads, incoherent rays in the box: {raw / 1e6:.3f} M rays/s")
    print(f"raw embreex on the photon pass's own batches: {st['photon_rays'] / replay / 1e6:.3f} M rays/s")
    print(f"ratio photons/s / raw rays/s (goal >= 0.5): {photon_rate / raw:.2f}")
    print(f"ratio photon rays/s / raw rays/s: {ray_rate / raw:.2f}; "
          f"/ raw on the same batches: {replay / t_pass:.2f}")
    per_m = (peak - peak_q) / ((n_photons - n_q) / 1e6)
    print(f"memory: tracemalloc peak {peak / 2**20:.1f} MiB ({n_photons} photons), "
          f"{peak_q / 2**20:.1f} MiB ({n_q}): {per_m / 2**20:.1f} MiB per million photons "
          f"emitted + {(peak - per_m * n_photons / 1e6) / 2**20:.1f} MiB fixed; peak RSS growth "
          f"over the small run {(rss1 - rss0) / 1024:.1f} MiB")
    print(f"memory split: tracing peak {split['tracing'] / 2**20:.1f} MiB, PhotonMap construction "
          f"peak {split['build'] / 2**20:.1f} MiB")
    if maps.global_map is not None:
        print(f"photon map storage: {maps.global_map.nbytes / 2**20:.1f} MiB global, "
              f"{(maps.caustic_map.nbytes if maps.caustic_map is not None else 0) / 2**20:.1f} MiB caustic")


if __name__ == "__main__":
    main()

"""Photon map speed next to scipy's cKDTree, measured in the same run.

    .venv/bin/python benchmarks/bench_photon_map.py            # 1e5 and 1e6 photons, 1e6 queries
    .venv/bin/python benchmarks/bench_photon_map.py --quick    # a small run (seconds)

For each photon distribution (uniform in a box; a caustic: most photons in a few small
Gaussian blobs on a plane) and size, times
- building: ``PhotonMap(positions, flux, directions)`` (encoding and balancing) against
  ``cKDTree(positions)``, best of a few;
- gathering: the k nearest photons of M query points drawn from the same distribution,
  ``PhotonMap.nearest(points, k, inf)`` against ``cKDTree.query(points, k, workers=-1)``
  (both with no radius limit, so both always return k photons), in chunks of at most
  ``--chunk`` points so the results fit in memory, the two alternating chunk by chunk.
Prints a markdown table: seconds, ratios ours / cKDTree (below 1 is faster), bytes per
photon. numba's compile (or cache load) time is measured separately, on tiny data first.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

import numba  # noqa: E402

from core.photons.photon_map import BYTES_PER_PHOTON, PhotonMap  # noqa: E402


def photons(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) float32 positions, metres."""
    if kind == "uniform":
        return (rng.random((n, 3)) * [4.0, 3.0, 2.5]).astype(np.float32)
    # A caustic: 90 % of the photons in five blobs (sigma 1 to 3 cm) on the floor plane,
    # the rest spread over the 2 m x 2 m floor.
    centres = rng.random((5, 2)) * 1.6 + 0.2
    sigma = np.array([0.01, 0.015, 0.02, 0.025, 0.03])
    blob = rng.integers(0, 5, n)
    xy = centres[blob] + rng.normal(size=(n, 2)) * sigma[blob, None]
    stray = rng.random(n) < 0.1
    xy[stray] = rng.random((int(stray.sum()), 2)) * 2.0
    return np.c_[xy, np.zeros(n)].astype(np.float32)


def best_of(repeats, fn):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return min(times), result


def compile_time() -> float:
    """First calls on tiny data: numba compiles the kernels (or loads them from cache)."""
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    pm = PhotonMap(rng.random((300, 3)), rng.random((300, 3)), rng.normal(size=(300, 3)))
    pm.nearest(rng.random((1000, 3)), 5, np.inf)
    return time.perf_counter() - t


def gather_times(pm, tree, queries, k, chunk):
    ours = theirs = 0.0
    for start in range(0, queries.shape[0], chunk):
        q = queries[start:start + chunk]
        t = time.perf_counter()
        idx, dist2 = pm.nearest(q, k, np.inf)
        ours += time.perf_counter() - t
        t = time.perf_counter()
        dist, _ = tree.query(q, k, workers=-1)
        theirs += time.perf_counter() - t
        if start == 0:  # the same neighbours, up to float32 rounding of the distances
            err = np.abs(np.sqrt(dist2.astype(np.float64)) - dist).max()
            assert (idx >= 0).all() and err < 1e-3, f"distances disagree with cKDTree ({err})"
        del idx, dist2, dist
    return ours, theirs


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1e4 and 1e5 photons, 1e5 queries")
    parser.add_argument("--sizes", type=float, nargs="+", help="photon counts")
    parser.add_argument("--queries", type=float, help="query points per measurement")
    parser.add_argument("--k", type=int, nargs="+", default=[50, 200])
    parser.add_argument("--chunk", type=float, default=250_000, help="queries per call")
    parser.add_argument("--repeats", type=int, default=3, help="builds timed (best kept)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    sizes = [int(s) for s in (args.sizes or ([1e4, 1e5] if args.quick else [1e5, 1e6]))]
    m = int(args.queries or (1e5 if args.quick else 1e6))
    chunk = int(args.chunk)

    first = compile_time()
    print(f"numba: {numba.get_num_threads()} threads ({numba.threading_layer()} layer); "
          f"compile or cache load: {first:.2f} s; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores (other work inflates both columns)")
    print(f"queries per measurement: {m:,}; photon map: {BYTES_PER_PHOTON} bytes/photon "
          "(cKDTree holds a float64 copy and int64 indices, 32 bytes, plus its nodes)")
    print()
    print("| photons | distribution | build ours (s) | build cKDTree (s) | ratio | k "
          "| gather ours (s) | gather cKDTree (s) | ratio | bytes/photon |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    rng = np.random.default_rng(args.seed)
    for n in sizes:
        for kind in ("uniform", "caustic"):
            positions = photons(kind, n, rng)
            flux = rng.random((n, 3)) * 1e-3
            directions = rng.normal(size=(n, 3))
            queries = photons(kind, m, rng)
            t_ours, pm = best_of(args.repeats, lambda: PhotonMap(positions, flux, directions))
            t_ckd, tree = best_of(args.repeats, lambda: cKDTree(positions))
            bpp = pm.nbytes / n
            for k in args.k:
                g_ours, g_ckd = gather_times(pm, tree, queries, k, chunk)
                print(f"| {n:.0e} | {kind} | {t_ours:.3f} | {t_ckd:.3f} | {t_ours / t_ckd:.2f} "
                      f"| {k} | {g_ours:.2f} | {g_ckd:.2f} | {g_ours / g_ckd:.2f} | {bpp:.0f} |",
                      flush=True)
            del pm, tree
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

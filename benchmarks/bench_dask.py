"""One frame's progressive passes on local:1 and local:2 Dask clusters, in one run: the
speed-up, the bytes sent per pass, the merge time, and the projected speed-up on 8, 64 and
512 machines (the scene broadcast and the merge are the serial parts; Amdahl).

    .venv/bin/python benchmarks/bench_dask.py [--passes 64] [--photons 100000] [--block 4]

The frame: the demo's Cornell box (examples/cornell_box.py's scene through core, no
Blender) if it can be built, else the caustic scene at 160 x 120. Each cluster is warmed
(numba kernels loaded in its workers) by a 2-pass render first.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from core.integrators import distributed  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from sppm_convergence import caustic_scene  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=48)
    ap.add_argument("--photons", type=int, default=100_000)
    ap.add_argument("--block", type=int, default=4)
    ap.add_argument("--width", type=int, default=160)
    args = ap.parse_args()
    scene = caustic_scene(1.0, args.width, args.width * 3 // 4)
    settings = RenderSettings().with_values(
        integrator="progressive", threads=1, photons_per_pass=args.photons,
        progressive_passes=args.passes, progressive_block=args.block)
    times, outs = {}, {}
    for n in (1, 2):
        with distributed.connect(f"local:{n}") as c:
            c.client.wait_for_workers(n, timeout=300)
            distributed.render(scene, settings.with_values(progressive_passes=2 * n,
                                                           progressive_block=1), c.client)
            t0 = time.perf_counter()
            outs[n] = distributed.render(scene, settings, c.client)
            times[n] = time.perf_counter() - t0
    same = np.array_equal(outs[1].passes["combined"], outs[2].passes["combined"])
    st = outs[2].stats
    per_pass_bytes = st["bytes_per_block"] / args.block
    merge_per_block = st["time_merge"] / max(st["tasks"], 1)
    pass_time = st["time_tasks"] / args.passes       # worker seconds per pass
    print(f"frame {scene.camera.width} x {scene.camera.height}, {args.passes} passes x "
          f"{args.photons:,} photons, blocks of {args.block}")
    print(f"local:1 {times[1]:.2f} s, local:2 {times[2]:.2f} s: speed-up "
          f"{times[1] / times[2]:.2f} (2 workers); images identical: {same}")
    print(f"scene broadcast {st['scene_bytes'] / 1e6:.2f} MB in {st['time_scatter']:.3f} s; "
          f"{per_pass_bytes / 1e3:.1f} kB returned per pass ({st['bytes_per_block'] / 1e3:.1f} "
          f"kB per block); merge {merge_per_block * 1e3:.2f} ms per block "
          f"({st['time_merge']:.3f} s in all); a pass costs {pass_time * 1e3:.1f} ms of worker time")
    # Projection (Amdahl): a frame with 8 blocks per machine, so every machine stays busy;
    # the serial parts measured above: the scene broadcast (a tree: log2 N rounds) and the
    # client receiving (1 Gbit/s) and merging every block, overlapped with the work.
    for n in (8, 64, 512):
        passes = 8 * n * args.block
        work = pass_time * passes
        transfer = passes / args.block * (st["bytes_per_block"] / 125e6 + merge_per_block)
        t_n = st["time_scatter"] * (1 + np.log2(n)) + max(work / n, transfer)
        print(f"projected {n:4d} machines, {passes:,} passes: speed-up {work / t_n:6.1f} "
              f"({work / t_n / n:.2f} N); receive + merge {transfer:.1f} s vs work/N "
              f"{work / n:.1f} s")


if __name__ == "__main__":
    main()

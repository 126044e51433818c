"""SPPM on the artist scene (benchmarks/tradeoff.py's ``artist``: Principled walls, a glossy
floor of roughness 0.1, copper, gold and frosted spheres) against its cached Cycles
reference: relMSE and mean ratio at a few pass counts (issue 13's glossy visible points).

    .venv/bin/python benchmarks/sppm_artist.py [--passes 16,64] [--photons 50000] [--seed 0]

The reference is tradeoff.py's (benchmarks/references/artist_48x36.npz: Cycles, 2 x 4096
samples, 8 bounces); relMSE = mean((a - b)^2 / (b^2 + 0.01)) as there. Only SPPM runs here
(no presets, no Cycles), so it takes a few minutes instead of tradeoff.py's half hour.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import tradeoff  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", default="16,64")
    ap.add_argument("--photons", type=int, default=tradeoff.SPPM_PHOTONS)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    marks = tuple(int(p) for p in args.passes.split(","))
    resolution = tradeoff.QUICK_RESOLUTION
    ref = np.load(tradeoff.REF_DIR / f"artist_{resolution[0]}x{resolution[1]}.npz")
    image = ref["image"].astype(np.float64)
    pm = tradeoff.PhotonMap()
    tradeoff.caustic_scene((8, 6))
    pm.progressive((1,), 1000)  # numba kernels compiled or loaded before the timing
    tradeoff.artist_scene(resolution)
    t0 = time.perf_counter()
    found = pm.progressive(marks, args.photons, seed=args.seed)
    print(f"artist {resolution[0]}x{resolution[1]}, {args.photons:,} photons/pass, seed "
          f"{args.seed} ({time.perf_counter() - t0:.1f} s)")
    print("| passes | wall s | relMSE | mean ratio |")
    print("|---:|---:|---:|---:|")
    for passes, (img, wall) in sorted(found.items()):
        print(f"| {passes} | {wall:.1f} | {tradeoff.rel_mse(img, image):.4f} | "
              f"{tradeoff.mean_ratio(img, image):.3f} |", flush=True)
    out = ROOT / "out"
    out.mkdir(exist_ok=True)
    np.savez_compressed(out / f"sppm_artist_seed{args.seed}.npz",
                        **{f"p{k}": v[0] for k, v in found.items()}, reference=image)


if __name__ == "__main__":
    main()

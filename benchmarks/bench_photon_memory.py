"""Memory at the peak of building a PhotonMap, in bytes per stored photon.

What the tracer does (core/photons/tracing.py ``_balance``): the photons stored arrive as per-bounce
pieces of float32 positions, flux and directions (36 B per photon), and become a
PhotonMap (23 B per photon). Each case runs in a fresh process: make the pieces, build
the map, and report (highest RSS during the build - RSS before the pieces were made) /
photons, so the pieces themselves are counted (they are freed during the build). The peak
is read from /proc/self/status VmHWM after resetting it (/proc/self/clear_refs "5"), so
numba's own allocations (invisible to tracemalloc) are counted too.

Baseline in the same run: the same photons through ``PhotonMap(concatenated arrays)``,
the constructor a caller holding whole arrays uses (its inputs stay alive).

    .venv/bin/python benchmarks/bench_photon_memory.py [--photons 2000000 8000000]
        [--core PATH]   # the folder holding another core/ to measure (e.g. an old checkout)
"""

import argparse
import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
PIECE = 1 << 18  # photons per piece, like a bounce of one tracer chunk

CHILD = r"""
import json, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from core.photons.photon_map import PhotonMap

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024
    raise KeyError(key)

n, piece, how = int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
rng = np.random.default_rng(1)
# Warm up: load the kernels (compiled or cached) before measuring.
PhotonMap.from_parts if hasattr(PhotonMap, "from_parts") else None
PhotonMap(rng.random((1000, 3), dtype=np.float32), rng.random((1000, 3), dtype=np.float32),
          rng.normal(size=(1000, 3)).astype(np.float32))
before = status("VmRSS")
open("/proc/self/clear_refs", "w").write("5")
pos, flux, dirs = [], [], []
for lo in range(0, n, piece):
    m = min(piece, n - lo)
    pos.append(rng.random((m, 3), dtype=np.float32))
    flux.append(rng.random((m, 3), dtype=np.float32))
    dirs.append(rng.normal(size=(m, 3)).astype(np.float32))
if how == "parts":
    pm = PhotonMap.from_parts(pos, flux, dirs)
else:  # the old tracer: concatenate each array, then the whole-array constructor
    arrays = []
    for parts in (pos, flux, dirs):
        arrays.append(np.concatenate(parts))
        parts.clear()
    pm = PhotonMap(*arrays)
    del arrays
peak = status("VmHWM")
after = status("VmRSS")
print(json.dumps({"peak": peak - before, "kept": after - before, "nbytes": pm.nbytes}))
"""


def measure(core_root, n, how):
    done = subprocess.run([sys.executable, "-c", CHILD, str(core_root), str(n), str(PIECE), how],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photons", type=int, nargs="+", default=[2_000_000, 8_000_000])
    parser.add_argument("--core", default=str(ROOT),
                        help="folder whose core/ is measured (default: this checkout)")
    args = parser.parse_args(argv)
    has_parts = (pathlib.Path(args.core) / "core" / "photon_map.py").read_text().count(
        "def from_parts") > 0
    print(f"core: {args.core}/core; pieces of {PIECE:,} photons; goal: peak < 60 B per photon")
    print(f"{'photons':>12} {'path':>14} {'peak B/photon':>14} {'kept B/photon':>14}")
    for n in args.photons:
        for how in (("parts", "whole") if has_parts else ("whole",)):
            r = measure(args.core, n, how)
            label = "from_parts" if how == "parts" else "whole arrays"
            print(f"{n:>12,} {label:>14} {r['peak'] / n:>14.1f} {r['kept'] / n:>14.1f}")


if __name__ == "__main__":
    main()

"""Does this bpy's Cycles still match the cached Cycles references in tests/data/?

    .venv/bin/python tools/cycles_version_check.py [--samples 256] [demo four_lights ...]

The references were rendered by tests/blender/cycles_reference.py with one Blender
version (the ``blender`` field of each .npz); this renders each scene again with the
running bpy's Cycles (two seeds, for the noise) and prints the per-channel mean ratio
and the worst 8x8 block against the cached image, with the combined standard error.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

from tests.blender import cycles_reference as ref  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("names", nargs="*", default=list(ref.SCENES))
    parser.add_argument("--samples", type=int, default=256)
    args = parser.parse_args(argv)
    for name in args.names:
        cached = ref.load_reference(name)
        a = ref.render_cycles(ref.SCENES[name](), args.samples, seed=11)
        b = ref.render_cycles(ref.SCENES[name](), args.samples, seed=12)
        sigma = np.hypot(ref.block_sigma(a, b), cached["block_sigma"])
        fig = ref.compare((a + b) / 2, cached["image"], sigma)
        within = np.nanmax(fig["excess"])
        print(f"{name}: Cycles {bpy.app.version_string} vs cached {cached['blender']}: channel "
              f"{np.round(100 * fig['channel'], 3)} %, worst block {100 * fig['worst_block']:.2f} %, "
              f"max excess {within:.2f} (<= 1: within 5 % + 3 sigma)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

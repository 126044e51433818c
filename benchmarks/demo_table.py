"""Render time of the demo against photon count and k: the table in docs/photon_rendering.md.

    .venv/bin/python benchmarks/demo_table.py [--resolution 160x120] [--samples 16]
        [--photons 50000,200000,800000] [--k 25,50,100]

Builds the demo's Cornell box (examples/cornell_box.py) in bpy, exports it once with the
engine's exporter, then renders it with the core for every (global photons, k) pair:
caustic photons = global photons / 2, caustic_k = global_k = k, final gathering with the
demo's gather rays. Prints a Markdown table: photons stored, the photon pass (tracing,
balancing, radiance cache), the camera pass (final gathering and caustics included) and
the total, in seconds. One warm-up render first, so numba's compilation is not counted.
The machine is shared: figures are wall-clock times of one run each.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

GATHER_RAYS = 128
"""Final-gather rays per pixel in every row (the table varies photons and k only)."""


def _ints(text):
    return [int(v) for v in text.split(",")]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="160x120")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--photons", type=_ints, default=[50_000, 200_000, 800_000])
    parser.add_argument("--k", type=_ints, default=[25, 50, 100])
    args = parser.parse_args(argv)
    w, h = (int(v) for v in args.resolution.lower().split("x"))

    import bpy

    from examples import cornell_box

    package = cornell_box.load_photon_map()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = cornell_box.build_cornell_box(resolution=(w, h))
    from importlib import import_module

    export = import_module(f"{package.__name__}.photon_engine.export")
    integrator = import_module(f"{package.__name__}.core.integrators.photon_mapping")
    settings_mod = import_module(f"{package.__name__}.core.settings")
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get()).scene

    def render(photons, k):
        st = settings_mod.RenderSettings(
            samples=args.samples, adaptive_threshold=0.0, global_photons=photons,
            caustic_photons=photons // 2,
            global_k=k, caustic_k=k, final_gather_rays=GATHER_RAYS)
        return integrator.render(exported, st).stats

    render(20_000, 20)  # warm-up: numba caches, Embree
    print(f"Demo scene, {w}x{h}, {args.samples} samples/pixel, "
          f"{GATHER_RAYS} gather rays/pixel (seconds, one run each)\n")
    print("| global / caustic photons emitted | k | stored global / caustic | photon pass "
          "| camera pass | total |")
    print("|---:|---:|---:|---:|---:|---:|")
    for photons in args.photons:
        for k in args.k:
            s = render(photons, k)
            print(f"| {photons:,} / {photons // 2:,} | {k} | {s['global_photons_stored']:,} / "
                  f"{s['caustic_photons_stored']:,} | {s['time_photons']:.1f} | "
                  f"{s['time_render']:.1f} | {s['time_total']:.1f} |", flush=True)


if __name__ == "__main__":
    main()

"""Is Cycles a reference for the volumetric caustic at a given spot light radius, and does
Photon Map agree with it there? (issue 16; figures in docs/volumes.md, "The volumetric
caustic against Cycles").

tests/blender/cycles_media_reference.py's fog scenes with the spot light's radius set to
--radius metres (its scenes use 0.1 m):
- the IOR-1 check: Cycles' image mean with an index-matched glass sphere (IOR 1, which
  must change nothing) against no sphere, --seeds seeds of --samples samples each (the
  spread of the per-seed means gives the standard error);
- with --photon-map, Photon Map (the media tests' settings, PHOTON_MAP_SETTINGS) on the
  scene without the sphere against Cycles' mean.

    .venv/bin/python benchmarks/media_light_radius.py --radius 1.0 --samples 512 --seeds 2 --photon-map
    .venv/bin/python benchmarks/media_light_radius.py --radius 0.4 --samples 1024 --seeds 4 --no-light-tree
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import scenes  # noqa: E402


def build(radius: float, sphere_ior: float | None):
    """The fog_spot scene (sphere_ior None) or fog_caustic with the sphere's IOR set, the
    spot light's radius ``radius`` metres."""
    scene = media.fog_spot_scene(sphere=sphere_ior is not None)
    bpy.data.lights["Spot"].shadow_soft_size = radius
    if sphere_ior is not None:
        glass = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
        glass.inputs["IOR"].default_value = sphere_ior
    return scene


def cycles_means(radius, sphere_ior, samples, seeds, light_tree=True) -> np.ndarray:
    """(seeds,) Cycles image means (all channels) of seeds 1..seeds."""
    means = []
    for seed in range(1, seeds + 1):
        scene = media.configure_cycles_media(build(radius, sphere_ior), samples, seed)
        scene.cycles.use_light_tree = light_tree
        means.append(float(scenes.render_passes(scene)["Combined"][..., :3].mean()))
    return np.array(means)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--radius", type=float, default=1.0, help="spot light radius, metres")
    ap.add_argument("--samples", type=int, default=512)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--no-light-tree", action="store_true")
    ap.add_argument("--photon-map", action="store_true")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    found = {}
    for label, ior in (("no sphere", None), ("IOR 1 sphere", 1.0)):
        m = cycles_means(args.radius, ior, args.samples, args.seeds, not args.no_light_tree)
        found[label] = m
        err = m.std(ddof=1) / np.sqrt(m.size) if m.size > 1 else float("nan")
        print(f"radius {args.radius} m, Cycles {args.seeds} x {args.samples} spp, {label}: "
              f"mean {m.mean():.5f} +- {err:.5f}", flush=True)
    ratio = found["IOR 1 sphere"].mean() / found["no sphere"].mean() - 1.0
    print(f"IOR 1 sphere / no sphere - 1 = {100 * ratio:+.2f} % (must be 0)")
    if args.photon_map:
        scene = build(args.radius, None)
        scenes.use_photon_map(scene, **media.PHOTON_MAP_SETTINGS)
        pm = float(scenes.render_passes(scene)["Combined"][..., :3].mean())
        print(f"Photon Map (PHOTON_MAP_SETTINGS), no sphere: mean {pm:.5f}, "
              f"/ Cycles - 1 = {100 * (pm / found['no sphere'].mean() - 1):+.2f} %")
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

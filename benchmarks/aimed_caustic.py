"""Aimed caustic photons from point and spot lights of radius > 0 (issue 16): the share of
aimed photons that enter their target and the flux they carry into it, and the caustic
photons stored in fog_caustic_1m's layout, by the core of the tree ROOT (e.g. main's, as
a baseline) and by this tree's, in the same run (each in its own process: both are
imported as ``core``).

- hit: one target sphere, 2^17 aimed photons: a 1 m soft-falloff spot light (50 degrees,
  blend 0.2) with a 0.255 m sphere 0.8 m below; the same as a sphere light; a 0.25 m
  point light with a 0.25 m sphere 2.5 m away. "flux" is what the photons that enter
  carry (W; the light's 100 W): equal in expectation in both trees.
- fog_caustic_1m (tests/blender/cycles_media_reference.py) built in core arrays: a 4 m
  floor (albedo 0.6) in World fog (sigma_s 0.175, sigma_a 0.075 /m, g 0.3), a glass
  sphere (IOR 1.5, 0.25 m) 1.2 m up, a 200 W spot (50 degrees, blend 0.2, radius 1 m)
  2 m up: caustic photons stored on surfaces and in the fog of --photons emitted, per
  seed 1..--seeds (global map skipped).

    .venv/bin/python benchmarks/aimed_caustic.py ROOT --seeds 3
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from core.photons import emission, tracing
from core.prepared import prepare
from core.scene import shapes
from core.scene.bounds import Targets
from core.scene.contract import LIGHT_POINT, LIGHT_SPOT, Lights, Materials, Scene
from core.scene.media import Media
from core.lights.light_set import EmissiveTriangles, LightSet
from core.settings import RenderSettings

seeds, photons = int(sys.argv[2]), int(sys.argv[3])
out = {"hit": {}, "stored": []}
no_tris = EmissiveTriangles.from_mesh(shapes.assemble([]), Materials.from_list([]))
spot = dict(kind=LIGHT_SPOT, position=(0.0, 0.0, 0.0), power=100.0, radius=1.0,
            spot_size=np.radians(50.0), spot_blend=0.2)
cases = {"1 m soft spot, 0.255 m sphere 0.8 m below": (spot, (0.0, 0.0, -0.8), 0.255),
         "1 m sphere spot, same": (dict(spot, soft_falloff=False), (0.0, 0.0, -0.8), 0.255),
         "0.25 m point, 0.25 m sphere 2.5 m away": (
             dict(kind=LIGHT_POINT, position=(0.0, 0.0, 0.0), power=100.0, radius=0.25),
             (0.0, 0.0, -2.5), 0.25)}
for name, (light, c, r) in cases.items():
    ls = LightSet.from_lights(Lights.from_list([light]))
    t = Targets(np.array([c], float), np.array([r]))
    src = emission.Source(0, np.zeros(3), name)
    _, p = emission.aimed_power(src, ls, no_tris, t, np.zeros(3), 5.0)
    n = 1 << 17
    em = emission.emit(src, ls, no_tris, np.zeros(3), np.zeros(3), 5.0, n, 0, n, seed=0,
                       map_id=0, source_slot=0, targets=t, target_prob=p)
    oc = em.origin - np.array(c)
    b = np.sum(oc * em.direction, axis=1)
    disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
    hit = (disc >= 0) & (-b + np.sqrt(np.maximum(disc, 0.0)) > 0)
    out["hit"][name] = [float(hit.mean()), float(em.flux[hit, 0].sum())]

mesh = shapes.assemble([(shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0]), 0),
                        (shapes.uv_sphere([0, 0, 1.2], 0.25, 24, 48), 1)])
mats = Materials.from_list([{"diffuse": [0.6] * 3}, {"transmission": [1, 1, 1], "ior": 1.5}])
lights = Lights.from_list([dict(kind=LIGHT_SPOT, position=(0.0, 0.0, 2.0), power=200.0,
                                radius=1.0, spot_size=np.radians(50.0), spot_blend=0.2)])
media = Media.from_list([{"sigma_s": [0.175] * 3, "sigma_a": [0.075] * 3,
                          "anisotropy": 0.3, "name": "Fog"}])
cam = shapes.pinhole([0, -4.5, 1.2], [0, 0, 0.8], 48, 36, 0.9)
scene = Scene(mesh, mats, lights, cam, media=media).validate()
for seed in range(1, seeds + 1):
    st = RenderSettings(seed=seed, caustic_photons=photons, photon_max_bounces=8, threads=2)
    prepared = prepare(scene, 2, seed)
    try:
        s = tracing.trace_photons(prepared, st, skip={"global": "benchmark"}).stats
    finally:
        prepared.close()
    out["stored"].append([s["caustic_stored"], s["volume_caustic_stored"]])
print("RESULT" + json.dumps(out))
"""


def run(root: pathlib.Path, seeds: int, photons: int) -> dict:
    """The child's figures for the core of ``root``."""
    done = subprocess.run([sys.executable, "-c", CHILD, str(root), str(seeds), str(photons)],
                          capture_output=True, text=True, check=True)
    line = next(x for x in done.stdout.splitlines() if x.startswith("RESULT"))
    return json.loads(line[len("RESULT"):])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("root", help="the baseline tree (its core is imported as core)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--photons", type=int, default=100_000, help="caustic photons emitted")
    a = ap.parse_args(argv)
    base = run(pathlib.Path(a.root).resolve(), a.seeds, a.photons)
    this = run(HERE, a.seeds, a.photons)
    print(f"aimed photons entering the target (2^17), flux they carry (W): {a.root} -> this tree")
    for name, (h0, f0) in base["hit"].items():
        h1, f1 = this["hit"][name]
        print(f"  {name}: {100 * h0:.2f} % -> {100 * h1:.2f} %, {f0:.4f} -> {f1:.4f} W")
    print(f"fog_caustic_1m, {a.photons:,} caustic photons emitted, seeds 1-{a.seeds}: "
          "stored on surfaces / in the fog")
    for seed, (s0, s1) in enumerate(zip(base["stored"], this["stored"]), 1):
        print(f"  seed {seed}: {s0[0]:,} / {s0[1]:,} -> {s1[0]:,} / {s1[1]:,}")


if __name__ == "__main__":
    main()

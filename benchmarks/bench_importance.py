"""What photon importance costs and what it gains (core/photons/importance.py).

    .venv/bin/python benchmarks/bench_importance.py [--photons 100000] [--reference 2000000]
        [--pass-photons 1000000] [--scenes behind,next]

Scenes (arrays, no Blender), 64 x 48, 2 samples, 32 final-gather rays:
- behind: the demo's Cornell box (bench_photons.demo_scene) with a second light, a 20 W
  point lamp behind the camera shining in through the open front;
- next: the demo plus a closed 2 m room 1.5 m to its right with a 500 W lamp inside
  (light the camera never sees, ten times the demo light's power).

For each: the photon pass with importance on (--pass-photons global, a fifth as many
caustic): its pre-pass time (camera rays, pilot photons) against the pass; then renders
at --photons global photons (half as many caustic) with importance on and off and off
at 4x the photons, against a reference at --reference photons (importance off), all
with seed 0, so they differ from the reference by their photon maps only:
relMSE = mean((a - b)^2 / (b^2 + 0.01)) over pixels and channels, for the combined image
and the indirect and caustics passes.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from bench_photons import demo_scene  # noqa: E402
from core.integrators import photon_mapping as integrator  # noqa: E402
from core.scene import shapes  # noqa: E402
from core.integrators.photon_terms import trace_maps  # noqa: E402
from core.prepared import prepare  # noqa: E402
from core.scene.contract import LIGHT_POINT, Lights, Scene  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.metrics import rel_mse  # noqa: E402


def _with(scene: Scene, extra_parts=(), extra_lights=(), width=96, height=72) -> Scene:
    """The scene's objects (one material each, as in the demo) plus parts and lights."""
    mesh = scene.mesh
    corners = mesh.vertices[mesh.triangles].astype(np.float64)
    parts = []
    for o in np.unique(mesh.object_index):
        sel = mesh.object_index == o
        parts.append((shapes.Part(corners[sel], mesh.normals[sel].astype(np.float64)),
                      int(mesh.material_index[sel][0])))
    rows = [{"kind": int(scene.lights.kind[i]), "to_world": scene.lights.to_world[i],
             "power": float(scene.lights.power[i]), "size": scene.lights.size[i],
             "name": f"Demo light {i}"} for i in range(scene.lights.count)] + list(extra_lights)
    cam = shapes.pinhole([0, -3, 1], [0, 0, 1], width, height, np.radians(54.4))
    return Scene(shapes.assemble(parts + list(extra_parts)), scene.materials,
                 Lights.from_list(rows), cam).validate()


def scenes(width=64, height=48):
    demo = demo_scene()
    behind = _with(demo, width=width, height=height, extra_lights=[{"kind": LIGHT_POINT, "position": [0.3, -4.0, 1.5],
                                        "power": 20.0, "name": "Lamp behind the camera"}])
    room = shapes.box([2.5, -1, 0], [4.5, 1, 2], inward=True)
    nextdoor = _with(demo, width=width, height=height, extra_parts=[(room, 0)],
                     extra_lights=[{"kind": LIGHT_POINT, "position": [3.5, 0, 1.5], "power": 500.0,
                                    "name": "Lamp next room"}])
    return {"demo + lamp behind the camera": behind, "demo + lamp in the next room": nextdoor}


def trace(scene, settings):
    """The photon maps a render of ``scene`` traces (importance pre-pass included)."""
    with prepare(scene, settings.threads) as prepared:
        return trace_maps(prepared, settings)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--photons", type=int, default=200_000)
    ap.add_argument("--reference", type=int, default=4_000_000)
    ap.add_argument("--pass-photons", type=int, default=1_000_000,
                    help="global photons of the cost measurement (caustic: a fifth)")
    ap.add_argument("--scenes", default="behind,next", help="behind, next or both")
    args = ap.parse_args()
    base = RenderSettings(samples=2, adaptive_threshold=0.0, final_gather_rays=32, threads=2,
                          seed=0)
    wanted = args.scenes.split(",")
    for key, (name, scene) in zip(("behind", "next"), scenes().items()):
        if key not in wanted:
            continue
        print(f"== {name}")
        # Cost: the pass with importance on, the pre-pass inside it.
        st = base.with_values(global_photons=args.pass_photons,
                              caustic_photons=args.pass_photons // 5)
        trace(scene, st.with_values(global_photons=20_000, caustic_photons=4000))
        pm = trace(scene, st)
        imp = pm.stats["importance"]
        work = pm.stats["time_emission"] + pm.stats["time_tracing"]
        print(f"pass {args.pass_photons:,} + {args.pass_photons // 5:,} photons: emission + "
              f"tracing {work:.2f} s, whole pass {pm.stats['time_photons']:.2f} s; importance "
              f"{imp['time']:.3f} s (camera {imp['time_camera']:.3f} s, {imp['camera_rays']:,} "
              f"rays; pilot {imp['time_pilot']:.3f} s, {imp['pilot_rays']:,} rays) = "
              f"{imp['time'] / work:.1%} of emission + tracing, "
              f"{imp['time'] / pm.stats['time_photons']:.1%} of the pass")
        for line in pm.stats["decisions"]:
            print("   ", line, flush=True)
        # Gain: relMSE against the reference at equal photon count. The seed drives the
        # camera samples too: seed 0 everywhere, so the renders differ from the reference
        # by their photon maps only.
        t0 = time.perf_counter()
        ref = integrator.render(scene, base.with_values(
            global_photons=args.reference, caustic_photons=args.reference // 2,
            photon_importance=False)).passes
        print(f"reference ({args.reference:,} photons) {time.perf_counter() - t0:.1f} s", flush=True)
        for n, on in ((args.photons, True), (args.photons, False), (4 * args.photons, False)):
            st = base.with_values(global_photons=n, caustic_photons=n // 2, photon_importance=on)
            t0 = time.perf_counter()
            out = integrator.render(scene, st)
            dt = time.perf_counter() - t0
            errs = ", ".join(f"{p} {rel_mse(out.passes[p], ref[p]):.5f}"
                             for p in ("combined", "indirect", "caustics"))
            print(f"  {n:,} + {n // 2:,} photons, importance {'on ' if on else 'off'}: relMSE "
                  f"{errs}; {dt:.1f} s", flush=True)


if __name__ == "__main__":
    main()

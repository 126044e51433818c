"""Seeded renders of tests/core/scenes.caustic_scene (24 x 24: mirror, glass, diffuse) by
the core of the tree ROOT, saved to OUT.npz: final gathering, preview and SPPM (2 passes),
every pass; and of the demo box with benchmarks/bench_shader.py's 25-node wood program on
its Principled walls (32 x 24, final gathering and SPPM: the programs at camera, gather
and photon hits). Run it on two trees and compare with np.array_equal to check that a
change renders bit for bit as before (e.g. the interpreter's speed-ups, issue 14):

    .venv/bin/python tools/seeded_renders.py ROOT OUT.npz
"""

import sys

root, out = sys.argv[1], sys.argv[2]
sys.path.insert(0, root)
sys.path.insert(0, root + "/tests/core")
sys.path.insert(0, root + "/benchmarks")

import numpy as np  # noqa: E402

from core.integrators import photon_mapping, sppm  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from scenes import caustic_scene  # noqa: E402

res = {}
sc = caustic_scene(width=24, height=24)
for mode in ("final_gather", "preview"):
    st = RenderSettings(samples=2, global_photons=5000, caustic_photons=5000,
                        final_gather_rays=4, indirect_mode=mode, threads=2)
    for k, v in photon_mapping.render(sc, st).passes.items():
        res[f"{mode}/{k}"] = v
st = RenderSettings(integrator="progressive", progressive_passes=2, photons_per_pass=3000,
                    threads=2)
for k, v in sppm.render(sc, st).passes.items():
    res[f"sppm/{k}"] = v
if len(sys.argv) < 4 or sys.argv[3] != "--no-textured":
    import bench_shader  # noqa: E402

    wood = bench_shader.textured_demo(bench_shader.wood_program()[0], 32)
    st = RenderSettings(samples=2, global_photons=5000, caustic_photons=5000,
                        final_gather_rays=4, threads=2)
    for k, v in photon_mapping.render(wood, st).passes.items():
        res[f"textured/final_gather/{k}"] = v
    st = RenderSettings(integrator="progressive", progressive_passes=2,
                        photons_per_pass=3000, threads=2)
    for k, v in sppm.render(wood, st).passes.items():
        res[f"textured/sppm/{k}"] = v
np.savez(out, **res)
print("saved", len(res), "passes to", out)

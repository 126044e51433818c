"""Issue 13: the artist scene with the specular layer of the walls / floor switched off
(Principled "Specular IOR Level" 0), Cycles (1024 spp) against Photon Map Preview (seeds 0, 1).

    .venv/bin/python benchmarks/probe_artist_layers.py walls|floor|both|none|diffuse
"""
import json
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from benchmarks import tradeoff as tb  # noqa: E402


def main():
    which = sys.argv[1]
    spp = int(sys.argv[2]) if len(sys.argv) > 2 else 1024
    pm = tb.PhotonMap()
    scene = tb.artist_scene((48, 36))
    mats = {"walls": ["Wall"], "floor": ["GlossyFloor"], "both": ["Wall", "GlossyFloor"],
            "none": [], "diffuse": ["Wall", "GlossyFloor"]}[which]
    if which == "diffuse":  # a Lambert-like room: no spheres either
        for name in ("Copper", "Gold", "Frosted"):
            bpy.data.objects.remove(bpy.data.objects[name])
    for m in mats:
        node = bpy.data.materials[m].node_tree.nodes["Principled BSDF"]
        node.inputs["Specular IOR Level"].default_value = 0.0
    t0 = time.perf_counter()
    ref, _ = tb.cycles_render(scene, spp, seed=7)
    tc = time.perf_counter() - t0
    core_scene = pm.export_scene()
    variants = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {"base": {}}
    for label, values in variants.items():
      for seed in (0, 1):
        settings = pm.presets.preset_settings("preview").with_values(seed=seed, **values)
        out = pm.integrator.render(core_scene, settings)
        P = {k: v.astype(np.float64)[..., :3] for k, v in out.passes.items()}
        rm = ref.mean()
        print(json.dumps(dict(spec_off=which, variant=label, seed=seed, cycles_spp=spp, cycles_s=round(tc, 1),
                              mean=round(P["combined"].mean() / rm, 4),
                              ind_caus=round((P["indirect"].mean() + P["caustics"].mean()) / rm, 4),
                              caustics=round(P["caustics"].mean() / rm, 4),
                              direct_spec=round((P["direct"].mean() + P["specular"].mean()) / rm, 4))),
              flush=True)


if __name__ == "__main__":
    main()

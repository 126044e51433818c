"""Issue 13 diagnosis: the artist scene's diffuse indirect excess, one variation at a time.

    .venv/bin/python benchmarks/probe_artist_variants.py VARIANT[,VARIANT...] [--seeds 0,1]

Prints per variant and seed: the image mean ratio vs the cached Cycles reference
(benchmarks/references/artist_48x36.npz), (indirect + caustics) / reference mean and the
two terms apart, and block ratios (top rows: ceiling, bottom rows: floor, the side columns).
"""
import json
import sys
import time
import pathlib
from importlib import import_module

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import numpy as np  # noqa: E402
from benchmarks import tradeoff as tb  # noqa: E402

RES = (48, 36)

VARIANTS = {
    "base": {},
    "photons4": dict(global_photons=800_000, caustic_photons=400_000),
    "k_half": dict(global_k=25, caustic_k=25),
    "photons4_k_half": dict(global_photons=800_000, caustic_photons=400_000, global_k=25,
                            caustic_k=25),
    "nocache": {},
    "nocaustic": dict(caustics=False),
    "noafterglossy": {},
    "nowallglossy": {},
    "mode_preview": dict(indirect_mode="preview"),
    "filter_none": dict(filter="none"),
    "pmb7": dict(photon_max_bounces=7),
    "pmb9": dict(photon_max_bounces=9),
}


def main():
    names = sys.argv[1].split(",")
    seeds = [0, 1]
    if "--seeds" in sys.argv:
        seeds = [int(s) for s in sys.argv[sys.argv.index("--seeds") + 1].split(",")]
    pm = tb.PhotonMap()
    pkg = pm.integrator.__name__.split(".")[0]
    gather = import_module(f"{pkg}.core.integrators.gather")
    pmi = pm.integrator
    prep_mod = import_module(f"{pkg}.core.prepared")
    est = import_module(f"{pkg}.core.photons.estimate")
    ref = np.load(ROOT / "benchmarks/references/artist_48x36.npz")["image"].astype(np.float64)
    tb.artist_scene(RES)
    core_scene = pm.export_scene()
    rm = ref.mean()
    h = ref.shape[0]
    w = ref.shape[1]
    blocks = {"top": (slice(0, h // 4), slice(None)), "bottom": (slice(3 * h // 4, h), slice(None)),
              "left": (slice(h // 4, 3 * h // 4), slice(0, w // 6)),
              "right": (slice(h // 4, 3 * h // 4), slice(5 * w // 6, w)),
              "centre": (slice(h // 4, 3 * h // 4), slice(w // 6, 5 * w // 6))}
    orig_cache = gather.build_radiance_cache
    orig_after = pmi.GLOBAL_AFTER_GLOSSY
    orig_prepare = pmi.prepare if hasattr(pmi, "prepare") else None
    orig_plane = est.PLANE_FRACTION
    for name in names:
        values = VARIANTS[name]
        gather.build_radiance_cache = (lambda *a, **k: None) if name == "nocache" else orig_cache
        pmi.GLOBAL_AFTER_GLOSSY = False if name == "noafterglossy" else orig_after
        for seed in seeds:
            settings = pm.presets.preset_settings("preview").with_values(seed=seed, **values)
            if name == "nowallglossy":
                import dataclasses
                real = prep_mod.prepare

                def patched(*a, **k):
                    p = real(*a, **k)
                    return dataclasses.replace(p, glossy_on_diffuse=np.zeros_like(p.glossy_on_diffuse))
                pmi.prepare = patched
            t0 = time.perf_counter()
            out = pmi.render(core_scene, settings)
            wall = time.perf_counter() - t0
            if name == "nowallglossy":
                pmi.prepare = orig_prepare
            P = {k: v.astype(np.float64) for k, v in out.passes.items()}
            img = P["combined"][..., :3]
            row = dict(variant=name, seed=seed, wall=round(wall, 2),
                       mean=round(img.mean() / rm, 4),
                       ind_caus=round((P["indirect"][..., :3].mean() + P["caustics"][..., :3].mean()) / rm, 4),
                       indirect=round(P["indirect"][..., :3].mean() / rm, 4),
                       caustics=round(P["caustics"][..., :3].mean() / rm, 4),
                       direct_spec=round((P["direct"][..., :3].mean() + P["specular"][..., :3].mean()) / rm, 4),
                       r_g=round(out.stats.get("global_radius", 0), 4),
                       r_c=round(out.stats.get("caustic_radius", 0), 4))
            for b, sl in blocks.items():
                row[b] = round(img[sl].mean() / ref[sl].mean(), 4)
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()

"""One setting of one benchmark scene over several seeds: error, noise and time.

    .venv/bin/python benchmarks/probe_seeds.py SCENE WxH PRESET [SETTINGS_JSON] [--seeds N] [--passes]

SCENE is one of benchmarks/tradeoff.py's SCENES with a cached reference at WxH
(benchmarks/references/<scene>_<W>x<H>.npz); PRESET one of core/presets.py's qualities,
SETTINGS_JSON values changed on top of it (e.g. '{"samples": 64, "adaptive_threshold": 0}').
Prints the median wall time (export excluded, numba warm after the first seed's render),
relMSE against the reference per seed and their mean, the noise (relMSE of the seeds'
spread: the mean over pixels of their variance over (reference^2 + 0.01)), the image's
mean ratio, the mean samples per pixel, and with --passes each pass's mean and noise.
A single seed's relMSE is a poor guide where fireflies rule: compare means over seeds.
"""
import argparse
import json
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import numpy as np  # noqa: E402

from benchmarks import tradeoff as tb  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", choices=sorted(tb.SCENES))
    ap.add_argument("resolution")
    ap.add_argument("preset")
    ap.add_argument("settings", nargs="?", default="{}")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--passes", action="store_true")
    args = ap.parse_args()
    w, h = map(int, args.resolution.split("x"))
    ref = tb.load_reference(args.scene, (w, h))
    if ref is None:
        sys.exit(f"no reference: {tb.regenerate_command(args.scene, (w, h))}")
    ref = ref["image"][..., :3].astype(np.float64)
    den = ref ** 2 + 0.01
    pm = tb.PhotonMap()
    tb.SCENES[args.scene]((w, h))
    scene = pm.export_scene()
    extra = json.loads(args.settings)
    walls, rel, images, spp = [], [], [], []
    for seed in range(args.seeds):
        st = pm.presets.preset_settings(args.preset).with_values(seed=seed, **extra)
        t0 = time.perf_counter()
        out = pm.integrator.render(scene, st)
        walls.append(time.perf_counter() - t0)
        images.append({k: v[..., :3].astype(np.float64) for k, v in out.passes.items()
                       if k != "photons"})
        rel.append(float(np.mean((images[-1]["combined"] - ref) ** 2 / den)))
        spp.append(out.stats.get("samples_mean", st.samples))
    combined = np.stack([i["combined"] for i in images])
    noise = float(np.mean(combined.var(axis=0, ddof=1) / den)) if args.seeds > 1 else float("nan")
    print(f"{args.scene} {args.resolution} {args.preset} {extra}: wall {np.median(walls):.2f} s, "
          f"relMSE {np.mean(rel):.5f} [{', '.join(f'{r:.4f}' for r in rel)}], noise {noise:.5f}, "
          f"mean ratio {combined.mean() / ref.mean():.4f}, samples per pixel {np.mean(spp):.1f}")
    if args.passes:
        for name in images[0]:
            a = np.stack([i[name] for i in images])
            print(f"  {name:16s} mean / reference mean {a.mean() / ref.mean():.4f}, noise "
                  f"{np.mean(a.var(axis=0, ddof=1) / den):.5f}")


if __name__ == "__main__":
    main()

"""Cost of the closure evaluator per hit: sample_bsdf (one direction, with the whole
material's eval and pdf behind a rough lobe) and eval_bsdf (one direction), in ns per call
on one thread, for each closure kind, with Lambert as the baseline measured in the same run.

    .venv/bin/python benchmarks/bench_closures.py [--n 200000]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core.materials import closure  # noqa: E402
from core.scene import closures as cl  # noqa: E402
from core.scene import contract  # noqa: E402

KINDS = {
    "Lambert (Diffuse r=0)": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(roughness=0.0)),
    "Oren-Nayar": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(roughness=0.5)),
    "Glossy multiscatter GGX": dict(kind=cl.CLOSURE_GLOSSY, params=dict(roughness=0.4)),
    "Metallic F82": dict(kind=cl.CLOSURE_METALLIC, params=dict(roughness=0.4)),
    "Glass rough": dict(kind=cl.CLOSURE_GLASS, params=dict(roughness=0.3)),
    "Glossy Beckmann": dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        roughness=0.4, distribution=cl.DISTRIBUTION_BECKMANN)),
    "Refraction Beckmann": dict(kind=cl.CLOSURE_REFRACTION, params=dict(
        roughness=0.2, ior=1.45, distribution=cl.DISTRIBUTION_BECKMANN)),
    "Sheen": dict(kind=cl.CLOSURE_SHEEN),
    "Principled default": dict(kind=cl.CLOSURE_PRINCIPLED),
    "Principled all layers": dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        transmission=0.3, coat_weight=1.0, sheen_weight=1.0, metallic=0.3,
        diffuse_roughness=0.3)),
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=200_000)
    n = ap.parse_args().n
    tab = closure.table(contract.Materials.from_list([{"closures": [c]} for c in KINDS.values()]))
    rng = np.random.default_rng(0)
    u = rng.random((n, 3))
    wo = np.array([0.3, 0.2, 0.93])
    wo /= np.linalg.norm(wo)
    z = np.array([0.0, 0.0, 1.0])
    t = np.array([1.0, 0.0, 0.0])
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    closure.sample_many(tab, 0, wo, z, z, t, True, u[:10])  # compile
    closure.eval_many(tab, 0, wo, wi[:10], z, z, t, True)
    base = None
    print(f"{'closure':28s} {'sample ns':>10s} {'eval ns':>10s} {'x Lambert':>10s}")
    for m, name in enumerate(KINDS):
        t0 = time.perf_counter()
        closure.sample_many(tab, m, wo, z, z, t, True, u)
        ts = (time.perf_counter() - t0) / n * 1e9
        t0 = time.perf_counter()
        closure.eval_many(tab, m, wo, wi, z, z, t, True)
        te = (time.perf_counter() - t0) / n * 1e9
        base = base or ts
        print(f"{name:28s} {ts:10.0f} {te:10.0f} {ts / base:10.2f}")


if __name__ == "__main__":
    main()

"""White furnace of every closure kind: the directional albedo (uniform environment of
radiance 1) by Monte Carlo of sample_bsdf's path weights, at several view angles, with the
standard error; and the directional albedo of Principled BSDF at base colour 1 with every
layer on. The figures docs/materials.md quotes.

    .venv/bin/python benchmarks/furnace_closures.py [--n 400000]
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from core.materials import closure  # noqa: E402
from core.scene import closures as cl  # noqa: E402
from core.scene import contract  # noqa: E402

KINDS = {
    "Lambert": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=1.0, roughness=0.0)),
    "Oren-Nayar r=1": dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=1.0, roughness=1.0)),
    "Translucent": dict(kind=cl.CLOSURE_TRANSLUCENT, params=dict(color=1.0)),
    "Sheen r=0.5": dict(kind=cl.CLOSURE_SHEEN, params=dict(color=1.0, roughness=0.5)),
    "Glossy GGX r=0.5": dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        color=1.0, roughness=0.5, distribution=cl.DISTRIBUTION_GGX)),
    "Glossy multi-GGX r=0.5": dict(kind=cl.CLOSURE_GLOSSY, params=dict(color=1.0, roughness=0.5)),
    "Metallic multi r=1": dict(kind=cl.CLOSURE_METALLIC, params=dict(color=1.0, roughness=1.0)),
    "Metallic GGX r=1": dict(kind=cl.CLOSURE_METALLIC, params=dict(
        color=1.0, roughness=1.0, distribution=cl.DISTRIBUTION_GGX)),
    "Glass multi r=0.5": dict(kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.5)),
    "Refraction r=0.5": dict(kind=cl.CLOSURE_REFRACTION, params=dict(color=1.0, roughness=0.5)),
    "Principled default": dict(kind=cl.CLOSURE_PRINCIPLED),
    "Principled white all layers": dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        color=1.0, roughness=0.4, transmission=0.3, coat_weight=1.0, coat_roughness=0.2,
        sheen_weight=1.0, sheen_roughness=0.3, diffuse_roughness=0.3, subsurface_weight=0.2)),
}
ANGLES = (0.0, 45.0, 75.0, 88.0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=400_000)
    n = ap.parse_args().n
    tab = closure.table(contract.Materials.from_list([{"closures": [c]} for c in KINDS.values()]))
    u = np.random.default_rng(1).random((n, 3))
    z = np.array([0.0, 0.0, 1.0])
    t = np.array([1.0, 0.0, 0.0])
    print(f"{'closure':30s}" + "".join(f"{a:>16.0f}" for a in ANGLES) + "   (deg; albedo +- s.e.)")
    for m, name in enumerate(KINDS):
        row = []
        for a in ANGLES:
            r = np.radians(a)
            wo = np.array([np.sin(r), 0.0, np.cos(r)])
            s = closure.sample_many(tab, m, wo, z, z, t, True, u)
            w = np.where(s[:, 7] > 0, s[:, 3], 0.0)
            row.append(f"{w.mean():9.4f}+-{w.std() / np.sqrt(n):.4f}")
        print(f"{name:30s}" + "".join(f"{c:>16s}" for c in row))


if __name__ == "__main__":
    main()

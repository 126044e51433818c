"""SPPM convergence in World fog: relMSE against a photon-mapping reference vs passes.

    .venv/bin/python benchmarks/sppm_fog_convergence.py                  # the table (docs/sppm.md)
    .venv/bin/python benchmarks/sppm_fog_convergence.py --make-reference # tests/data/sppm_fog_ref.npz

The scene (tests/core/scenes.fog_scene, also the tests'): a floor and a back wall in
homogeneous World fog (sigma_s 0.25, sigma_a 0.05 1/m, g 0.3) under a 300 W point light,
24 x 24 pixels. The reference is the other integrator (core/integrators/photon_mapping.py,
final gathering, its own volume photon maps with k-NN radii) at high counts: independent
of the code under test (its Volume Direct shares volume.py's shadow-ray estimator, its
beam estimate and surface estimates do not share the progressive radii).
relMSE = mean((a - b)^2 / (b^2 + 0.01)) over pixels and channels.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.integrators import photon_mapping, sppm  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import fog_scene  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "sppm_fog_ref.npz"
REF_SETTINGS = dict(seed=99, samples=64, global_photons=1_000_000, caustics=False, threads=2)
PHOTONS_PER_PASS = 20_000


def rel_mse(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return float(np.mean((a - b) ** 2 / (b * b + 0.01)))


def make_reference() -> None:
    t0 = time.perf_counter()
    out = photon_mapping.render(fog_scene(), RenderSettings(**REF_SETTINGS))
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(REFERENCE, image=out.passes["combined"],
                        command="benchmarks/sppm_fog_convergence.py --make-reference",
                        settings=repr(REF_SETTINGS))
    print(f"wrote {REFERENCE} in {time.perf_counter() - t0:.1f} s")


def table(max_passes: int, seed: int) -> None:
    """Both forms of SPPM: direct light (and Volume Direct) by shadow rays, the default,
    and by photons (standard SPPM)."""
    ref = np.load(REFERENCE)["image"]
    settings = RenderSettings().with_values(seed=seed, threads=2)
    marks = {1, 4, 16, 64, 256, 1024}
    rows = {}
    for direct in sppm.DIRECT_MODES:
        sppm.render(fog_scene(8, 8), settings.with_values(  # compile outside the timing
            progressive_passes=1, photons_per_pass=100, progressive_direct=direct))
        t0 = time.perf_counter()
        for state in sppm.progressive_passes(fog_scene(), settings.with_values(
                photons_per_pass=PHOTONS_PER_PASS, progressive_direct=direct), max_passes):
            if state.passes in marks:
                img = state.radiance()
                rows.setdefault(state.passes, []).append(
                    f"{time.perf_counter() - t0:.1f} | {rel_mse(img, ref):.4f} | "
                    f"{img.mean() / ref.mean():.3f}")
    print("| passes | shadow-ray direct: wall s | relMSE | mean ratio "
          "| photon direct: wall s | relMSE | mean ratio |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for k, cells in rows.items():
        print(f"| {k} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--make-reference", action="store_true")
    ap.add_argument("--passes", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.make_reference:
        make_reference()
    else:
        table(args.passes, args.seed)


if __name__ == "__main__":
    main()

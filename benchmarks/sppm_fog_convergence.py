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

from benchmarks.sppm_convergence import convergence_table  # noqa: E402
from core.integrators import photon_mapping  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import fog_scene  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "sppm_fog_ref.npz"
REF_SETTINGS = dict(seed=99, samples=64, global_photons=1_000_000, caustics=False, threads=2)
PHOTONS_PER_PASS = 20_000


def make_reference() -> None:
    t0 = time.perf_counter()
    out = photon_mapping.render(fog_scene(), RenderSettings(**REF_SETTINGS))
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(REFERENCE, image=out.passes["combined"],
                        command="benchmarks/sppm_fog_convergence.py --make-reference",
                        settings=repr(REF_SETTINGS))
    print(f"wrote {REFERENCE} in {time.perf_counter() - t0:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--make-reference", action="store_true")
    ap.add_argument("--passes", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.make_reference:
        make_reference()
    else:
        # Direct light and Volume Direct by shadow rays (the default) or by photons.
        convergence_table(fog_scene, np.load(REFERENCE)["image"],
                          RenderSettings().with_values(seed=args.seed, threads=2),
                          PHOTONS_PER_PASS, args.passes)


if __name__ == "__main__":
    main()

"""SPPM convergence on the caustic scene: relMSE against a reference vs passes and wall time.

    .venv/bin/python benchmarks/sppm_convergence.py                  # the table (docs/sppm.md)
    .venv/bin/python benchmarks/sppm_convergence.py --make-reference # tests/data/sppm_caustic_ref.npz

The scene (tests/core/scenes.caustic_scene, also the tests'): a 4 x 4 m diffuse floor
(albedo 0.8), a glass sphere (radius 0.5 m, ior 1.5) 0.1 m above it, a 200 W point light
(radius 0) at (0.3, 0, 2.5) m, a 32 x 32 pinhole camera. The reference is SPPM itself with
1024 passes of 32 000 photons and another seed, direct light by photons (about 25 s on
one core); the test's independent oracle is the diffuse-only check against the
integrator (test_sppm.py). The table shows both forms (``sppm.DIRECT_MODES``).
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

from core.integrators import sppm  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import caustic_scene  # noqa: E402
from tests.metrics import rel_mse  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "sppm_caustic_ref.npz"
REF_PASSES, REF_PHOTONS, REF_SEED = 1024, 32_000, 99
PHOTONS_PER_PASS = 25_000


def make_reference() -> None:
    t0 = time.perf_counter()
    # Standard SPPM (direct light by photons): the form the stored reference was made with.
    out = sppm.render(caustic_scene(), RenderSettings().with_values(
        seed=REF_SEED, threads=1, progressive_passes=REF_PASSES, photons_per_pass=REF_PHOTONS,
        progressive_direct="photons"))
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(REFERENCE, image=out.passes["combined"],
                        command="benchmarks/sppm_convergence.py --make-reference",
                        passes=REF_PASSES, photons_per_pass=REF_PHOTONS, seed=REF_SEED)
    print(f"wrote {REFERENCE} in {time.perf_counter() - t0:.1f} s")


def convergence_table(build, reference: np.ndarray, settings: RenderSettings,
                      photons_per_pass: int, max_passes: int) -> None:
    """Print SPPM's convergence on the scene ``build()`` in both forms
    (``sppm.DIRECT_MODES``: direct light by shadow rays, the default, and by photons,
    standard SPPM), ``photons_per_pass`` photons a pass: at 1, 4, 16, ... passes up to
    ``max_passes``, wall time (from the first pass, numba compiled before), relMSE and mean
    ratio against ``reference`` (H, W, 3), a markdown row per pass count."""
    marks = {1, 4, 16, 64, 256, 1024}
    rows: dict[int, list[str]] = {}
    for direct in sppm.DIRECT_MODES:
        sppm.render(build(8, 8), settings.with_values(  # compile outside the timing
            progressive_passes=1, photons_per_pass=100, progressive_direct=direct))
        t0 = time.perf_counter()
        for state in sppm.progressive_passes(build(), settings.with_values(
                photons_per_pass=photons_per_pass, progressive_direct=direct), max_passes):
            if state.passes in marks:
                img = state.radiance()
                rows.setdefault(state.passes, []).append(
                    f"{time.perf_counter() - t0:.2f} | {rel_mse(img, reference):.4f} | "
                    f"{img.mean() / reference.mean():.3f}")
    print("| passes | photons | shadow-ray direct: wall s | relMSE | mean ratio "
          "| photon direct: wall s | relMSE | mean ratio |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for k, cells in rows.items():
        print(f"| {k} | {k * photons_per_pass:,} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--make-reference", action="store_true")
    ap.add_argument("--passes", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.make_reference:
        make_reference()
    else:
        convergence_table(caustic_scene, np.load(REFERENCE)["image"],
                          RenderSettings().with_values(seed=args.seed, threads=1),
                          PHOTONS_PER_PASS, args.passes)


if __name__ == "__main__":
    main()

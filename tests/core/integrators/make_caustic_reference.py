"""Make tests/data/pm_caustic_ref.npz: the caustic scene of test_sppm.py rendered by the
photon-mapping integrator at high settings, the reference SPPM converges to (a different
algorithm: photon maps, k-nearest estimates and final gathering, not SPPM's passes).

    .venv/bin/python tests/core/integrators/make_caustic_reference.py
"""

import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))

from core import render  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import caustic_scene  # noqa: E402

REFERENCE = ROOT / "tests" / "data" / "pm_caustic_ref.npz"
SETTINGS = dict(seed=7, samples=256, global_photons=2_000_000, caustic_photons=4_000_000,
                global_k=200, caustic_k=200, final_gather_rays=1024)


def main() -> None:
    t0 = time.perf_counter()
    out = render(caustic_scene(), RenderSettings().with_values(**SETTINGS))
    np.savez_compressed(REFERENCE, image=out.passes["combined"],
                        command="tests/core/integrators/make_caustic_reference.py",
                        settings=repr(SETTINGS))
    print(f"wrote {REFERENCE} in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()

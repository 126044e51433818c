"""docs/images/prism.png: the rainbow caustic of a dispersive prism (docs/dispersion.md).

tests/core/scenes.prism_scene (a 60-degree prism of n_d 1.5168 1 m above a white floor, a
white spot light, narrowed to 0.04 rad, through its left face) rendered by the core at
192 x 144 through the tests' camera position with a narrower field of view (0.55 rad), three times side
by side: Dispersion 0 (off: a white caustic), 64.17 (N-BK7, crown glass) and 20 (a glass
more dispersive than any flint, to show the spread). The same seed, photons and settings
each time; only the material's Abbe number changes.

    .venv/bin/python tools/prism_picture.py [OUT_DIR]   (default docs/images)
"""

import pathlib
import sys
import time
from dataclasses import replace

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import render  # noqa: E402
from core.io.exr import save_png  # noqa: E402
from core.scene import shapes  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from tests.core.scenes import prism_scene  # noqa: E402

ABBE = (0.0, 64.17, 20.0)
CAMERA = shapes.pinhole([4.4, -2.2, 2.0], [4.35, 0.0, 0.0], 192, 144, 0.55)


def main():
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "images"
    settings = RenderSettings().with_values(
        samples=4, global_photons=100_000, caustic_photons=4_000_000, caustic_k=50,
        final_gather_rays=16, threads=2, seed=7)
    images = []
    for abbe in ABBE:
        t0 = time.perf_counter()
        scene = replace(prism_scene(abbe, spot_size=0.04), camera=CAMERA)  # zoomed in
        res = render(scene, settings)
        img = res.passes["combined"].astype(np.float64)
        assert np.all(np.isfinite(img)) and np.all(img >= 0)
        print(f"V_d {abbe:g}: {time.perf_counter() - t0:.1f} s, mean RGB "
              f"{np.round(img.reshape(-1, 3).mean(axis=0), 5)}")
        images.append(img)
    path = save_png(str(out / "prism.png"), np.clip(np.concatenate(images, axis=1), 0, 1))
    print("wrote", path)


if __name__ == "__main__":
    main()

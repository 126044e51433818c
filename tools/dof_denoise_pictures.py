"""The pictures of docs/blender.md, "Depth of field and denoising".

    .venv/bin/python tools/dof_denoise_pictures.py [--out docs/images]

dof.png: tests/blender/test_dof.py's scene at 192 x 144, pinhole | f/0.1 focused on the
second sphere | 5 blades, ratio 1.6. denoise.png: the demo at 128 x 96 with the Preview
preset, as rendered | through the Denoise setting's compositor | Converged.
"""

import argparse
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402,F401

from core.io.exr import save_png  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes, test_dof  # noqa: E402
from tests.blender.test_denoise import composite  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "images")
    out = parser.parse_args().out
    test_dof.SIZE = (192, 144)
    images = []
    for args in (dict(use_dof=False), dict(), dict(blades=5, rotation=0.4, ratio=1.6)):
        scene = test_dof.dof_scene(**args)
        scenes.use_photon_map(scene, samples=64, seed=1)
        images.append(scenes.render_passes(scene)["Combined"][..., :3])
    save_png(str(out / "dof.png"), np.clip(np.concatenate(images, axis=1), 0, 1))
    print("wrote", out / "dof.png")

    from photon_map.photon_engine.cli import apply_quality

    images = []
    with tempfile.TemporaryDirectory() as tmp:
        for quality, denoise in (("preview", False), ("preview", True), ("converged", False)):
            scene = ref.demo_scene(resolution=(128, 96))
            scenes.use_photon_map(scene, seed=5)
            apply_quality(scene.photon_map, quality)
            scene.photon_map.denoise = denoise
            images.append(composite(scene, pathlib.Path(tmp) / f"{quality}{denoise}.exr"))
            scene.photon_map.denoise = False
    save_png(str(out / "denoise.png"), np.clip(np.concatenate(images, axis=1), 0, 1))
    print("wrote", out / "denoise.png")


if __name__ == "__main__":
    main()

"""A picture of Rendered shading in the 3D viewport for the README (docs/images).

    .venv/bin/python tools/viewport_picture.py [--out docs/images/viewport_rendered.png]
        [--passes 64] [--photons 100000]

Builds the demo's Cornell box (examples/cornell_box.py) inside Debian's Blender 3.4 (the
``bpy`` module has no GPU), opens it with a window on a virtual X server (``xvfb-run``),
looks through the camera in Rendered shading with Photon Map, waits until Viewport Passes
passes are done and saves a screenshot of the 3D view (tests/blender/viewport_window.py,
the script the viewport test runs too). Needs ``apt-get install blender
xvfb`` (tools/setup.sh installs both).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None):
    from tests.blender import debian_blender

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "viewport_rendered.png"))
    parser.add_argument("--passes", type=int, default=64)
    parser.add_argument("--photons", type=int, default=100_000)
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        seen = debian_blender.render_in_viewport(pathlib.Path(tmp), "cornell", out, args.passes,
                                                 args.photons, window=(900, 700), timeout=700)
    print("VIEWPORT", json.dumps(seen))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

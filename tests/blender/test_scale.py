"""Scale invariance: the demo scaled by 1e-3 and by 1e3 (light power x scale^2, so the
irradiance is unchanged), or moved to (1e4, 1e4, 1e4), renders the same image as the demo
itself, within the renders' noise. Ray offsets that do not scale with the scene show up
here as acne or light leaks (too small) or missing contact shadows (too large).
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_reference as ref  # noqa: E402

pytestmark = pytest.mark.blender

SAMPLES = 256  # the same as the Cycles comparison of the demo, whose render is reused


@pytest.mark.parametrize("scale, offset", [
    (1e-3, (0.0, 0.0, 0.0)),
    (1e3, (0.0, 0.0, 0.0)),
    (1.0, (1e4, 1e4, 1e4)),
])
def test_demo_is_scale_and_translation_invariant(scale, offset):
    base, sigma_base, _ = ref.photon_map_pair("demo", SAMPLES)
    image, sigma, _ = ref.photon_map_pair("demo", SAMPLES, scale=scale, offset=offset)
    figures = ref.compare(image, base, np.sqrt(sigma_base**2 + sigma**2))
    print(f"\nscale {scale:g}, offset {offset}: channel {np.round(100 * figures['channel'], 3)} %, "
          f"worst block {100 * figures['worst_block']:.2f} %, "
          f"worst excess {np.nanmax(figures['excess']):.2f}")
    assert np.all(np.isfinite(image)) and image.min() >= 0
    assert np.all(np.abs(figures["channel"]) < 0.01), figures["channel"]
    assert np.nanmax(figures["excess"]) <= 1.0

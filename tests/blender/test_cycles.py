"""Photon Map against Cycles, the unit reference: same bpy scene, Cycles restricted to what
Photon Map computes now (emission + direct light + perfect specular chains; see
cycles_reference.py for the settings and why), compared at 64 x 48.

Cycles' images are cached in tests/data/ (two seeds of 1024 samples each, with the
standard error of their 8 x 8 block means); ``cycles_reference.py`` re-renders them.
Photon Map renders twice with different seeds, which gives its own noise. A block passes
when |PM - Cycles| <= 5 % of Cycles + 3 sigma (sigma: both renders' noise); the image
means per channel must agree within 2 %.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Vector  # noqa: E402

from tests.blender import cycles_reference as ref  # noqa: E402

pytestmark = pytest.mark.blender

# Photon Map samples per pixel (over both seeds): the demo's glass and mirror need more.
SAMPLES = {"demo": 256, "four_lights": 128, "visible_lights": 256,
           "point": 64, "spot": 64, "sun": 64, "area": 64}


def report(name, figures):
    blocks = figures["blocks"]
    print(f"\n{name}: channel means PM/Cycles - 1 = {np.round(100 * figures['channel'], 2)} %, "
          f"worst block {100 * figures['worst_block']:.1f} %, "
          f"median |block| {100 * np.nanmedian(np.abs(blocks)):.2f} %, "
          f"worst excess {np.nanmax(figures['excess']):.2f}, "
          f"noise-limited blocks {100 * figures['noisy_blocks']:.0f} %")


@pytest.mark.parametrize("name", list(ref.SCENES))
def test_matches_cycles(name):
    cycles = ref.load_reference(name)
    image, sigma_pm, passes = ref.photon_map_pair(name, SAMPLES[name])
    assert np.all(np.isfinite(image)) and image.min() >= 0
    sigma = np.sqrt(sigma_pm**2 + cycles["block_sigma"].astype(np.float64) ** 2)
    figures = ref.compare(image, cycles["image"], sigma)
    report(name, figures)
    assert np.all(np.abs(figures["channel"]) < 0.02), figures["channel"]
    bad = np.argwhere(figures["excess"] > 1.0)
    assert bad.size == 0, (f"blocks (row, col, channel) off by more than 5 % + 3 sigma: "
                           f"{bad.tolist()}, relative differences "
                           f"{[round(float(figures['blocks'][tuple(b)]), 3) for b in bad]}")


def _pixel_rays(scene, cam_obj, pixels):
    """World origin and unit directions (N, 3) through pixel centres, built from Blender's
    own camera frame (``Camera.view_frame``), independent of the exporter."""
    w, h = scene.render.resolution_x, scene.render.resolution_y
    frame = [Vector(v) for v in cam_obj.data.view_frame(scene=scene)]  # tr, br, bl, tl
    tr, br, bl, tl = (np.array(v) for v in frame)
    u = (pixels[:, 0] + 0.5) / w
    v = 1.0 - (pixels[:, 1] + 0.5) / h
    local = bl + u[:, None] * (br - bl) + v[:, None] * (tl - bl)
    m = np.array(cam_obj.matrix_world)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    d = local @ rot.T
    return m[:3, 3], d / np.linalg.norm(d, axis=1, keepdims=True)


def _hit_sphere(o, d, centre, radius):
    """Distance (N,) to the first hit of rays o + t d on a sphere, inf when missed."""
    oc = o - np.asarray(centre)
    b = np.einsum("ij,ij->i", np.broadcast_to(oc, d.shape), d)
    c = np.einsum("ij,ij->i", np.broadcast_to(oc, d.shape), np.broadcast_to(oc, d.shape)) - radius**2
    disc = b * b - c
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc > 0) & (t > 0), t, np.inf)


def test_mirror_sphere_shows_the_red_wall():
    """A pixel on the mirror sphere whose reflected ray reaches the red wall: Photon Map
    shows the wall there, with the mirror's tint: 0.9 x the wall's own radiance where the
    camera sees that spot of the wall directly (a Lambertian wall looks the same from
    every direction), and the same value as Cycles."""
    from examples import cornell_box as box

    scene = ref.demo_scene()
    bpy.context.view_layer.update()  # matrix_world of the new objects
    cam_obj = scene.camera
    w, h = scene.render.resolution_x, scene.render.resolution_y
    cols, rows = np.meshgrid(np.arange(w), np.arange(h))
    pixels = np.stack([cols.ravel(), rows.ravel()], axis=1)
    o, d = _pixel_rays(scene, cam_obj, pixels)
    centre, radius = np.array(box.MIRROR_CENTRE), box.SPHERE_RADIUS
    t = _hit_sphere(o, d, centre, radius)
    hit = np.isfinite(t)
    p = o + np.where(hit, t, 0.0)[:, None] * d
    n = (p - centre) / radius
    r = d - 2 * np.einsum("ij,ij->i", d, n)[:, None] * n
    # Reflected ray to the red wall (x = -1), well inside it, seen head-on enough.
    toward = hit & (r[:, 0] < -0.3)
    s = np.where(toward, (-1.0 - p[:, 0]) / np.where(toward, r[:, 0], -1.0), 0.0)
    wall = p + s[:, None] * r
    ok = toward & (np.abs(wall[:, 1]) < 0.7) & (wall[:, 2] > 0.3) & (wall[:, 2] < 1.7) \
        & (-np.einsum("ij,ij->i", d, n) > 0.6)
    assert ok.any(), "no mirror pixel reflects the red wall: the scene changed"
    # Where the camera sees each such wall point directly (and nothing is in front of it).
    candidates = []
    for i in np.flatnonzero(ok):
        proj = world_to_camera_view(scene, cam_obj, Vector(wall[i]))
        c2, r2 = int(proj.x * w), int((1.0 - proj.y) * h)
        if 1 <= c2 < w - 1 and 1 <= r2 < h - 1:
            _, d2 = _pixel_rays(scene, cam_obj, np.array([[c2, r2]]))
            if not np.isfinite(_hit_sphere(o, d2, centre, radius)[0]):
                candidates.append((i, c2, r2))
    assert candidates, "no reflected wall point is directly visible: the scene changed"
    # The most head-on reflection varies least across the pixel's footprint.
    i, c2, r2 = max(candidates, key=lambda c: -np.einsum("j,j->", d[c[0]], n[c[0]]))
    col, row = pixels[i]

    image, _, _ = ref.photon_map_pair("demo", SAMPLES["demo"])
    cycles = ref.load_reference("demo")["image"]
    mirror_px = image[row, col].astype(np.float64)
    wall_px = image[r2 - 1:r2 + 2, c2 - 1:c2 + 2].reshape(-1, 3).mean(axis=0)
    print(f"\nmirror pixel (col {col}, row {row}) = {mirror_px}, Cycles {cycles[row, col]}, "
          f"wall at (col {c2}, row {r2}) = {wall_px}")
    assert mirror_px[0] > 4 * mirror_px[1] and mirror_px[0] > 4 * mirror_px[2], "not red"
    np.testing.assert_allclose(mirror_px[0], box.MIRROR[0] * wall_px[0], rtol=0.1)
    np.testing.assert_allclose(mirror_px[0], cycles[row, col, 0], rtol=0.1)


@pytest.mark.parametrize("angle_deg", [8.0, 60.0])
def test_sun_disc_seen_by_the_camera(angle_deg):
    """A sun visible to camera rays shows as a disc of radiance S / (pi sin^2(angle / 2))
    (measured in Cycles 5.0: 130.83 at 8 degrees, 2.5465 at 60, 0.8488 at 120, for S = 2),
    so that its irradiance on a surface facing it stays S."""
    import math

    from tests.blender import scenes

    def build():
        scene = scenes.reset()
        scenes.set_resolution(8, 8)
        sun = scenes.add_light('SUN', power=2.0, angle=math.radians(angle_deg), name="Sun")
        sun.visible_camera = True
        scenes.add_camera(location=(0.0, 0.0, 0.0), look_at=(0.0, 0.0, 1.0), lens=200.0)
        return scene

    expected = 2.0 / (math.pi * math.sin(math.radians(angle_deg) / 2) ** 2)
    cycles = ref.render_cycles(build(), 16)
    photon_map = ref.render_photon_map(build(), 4)["Combined"][..., :3]
    print(f"\nsun disc {angle_deg} deg: Cycles {cycles[4, 4, 0]:.4f}, Photon Map "
          f"{photon_map[4, 4, 0]:.4f}, S / (pi sin^2 h) = {expected:.4f}")
    assert cycles[4, 4, 0] == pytest.approx(expected, rel=1e-3)  # the convention holds
    np.testing.assert_allclose(photon_map[3:5, 3:5], expected, rtol=1e-3)

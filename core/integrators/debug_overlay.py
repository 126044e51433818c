"""The photon debug pass: every stored photon the camera sees, drawn as a dot.

A photon is drawn when the render camera would see the surface point it sits on:

- it lies in front of the camera, between the clipping planes (depth along the view axis,
  as ``camera.py`` clips) and inside the image;
- nothing is in the way: one occlusion ray per photon, from the camera (its near plane, as
  camera rays start there) towards the photon, stopping ``16 * eps(p)`` short of it
  (``eps`` is ``geometry.py``'s scale-relative offset). A photon ON a visible surface is
  therefore drawn, whatever the surface's slope, and one behind an occluder is not.

Why a ray per photon and not the pixel's first-hit depth: the depth at a pixel's centre
differs from the depth of a photon elsewhere in that pixel by up to (pixel footprint x
slope), so on a slanted surface a depth comparison drops the photons lying beyond the
centre unless its tolerance grows with the slope, and then it lets occluded photons
through near edges. The ray goes through the photon itself, so there is no such error.

Glass and mirrors are occluders like any surface: a photon on a floor seen through a glass
sphere is hidden, because what the camera sees first at that pixel is the glass (the
caustic under the sphere shows from where the floor is seen directly). Photons seen in a
mirror are not drawn either. A photon map stores no surface normal, so a photon on the far
side of a single-sided plane (a wall modelled as one plane, lit from behind) is drawn.

Colour: a dot has the photon's flux divided by the 99th percentile of the photons'
brightest channel (``display_scale``), so colour shows power relative to the map's
typical photon, independent of the light's wattage; 99 % of dots are within [0, 1], the
rest brighter. Where several dots cover a pixel it holds their mean colour (power, not
density: density shows as coverage). Alpha is 1 where a dot is and 0 elsewhere.
"""

from __future__ import annotations

import numpy as np

from ..scene.camera import camera_frame, project
from ..scene.geometry import point_eps
from ..scene.contract import CAMERA_ORTHOGRAPHIC, Camera

# Names of the photon selection (the panel's "Overlay Map" enum uses the same identifiers).
OVERLAY_MAPS = ("global", "caustic", "both")
# Occlusion rays stop this many offset epsilons short of the photon. Measured on a tilted
# plane far from the origin (tests/core/integrators/test_debug_overlay.py), Embree's hit distance on
# the photon's own surface errs by up to ~eps/40 / cos(incidence): 1 eps hides photons
# seen within ~1.5 degrees of grazing, 4 eps none down to 0.75 degrees. 16 leaves a
# margin, and an occluder must still be closer than 2^-16 of the scene size to be missed.
VISIBILITY_TOLERANCE = 16.0
# The percentile of photon brightness that maps to colour 1.
DISPLAY_PERCENTILE = 99.0
MAX_DOT_RADIUS_PX = 32.0


def select_photons(global_map, caustic_map, which: str) -> tuple[np.ndarray, np.ndarray]:
    """(positions (N, 3) float32 metres, flux (N, 3) float32 watts) of the chosen map(s).

    global_map, caustic_map: objects with ``.positions`` and ``.flux`` (``PhotonMap``) or
    None (a map that was not traced counts as empty). which: one of ``OVERLAY_MAPS``.
    """
    if which not in OVERLAY_MAPS:
        raise ValueError(f"overlay_map must be one of {OVERLAY_MAPS}, got {which!r}")
    chosen = {"global": (global_map,), "caustic": (caustic_map,),
              "both": (global_map, caustic_map)}[which]
    maps = [m for m in chosen if m is not None and len(m.positions)]
    if not maps:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)
    positions = np.concatenate([np.asarray(m.positions, np.float32) for m in maps])
    flux = np.concatenate([np.asarray(m.flux, np.float32) for m in maps])
    return positions, flux


def display_scale(flux: np.ndarray) -> float:
    """Watts that map to colour 1: the 99th percentile of each photon's brightest channel.

    1.0 when there are no photons or they all carry zero flux (every dot is then black).
    """
    flux = np.asarray(flux)
    if flux.shape[0] == 0:
        return 1.0
    scale = float(np.percentile(flux.max(axis=1), DISPLAY_PERCENTILE))
    return scale if scale > 0.0 else 1.0


def display_colors(flux: np.ndarray, scale: float | None = None) -> np.ndarray:
    """(N, 3) float32: flux / ``scale`` (``display_scale(flux)`` when None), not clamped."""
    flux = np.asarray(flux, np.float32)
    scale = display_scale(flux) if scale is None else _positive("scale", scale)
    return (flux / np.float32(scale)).astype(np.float32)


def visible_photons(camera: Camera, accel, positions: np.ndarray, extent: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Which photons the camera sees, and where.

    camera: the render camera; accel: ``accel.Accelerator`` (or the brute-force twin) over
    the scene's triangles; positions: (N, 3) float32, metres; extent: the scene's largest
    bounding-box side in metres (``geometry.scene_extent(*scene.bounds())``); None uses the
    box of the photons and the camera.

    Returns (visible (N,) bool, pixel (N, 2) float64 continuous (column, row), row 0 at
    the top).
    """
    positions = _check_rows("positions", positions)
    n = positions.shape[0]
    if n == 0:
        return np.zeros(0, bool), np.zeros((0, 2))
    cam_pos, right, up, back = camera_frame(camera)
    if extent is None:
        pts = np.vstack([positions.astype(np.float64), cam_pos[None]])
        extent = float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    p = positions.astype(np.float64)
    rel = p - cam_pos
    depth = -(rel @ back)
    near, far = float(camera.clip_start), float(camera.clip_end)
    with np.errstate(divide="ignore", invalid="ignore"):
        pixel = project(camera, p)
    ok = (depth >= near) & (depth <= far)
    ok &= np.all(np.isfinite(pixel), axis=1)
    ok &= (pixel[:, 0] >= 0) & (pixel[:, 0] < camera.width)
    ok &= (pixel[:, 1] >= 0) & (pixel[:, 1] < camera.height)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return ok, pixel

    # Occlusion rays from the near plane (where camera rays start) towards each photon.
    q, r, z = p[idx], rel[idx], depth[idx]
    if camera.kind == CAMERA_ORTHOGRAPHIC:
        direction = np.broadcast_to(-back, q.shape)
        origin = q + (z - near)[:, None] * back
        dist = z - near
    else:
        length = np.linalg.norm(r, axis=1)
        direction = r / length[:, None]
        start = near * length / z  # near / cos(angle from the view axis)
        origin = cam_pos + start[:, None] * direction
        dist = length - start
    tol = VISIBILITY_TOLERANCE * point_eps(q, extent)
    reach = dist - tol
    # A photon within tol of the near plane has nothing in front of it that camera rays see.
    blocked = np.zeros(idx.size, bool)
    test = reach > 0.0
    if np.any(test):
        blocked[test] = accel.occluded(origin[test], direction[test], reach[test])
    ok[idx[blocked]] = False
    return ok, pixel


def photon_overlay(camera: Camera, accel, positions: np.ndarray, flux: np.ndarray, *,
                   dot_radius_px: float = 1.0, scale: float | None = None,
                   extent: float | None = None) -> np.ndarray:
    """The photon debug image: (H, W, 4) float32, RGBA, row 0 at the top.

    camera, accel, extent: as ``visible_photons``. positions: (N, 3) float32, metres;
    flux: (N, 3) float32, watts per photon. dot_radius_px: a dot covers the pixels whose
    integer offset (dx, dy) from the photon's pixel has dx^2 + dy^2 <= radius^2 (0: one
    pixel, 1: a plus of 5, 2: 13 pixels). scale: watts shown as colour 1; None:
    ``display_scale(flux)`` over all the photons given (visible or not), so the colours do
    not change when the camera moves.

    RGB is the mean ``flux / scale`` of the dots covering a pixel, alpha 1 there; pixels
    without a dot are (0, 0, 0, 0).
    """
    positions = _check_rows("positions", positions)
    flux = _check_rows("flux", flux)
    if flux.shape[0] != positions.shape[0]:
        raise ValueError(f"flux must have one row per photon ({positions.shape[0]}), "
                         f"got {flux.shape[0]}")
    if np.any(flux < 0):
        raise ValueError("flux must be >= 0 (watts)")
    radius = float(dot_radius_px)
    if not (0.0 <= radius <= MAX_DOT_RADIUS_PX):
        raise ValueError(f"dot_radius_px must be in [0, {MAX_DOT_RADIUS_PX:g}], got {dot_radius_px}")
    w, h = int(camera.width), int(camera.height)
    image = np.zeros((h, w, 4), np.float32)
    if positions.shape[0] == 0:
        return image
    colors = display_colors(flux, scale)

    visible, pixel = visible_photons(camera, accel, positions, extent)
    idx = np.flatnonzero(visible)
    if idx.size == 0:
        return image
    col = np.floor(pixel[idx, 0]).astype(np.int64)
    row = np.floor(pixel[idx, 1]).astype(np.int64)
    rgb = colors[idx].astype(np.float64)

    # Splat: every (photon, offset) pair is one entry; bincount sums them per pixel.
    k = int(np.floor(radius))
    dy, dx = np.mgrid[-k:k + 1, -k:k + 1]
    inside = dx * dx + dy * dy <= radius * radius
    dx, dy = dx[inside], dy[inside]
    cc = (col[:, None] + dx[None]).ravel()
    rr = (row[:, None] + dy[None]).ravel()
    keep = (cc >= 0) & (cc < w) & (rr >= 0) & (rr < h)
    target = (rr * w + cc)[keep]
    count = np.bincount(target, minlength=w * h)
    covered = count > 0
    for c in range(3):
        values = np.repeat(rgb[:, c], dx.size)[keep]
        total = np.bincount(target, weights=values, minlength=w * h)
        channel = image[..., c].reshape(-1)
        channel[covered] = total[covered] / count[covered]
    image[..., 3].reshape(-1)[covered] = 1.0
    return image


def composite_over(combined: np.ndarray, overlay: np.ndarray) -> np.ndarray:
    """The dots over the image: (H, W, 3) float32 = combined * (1 - alpha) + dot * alpha.

    combined: (H, W, 3) float32 radiance; overlay: (H, W, 4) float32 from ``photon_overlay``.
    """
    combined = np.asarray(combined, np.float32)
    overlay = np.asarray(overlay, np.float32)
    if combined.ndim != 3 or combined.shape[2] != 3:
        raise ValueError(f"combined must have shape (H, W, 3), got {combined.shape}")
    if overlay.shape != combined.shape[:2] + (4,):
        raise ValueError(f"overlay must have shape {combined.shape[:2] + (4,)}, got {overlay.shape}")
    alpha = overlay[..., 3:4]
    return (combined * (1.0 - alpha) + overlay[..., :3] * alpha).astype(np.float32)


def _check_rows(name: str, a) -> np.ndarray:
    a = np.asarray(a, np.float32)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
    if a.size and not np.all(np.isfinite(a)):
        raise ValueError(f"{name} holds non-finite values")
    return a


def _positive(name: str, value) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value}")
    return value

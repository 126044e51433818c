"""Blender's scene camera -> core.scene.contract.Camera, with Blender's own sensor-fit rule.

Blender (BKE_camera_params_compute_viewplane) and Cycles frame the picture the same way:
- the sensor size is ``sensor_height`` when Sensor Fit is VERTICAL, else ``sensor_width``
  (AUTO uses the width even when it ends up fitting vertically);
- AUTO fits horizontally when width x pixel_aspect_x >= height x pixel_aspect_y;
- the fitted film extent at distance 1 is sensor / lens (perspective) or ``ortho_scale``
  metres (orthographic); the other extent follows the image's aspect, pixel aspect included;
- lens shift is in units of that fitted extent.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..core.scene.contract import CAMERA_ORTHOGRAPHIC, CAMERA_PERSPECTIVE, Camera
from .export_errors import ExportError, NoCameraError


def render_size(render) -> tuple[int, int]:
    """Output resolution in pixels, percentage applied as Blender does (integer division)."""
    pct = int(render.resolution_percentage)
    return int(render.resolution_x) * pct // 100, int(render.resolution_y) * pct // 100


def render_region(render, width: int, height: int) -> tuple | None:
    """The Render Region (``render.use_border``) as core pixels (x0, y0, x1, y1), row 0 at
    the top, x1 and y1 exclusive; None without one. Blender's own rule (pipeline.cc,
    render_init_from_main: ``disprect.xmin = rd->border.xmin * winx``): each border
    fraction (a float32) times the resolution in float32 arithmetic, truncated to an
    integer. Its RenderResult is then x1 - x0 by y1 - y0 pixels, cropped or pasted into the
    frame at (x0, y0) by Blender (``use_crop_to_border``). In float32, 0.65 x 40 is exactly
    26 (in float64 it is 25.99999); 0.2 x 54 = 10.8 is pixel 10, not 11. Checked against
    where Blender pastes the region (tests/blender/test_render_region.py, and
    test_blender_exe_region.py through ``blender -b``)."""
    if not render.use_border:
        return None

    def pixel(fraction, size):
        return int(np.float32(fraction) * np.float32(size))  # C's float product, truncated

    x0, x1 = pixel(render.border_min_x, width), pixel(render.border_max_x, width)
    # Blender's rows count from the bottom.
    y0, y1 = pixel(render.border_min_y, height), pixel(render.border_max_y, height)
    x0, x1 = max(0, min(x0, width)), max(0, min(x1, width))
    y0, y1 = max(0, min(y0, height)), max(0, min(y1, height))
    if x1 <= x0 or y1 <= y0:
        return None  # an empty border: Blender renders the whole frame
    if (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return (x0, height - y1, x1, height - y0)


def film_extents(cam, width: int, height: int, pixel_aspect=(1.0, 1.0)):
    """(film_size (2,), film_shift (2,)) float64 for camera data ``cam`` at this resolution.

    Perspective: on the plane at distance 1 (tan of the half field of view is size / 2).
    Orthographic: metres.
    """
    ax, ay = float(pixel_aspect[0]), float(pixel_aspect[1])
    aspect = (width * ax) / (height * ay)
    fit = cam.sensor_fit
    sensor = cam.sensor_height if fit == 'VERTICAL' else cam.sensor_width
    if fit == 'AUTO':
        fit = 'HORIZONTAL' if width * ax >= height * ay else 'VERTICAL'
    if cam.type == 'ORTHO':
        fitted = float(cam.ortho_scale)
    else:
        fitted = float(sensor) / float(cam.lens)
    if fit == 'HORIZONTAL':
        size = np.array([fitted, fitted / aspect])
    else:
        size = np.array([fitted * aspect, fitted])
    shift = np.array([cam.shift_x, cam.shift_y], np.float64) * fitted
    return size, shift


def without_scale(matrix: np.ndarray, what: str) -> np.ndarray:
    """A (4, 4) float64 world matrix with unit-length axes; raises ExportError if degenerate."""
    m = np.array(matrix, np.float64)
    if not np.all(np.isfinite(m)):
        raise ExportError(f"{what} has a non-finite transform (NaN or infinity in its matrix)")
    norms = np.linalg.norm(m[:3, :3], axis=0)
    if np.any(norms <= 0):
        raise ExportError(f"{what} has a zero scale on one axis; it has no orientation")
    m[:3, :3] /= norms
    return m


def export_camera(depsgraph, warnings: list[str]) -> Camera:
    """The scene camera as seen by the renderer; NoCameraError when the scene has none."""
    scene = depsgraph.scene
    cam_obj = scene.camera
    if cam_obj is None:
        raise NoCameraError(f"scene '{scene.name}' has no active camera; add one and set it "
                            f"as the scene camera (Scene Properties > Camera)")
    cam_obj = cam_obj.evaluated_get(depsgraph)
    cam = cam_obj.data
    if cam_obj.type != 'CAMERA':
        raise NoCameraError(f"the scene camera '{cam_obj.name}' is a {cam_obj.type} object, "
                            f"not a camera")
    if cam.type == 'PANO':
        warnings.append(f"Camera '{cam_obj.name}': panoramic cameras are not supported; "
                        f"rendering it as a perspective camera")
    render = scene.render
    width, height = render_size(render)
    if width < 1 or height < 1:
        raise ExportError(f"render resolution {width}x{height} (after "
                          f"{render.resolution_percentage}%) is empty")
    check_camera_values(cam_obj, cam)
    size, shift = film_extents(cam, width, height, (render.pixel_aspect_x, render.pixel_aspect_y))
    return Camera(
        to_world=without_scale(cam_obj.matrix_world, f"camera '{cam_obj.name}'"),
        width=width,
        height=height,
        film_size=size,
        film_shift=shift,
        kind=CAMERA_ORTHOGRAPHIC if cam.type == 'ORTHO' else CAMERA_PERSPECTIVE,
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
        name=cam_obj.name,
        region=render_region(render, width, height),
        **depth_of_field(cam_obj, cam),
    )


def check_camera_values(cam_obj, cam) -> None:
    """Raise ExportError naming the camera setting, in the UI's words, whose value cannot
    make a camera (NaN from a driver or a script, zero, negative), before the core would
    name its own field (``camera.film_size``, ``camera.clip_start``)."""
    fit = cam.sensor_fit
    values = [("Clip Start", cam.clip_start, True), ("Clip End", cam.clip_end, True),
              ("Shift X", cam.shift_x, False), ("Shift Y", cam.shift_y, False)]
    if cam.type == 'ORTHO':
        values.insert(0, ("Orthographic Scale", cam.ortho_scale, True))
    else:
        sensor = ("Sensor Height", cam.sensor_height) if fit == 'VERTICAL' else \
            ("Sensor Width" if fit == 'HORIZONTAL' else "Sensor Size", cam.sensor_width)
        values[:0] = [("Focal Length", cam.lens, True), (*sensor, True)]
    for name, value, positive in values:
        value = float(value)
        if not np.isfinite(value) or (positive and value <= 0.0):
            need = "a finite number > 0" if positive else "a finite number"
            raise ExportError(f"camera '{cam_obj.name}': {name} must be {need}, got {value:g}")
    if not float(cam.clip_start) < float(cam.clip_end):
        raise ExportError(f"camera '{cam_obj.name}': Clip Start ({float(cam.clip_start):g}) "
                          f"must be less than Clip End ({float(cam.clip_end):g})")


_FSTOP_INFINITY = float(np.finfo(np.float32).max)
"""Blender's largest f-stop (typing inf stores it): a pinhole, exactly."""


def depth_of_field(cam_obj, cam) -> dict:
    """Camera fields for the Depth of Field panel, as Cycles reads it (blender/camera.cpp):
    aperture radius = focal length / (2 f-stop) for a perspective camera (the lens in mm
    x 1e-3), 1 / (2 f-stop) for an orthographic one, in scene units either way: Cycles
    applies no unit scale (Scene > Units > Unit Scale) to it, and the focus distance is
    stored in scene units too; blades < 3 = round, rotation in radians, ratio; the focus
    distance is the focus object's depth along the view axis, else ``focus_distance``.
    {} without DOF."""
    dof = getattr(cam, "dof", None)
    if dof is None or not dof.use_dof:
        return {}
    fstop = max(float(dof.aperture_fstop), 1e-5)
    if fstop >= _FSTOP_INFINITY:  # "inf" typed into the field: Blender stores FLT_MAX
        return {}
    focus = float(dof.focus_distance)
    if dof.focus_object is not None:
        m = np.array(cam_obj.matrix_world, np.float64)
        target = np.array(dof.focus_object.matrix_world, np.float64)[:3, 3]
        view = -m[:3, 2] / np.linalg.norm(m[:3, 2])
        focus = abs(float(np.dot(view, target - m[:3, 3])))
    blades = int(dof.aperture_blades)
    lens = 1.0 if cam.type == 'ORTHO' else float(cam.lens) * 1e-3
    return {"aperture_radius": lens / (2.0 * fstop),
            "focus_distance": max(focus, 1e-6),
            "aperture_blades": blades if blades >= 3 else 0,
            "aperture_rotation": float(dof.aperture_rotation),
            "aperture_ratio": max(float(dof.aperture_ratio), 1e-6)}


def render_origin(camera: Camera) -> np.ndarray:
    """(3,) float64 world position of the render frame's origin: the camera's position.

    The exporter moves everything (geometry, lights, camera) by -origin in float64 before
    anything is stored as float32, so float32 only has to hold the scene's extent around
    the camera, not its distance from Blender's world origin (architecture and GIS scenes
    at 1e4 to 1e6 m). A uniform world and every image are independent of the origin.
    """
    return np.array(np.asarray(camera.to_world, np.float64)[:3, 3])


def relative_matrix(matrix, origin) -> np.ndarray:
    """(4, 4) float64 copy of ``matrix`` translated by -``origin`` (3,) metres."""
    m = np.array(matrix, np.float64)
    m[:3, 3] -= np.asarray(origin, np.float64)
    return m


def relative_camera(camera: Camera, origin) -> Camera:
    """``camera`` in the render frame whose origin is at world ``origin`` (3,) metres."""
    return dataclasses.replace(camera, to_world=relative_matrix(camera.to_world, origin))


@dataclasses.dataclass(frozen=True)
class CameraView:
    """The render camera as the Texture Coordinate node's Camera and Window outputs see it
    (Cycles' kernel_data.cam.worldtocamera and worldtondc), for world points in metres.

    world_to_camera: (4, 4) float64, world -> Cycles' camera space (x right, y up, +z in
    front of the camera: Blender's camera axes with z negated; no scale).
    world_to_ndc: (4, 4) float64, projective: world -> (x, y in [0, 1] over the render
    frame, 0, w); divide by w (row 3). Blender's own projection
    (``Object.calc_matrix_camera``: sensor fit, shift, pixel aspect)."""
    world_to_camera: np.ndarray
    world_to_ndc: np.ndarray


def camera_view(depsgraph) -> "CameraView | None":
    """The scene camera's CameraView, or None without a camera object."""
    scene = depsgraph.scene
    cam_obj = scene.camera
    if cam_obj is None or cam_obj.type != 'CAMERA':
        return None
    cam_obj = cam_obj.evaluated_get(depsgraph)
    to_world = without_scale(cam_obj.matrix_world, f"camera '{cam_obj.name}'")
    to_camera = np.linalg.inv(to_world)
    flip = np.diag([1.0, 1.0, -1.0, 1.0])
    width, height = render_size(scene.render)
    proj = np.array(cam_obj.calc_matrix_camera(
        depsgraph, x=max(width, 1), y=max(height, 1),
        scale_x=scene.render.pixel_aspect_x, scale_y=scene.render.pixel_aspect_y), np.float64)
    to_ndc = np.array([[0.5, 0.0, 0.0, 0.5], [0.0, 0.5, 0.0, 0.5], [0.0, 0.0, 0.0, 0.0],
                       [0.0, 0.0, 0.0, 1.0]])
    return CameraView(flip @ to_camera, to_ndc @ proj @ to_camera)

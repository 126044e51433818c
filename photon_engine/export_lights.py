"""Blender lights -> rows for core.scene.contract.Lights.from_list, in Cycles' units.

What Cycles does with a light's settings, and so what we pass on (DESIGN.md, "Units"):
- power = energy x 2^exposure; colour = colour x blackbody(temperature) when enabled
  x the light's own node tree (Emission colour x strength) when it uses nodes;
- "Normalize" off means the power is per unit of emitting area: the equivalent normalised
  power is P x area (area lights: the scaled rectangle or ellipse; point/spot: pi r^2;
  sun: pi tan^2(angle / 2)); a point-like light (r = 0) is unaffected;
- the matrix loses its scale, but an area light's extents take the object's scale;
- ray visibility is the object's ``visible_camera`` (False by default for lights in
  Blender 5), ``visible_diffuse``, ``visible_glossy`` (seen in mirrors) and
  ``visible_transmission`` (seen through glass); shadows follow ``use_shadow``;
- point and spot lights pass "Soft Falloff" on (Cycles then treats the radius as a disk
  facing the shading point rather than a sphere).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.scene.contract import AREA_ELLIPSE, AREA_RECTANGLE, LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN
from .export_camera import without_scale
from .export_materials import read_light_nodes

_KINDS = {'POINT': LIGHT_POINT, 'SPOT': LIGHT_SPOT, 'SUN': LIGHT_SUN, 'AREA': LIGHT_AREA}


def light_row(obj, matrix, name: str, warnings: list[str]) -> dict | None:
    """One light instance -> a row dict; None (with a warning) when it cannot emit.

    obj: the evaluated light object; matrix: its (4, 4) world matrix (instance matrix).
    """
    light = obj.data
    kind = _KINDS.get(light.type)
    if kind is None:
        warnings.append(f"Light '{name}': type {light.type} is not supported; skipped")
        return None
    m = np.array(matrix, np.float64)
    to_world = without_scale(m, f"light '{name}'")
    scale = np.linalg.norm(m[:3, :3], axis=0)

    color = np.asarray(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.asarray(light.temperature_color[:3], np.float64)
    color = color * read_light_nodes(light, warnings)
    power = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    if power < 0 or np.any(color < 0):
        warnings.append(f"Light '{name}': negative power or colour is not supported; skipped")
        return None

    row = {"kind": kind, "to_world": to_world, "name": name,
           "visible_to_camera": bool(getattr(obj, "visible_camera", False)),
           "visible_to_diffuse": bool(getattr(obj, "visible_diffuse", True)),
           "visible_to_glossy": bool(getattr(obj, "visible_glossy", True)),
           "visible_to_transmission": bool(getattr(obj, "visible_transmission", True)),
           "cast_shadow": bool(getattr(light, "use_shadow", True))}
    emitting_area = 0.0  # for "Normalize" off
    if kind in (LIGHT_POINT, LIGHT_SPOT):
        radius = float(light.shadow_soft_size)
        row["radius"] = radius
        row["soft_falloff"] = bool(getattr(light, "use_soft_falloff", True))
        emitting_area = math.pi * radius * radius
        if kind == LIGHT_SPOT:
            row["spot_size"] = float(light.spot_size)
            row["spot_blend"] = float(light.spot_blend)
            if not np.allclose(scale, scale[0], rtol=1e-4):
                warnings.append(f"Light '{name}': a non-uniform scale that squashes the spot "
                                f"cone is not supported; using a round cone")
            if getattr(light, "use_square", False):
                warnings.append(f"Light '{name}': square spot cones are not supported; "
                                f"using a round cone")
    elif kind == LIGHT_SUN:
        row["angle"] = float(light.angle)
        emitting_area = math.pi * math.tan(0.5 * float(light.angle)) ** 2
    else:
        ellipse = light.shape in ('DISK', 'ELLIPSE')
        size_y = light.size_y if light.shape in ('RECTANGLE', 'ELLIPSE') else light.size
        extents = np.array([light.size * scale[0], size_y * scale[1]], np.float64)
        row["shape"] = AREA_ELLIPSE if ellipse else AREA_RECTANGLE
        row["size"] = extents
        emitting_area = float(extents[0] * extents[1]) * (math.pi / 4 if ellipse else 1.0)
        if emitting_area <= 0:
            warnings.append(f"Light '{name}': area light of zero size emits nothing; skipped")
            return None
        if float(getattr(light, "spread", math.pi)) < math.pi - 1e-6:
            warnings.append(f"Light '{name}': area light spread below 180 degrees is not "
                            f"supported; emitting into the full hemisphere")
    if not getattr(light, "normalize", True) and emitting_area > 0:
        power *= emitting_area
    row["color"] = color
    row["power"] = power
    return row

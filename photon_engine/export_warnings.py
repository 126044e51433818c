"""Scene-level features the renderer does not support yet, each said once by name.

The exporter renders what it can; what it drops or ignores is reported here, one warning
per object or setting, in the words of Blender's UI (docs/blender.md, "What is not
supported yet, and what you will see"):

- hair particle systems drawn as paths, and Curves (hair) objects (not rendered);
- motion blur (ignored: one instant is rendered);
- closed transmissive meshes whose normals point inward (rendered as they are, inside out:
  core/scene/orientation.py).
"""

from __future__ import annotations

import numpy as np

from ..core.color import LUMINANCE
from ..core.scene import orientation
from ..core.scene.contract import Scene


def dropped_objects(depsgraph) -> list[str]:
    """Warnings for hair the renderer drops: particle hair drawn as paths, Curves objects."""
    out = []
    for obj in depsgraph.objects:
        if obj.type == 'CURVES':
            out.append(f"Object '{obj.name}': Curves hair objects are not supported yet; "
                       f"not rendered")
            continue
        for psys in getattr(obj, "particle_systems", ()):
            settings = psys.settings
            if settings.type == 'HAIR' and settings.render_type == 'PATH':
                out.append(f"Object '{obj.name}': hair particle system '{psys.name}' is not "
                           f"supported yet; not rendered")
    return out


def motion_blur(scene) -> str | None:
    if scene.render.use_motion_blur:
        return ("Motion Blur (Render Properties > Motion Blur) is not supported yet; "
                "ignored (the frame is rendered at one instant)")
    return None


def inside_out_glass(scene: Scene) -> list[str]:
    """Warnings for the closed objects with a transmissive material (transmission
    luminance > 0) whose normals point inward."""
    mats = scene.materials
    if scene.mesh.triangle_count == 0 or mats.count == 0:
        return []
    transmissive = np.asarray(mats.transmission, np.float64) @ LUMINANCE > 0.0
    which = transmissive[scene.mesh.material_index]
    names = scene.mesh.object_names
    return [f"Object '{names[i] if i < len(names) else i}': closed glass with its normals "
            f"pointing inward (negative volume), so it refracts inside out; use Mesh > "
            f"Normals > Recalculate Outside"
            for i in orientation.inside_out(scene.mesh, which)]


def scene_warnings(depsgraph, scene: Scene) -> list[str]:
    """Every scene-level warning of ``depsgraph`` exported as ``scene``."""
    out = [w for w in (motion_blur(depsgraph.scene),) if w is not None]
    out += dropped_objects(depsgraph)
    out += inside_out_glass(scene)
    return out

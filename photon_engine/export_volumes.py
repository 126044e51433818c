"""Volume shaders -> participating media (core/scene/media.py), as Cycles defines them.

The coefficients, per RGB channel in 1/m (Blender's density is per metre), from Cycles'
svm_closure.h (and EEVEE's node_volume_* shaders, which follow it):
- Volume Absorption (Color C, Density rho): sigma_a = max(1 - C, 0) rho;
- Volume Scatter (Color C, Density rho, Anisotropy g): sigma_s = C rho, Henyey-Greenstein g;
- Principled Volume (Color C, Density rho, Anisotropy g, Absorption Color A, Emission
  Strength S, Emission Color E): sigma_s = C rho,
  sigma_a = max(1 - C, 0) max(1 - sqrt(A), 0) rho, emission S E (W/(m^3 sr), not scaled by
  the density), plus the blackbody emission (``blackbody_emission``: Blackbody Intensity B,
  Temperature T, Blackbody Tint K: K x sigma_SB 1e-6 / pi x mix(1, T^4, B) x the Blackbody
  node's colour of T, Cycles' svm_node_principled_volume; constant inputs only);
- Emission on a Volume output: emission Strength x Color;
- Add Shader sums the media, Mix Shader weighs them by (1 - Fac, Fac); the anisotropy of a
  sum is the sigma_s-weighted mean of its lobes' g (Cycles keeps the lobes apart: exact
  for equal g).
Heterogeneous density: a mesh material whose Volume output is one Principled Volume,
Volume Scatter or Volume Absorption with its Density linked gets a density program
(``export_shader.compile_sockets`` with target TARGET_DENSITY: Noise, Gradient, ColorRamp,
Math ... through Texture Coordinate Object / Generated or the Geometry Position), its
coefficients at density 1 (core/scene/media.py); Cycles clamps the density at 0 as the
renderer does. Since the sixth slice the varying node may sit under Add / Mix Shaders:
its coefficients (times the Mix factors above it) make the heterogeneous row and the rest
of the sum a homogeneous row ``homogeneous_part`` in the same object (export.py). A
varying colour (issue 16): a Principled Volume's linked Color / Absorption Color or a Volume
Scatter's or Volume Absorption's linked Color makes that node the varying one too; its
program has seven outputs (density, Color, Absorption Color; a Volume Absorption's
Absorption Color 0) and its row holds weights (core/scene/media.py). The World's Volume
varies the same way (one medium: its varying node beside other volume shaders is reported
and its own values used; core/media/regions.py confines its varying part to a box around
the scene). Any other linked input (a second varying node in the same material or World)
is reported by node and input and its own value used. The World's Volume fills all space
(``world_medium``); a
mesh material's Volume fills the inside of every object using it (``material_medium``;
export.py makes one medium per object and material, bounded by that object's faces of the
material, and leaves a volume-only material's faces out of the surfaces: they are null
interfaces, as in Cycles).
"""

from __future__ import annotations

import numpy as np

from ..core.scene.media import WORLD
from ..core.shading import program as pg
from ..core.shading.color import blackbody_rec709
from . import compat
from .export_nodes import follow_reroutes
from .export_shader import REC709_TO_SCENE_LINEAR, compile_sockets, constant


CLOSURE_WEIGHT_CUTOFF = 1e-5
"""Cycles' CLOSURE_WEIGHT_CUTOFF: a Blackbody Intensity or intensity below it adds nothing."""

STEFAN_BOLTZMANN = 5.670373e-8
"""W/(m^2 K^4), the value Cycles' svm_node_principled_volume uses."""


def blackbody_emission(intensity: float, temperature: float, tint) -> np.ndarray:
    """A Principled Volume's blackbody emission (3,) float64 W/(m^3 sr), Cycles' definition
    (svm_node_principled_volume): Blackbody Intensity ``intensity`` (its 1 is "physically
    accurate"), ``temperature`` kelvin (clamped at 0), Blackbody Tint ``tint`` (3,):
    tint x sigma_SB 1e-6 / pi x mix(1, T^4, intensity) x the Blackbody node's colour of T
    (``core.shading.color.blackbody_rec709``, taken to scene linear by the Blackbody
    node's matrix). Not clamped, as in Cycles: below about 1300 K the colour's blue (below
    800 K its green too) is negative and subtracts from the node's Emission Strength x
    Emission Color; the caller clamps the node's sum at 0 (a medium's emission cannot be
    negative)."""
    if not intensity > CLOSURE_WEIGHT_CUTOFF:
        return np.zeros(3)
    t = max(float(temperature), 0.0)
    scale = STEFAN_BOLTZMANN * 1e-6 / np.pi * ((1.0 - intensity) + intensity * t ** 4)
    if not scale > CLOSURE_WEIGHT_CUTOFF:
        return np.zeros(3)
    rgb = np.asarray(REC709_TO_SCENE_LINEAR, np.float64) @ np.asarray(blackbody_rec709(t))
    return np.asarray(tint, np.float64)[:3] * scale * rgb


class _Medium:
    """Coefficients being summed: sigma_a, sigma_s, emission (3,) float64, g_weight: the
    sum of sigma_s-luminance x g (the mean anisotropy's numerator)."""

    def __init__(self):
        self.sigma_a = np.zeros(3)
        self.sigma_s = np.zeros(3)
        self.emission = np.zeros(3)
        self.g_weight = 0.0

    def add(self, other: "_Medium", w: float) -> None:
        self.sigma_a += w * other.sigma_a
        self.sigma_s += w * other.sigma_s
        self.emission += w * other.emission
        self.g_weight += w * other.g_weight

    @property
    def anisotropy(self) -> float:
        s = float(np.mean(self.sigma_s))
        return float(np.clip(self.g_weight / s, -1.0, 1.0)) if s > 0 else 0.0


def _value(node, name, owner, warnings, size=None):
    """An input's own value (colour inputs: RGB (3,) float64), reporting a link."""
    sock = node.inputs.get(name)
    if sock is None:
        return np.zeros(3) if size == 3 else 0.0
    if sock.is_linked and follow_reroutes(sock) is not None:
        warnings.append(f"{owner}: input '{name}' of node '{node.name}' is linked (textured "
                        f"or heterogeneous media are not supported yet); using its own value")
    v = sock.default_value
    if size == 3:
        return np.asarray(v[:3], np.float64)
    return float(v)


def _linked(node, name) -> bool:
    sock = node.inputs.get(name)
    return sock is not None and sock.is_linked and follow_reroutes(sock) is not None


def _density(node, owner, warnings, linked, colours=()) -> tuple[float, bool, bool]:
    """The node's Density, whether the node varies and whether its colour does:
    (1, True, colour) when its Density or one of its ``colours`` inputs (Color, Absorption
    Color) is linked and ``linked`` (a list, None: never) is still empty: {input name:
    socket} of the Density and the colours is appended (the medium is heterogeneous);
    else (its own value, False, False), a link reported (a second varying node in the same
    material among them; the colours' links by ``_value``)."""
    sock = node.inputs.get("Density")
    varying = [n for n in ("Density",) + tuple(colours) if _linked(node, n)]
    if linked is not None and varying:
        if not linked:
            linked.append({n: node.inputs[n] for n in ("Density",) + tuple(colours)
                           if node.inputs.get(n) is not None})
            return 1.0, True, any(n != "Density" for n in varying)
        if "Density" in varying:
            warnings.append(f"{owner}: input 'Density' of node '{node.name}' is linked, and "
                            f"another volume node already varies (one varying volume node "
                            f"per material is supported); using its own value")
            return max(float(sock.default_value), 0.0), False, False
    return max(_value(node, "Density", owner, warnings), 0.0), False, False


def _read(sock, owner, warnings, depth=0, linked=None, weight=1.0) -> _Medium:
    """The medium of a Volume socket. ``linked``: a list (None: no varying density) that
    takes the first volume node whose Density (or, Principled Volume / Volume Scatter, Color
    / Absorption Color) is linked, anywhere under Add / Mix Shaders: [{input name: socket}
    of its Density and colours, its medium at density 1 (weights for a varying colour)
    times ``weight``, the product of the Mix factors above it]; that node then adds nothing
    to the returned (homogeneous) medium."""
    m = _Medium()
    out = follow_reroutes(sock) if sock is not None else None
    if out is None or depth > 32:
        return m
    node = out.node
    kind = node.bl_idname
    varies = False
    if kind == "ShaderNodeAddShader":
        for k in (0, 1):
            m.add(_read(node.inputs[k], owner, warnings, depth + 1, linked, weight), 1.0)
    elif kind == "ShaderNodeMixShader":
        fac = float(np.clip(_value(node, "Fac", owner, warnings), 0.0, 1.0))
        m.add(_read(node.inputs[1], owner, warnings, depth + 1, linked, weight * (1.0 - fac)),
              1.0 - fac)
        m.add(_read(node.inputs[2], owner, warnings, depth + 1, linked, weight * fac), fac)
    elif kind == "ShaderNodeVolumeAbsorption":
        rho, varies, colour = _density(node, owner, warnings, linked, ("Color",))
        # A varying colour: the row's sigma_a is the weight max(1 - C, 0) of the program's
        # Color multiplies (its Absorption Color slots hold 0)
        c = np.zeros(3) if colour else _value(node, "Color", owner, warnings, 3)
        m.sigma_a = np.maximum(1.0 - c, 0.0) * rho
    elif kind == "ShaderNodeVolumeScatter":
        rho, varies, colour = _density(node, owner, warnings, linked, ("Color",))
        # A varying colour: the row's sigma_s is the weight the program's Color multiplies
        c = np.ones(3) if colour else np.maximum(_value(node, "Color", owner, warnings, 3), 0.0)
        m.sigma_s = c * rho
        m.g_weight = float(np.mean(m.sigma_s)) * _value(node, "Anisotropy", owner, warnings)
        phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
        if phase != "HENYEY_GREENSTEIN":
            warnings.append(f"{owner}: phase function '{phase}' of node '{node.name}' is not "
                            f"supported yet; using Henyey-Greenstein")
    elif kind == "ShaderNodeVolumePrincipled":
        rho, varies, colour = _density(node, owner, warnings, linked,
                                       ("Color", "Absorption Color"))
        if colour:  # weights, which the program's Color and Absorption Color multiply
            m.sigma_s, m.sigma_a = np.ones(3), np.ones(3)
        else:
            c = np.maximum(_value(node, "Color", owner, warnings, 3), 0.0)
            a = np.sqrt(np.maximum(_value(node, "Absorption Color", owner, warnings, 3), 0.0))
            m.sigma_s = c * rho
            m.sigma_a = np.maximum(1.0 - c, 0.0) * np.maximum(1.0 - a, 0.0) * rho
        m.g_weight = float(np.mean(m.sigma_s)) * _value(node, "Anisotropy", owner, warnings)
        strength = max(_value(node, "Emission Strength", owner, warnings), 0.0)
        m.emission = strength * np.maximum(_value(node, "Emission Color", owner, warnings, 3), 0.0)
        bb = _value(node, "Blackbody Intensity", owner, warnings)
        if bb > CLOSURE_WEIGHT_CUTOFF:
            m.emission = np.maximum(m.emission + blackbody_emission(
                bb, _value(node, "Temperature", owner, warnings),
                _value(node, "Blackbody Tint", owner, warnings, 3)), 0.0)
    elif kind == "ShaderNodeEmission":
        strength = max(_value(node, "Strength", owner, warnings), 0.0)
        m.emission = strength * np.maximum(_value(node, "Color", owner, warnings, 3), 0.0)
    else:
        warnings.append(f"{owner}: node '{node.name}' ({kind}) on the Volume output is not "
                        f"supported; ignored")
    if varies:
        # The varying node's own row (its weight applied here: the callers scale only
        # what this returns)
        het = _Medium()
        het.add(m, weight)
        linked.append(het)
        return _Medium()
    return m


def _volume_socket(tree, idname):
    """The active output node's linked Volume input, or None."""
    if tree is None:
        return None
    output = tree.get_output_node('CYCLES') if hasattr(tree, "get_output_node") else None
    if output is None:
        output = next((n for n in tree.nodes if n.bl_idname == idname
                       and getattr(n, "is_active_output", True)), None)
    if output is None:
        return None
    sock = output.inputs.get("Volume")
    return sock if sock is not None and sock.is_linked and follow_reroutes(sock) is not None \
        else None


def world_medium(world, warnings: list[str]) -> dict | None:
    """The World's Volume as a ``Media.from_list`` row (bounds WORLD), or None when its
    active World Output has no Volume linked."""
    if world is None:
        return None
    sock = _volume_socket(compat.node_tree(world), "ShaderNodeOutputWorld")
    if sock is None:
        return None
    owner = f"World '{world.name}'"
    read: list[str] = []
    row = _varying_row(world, sock, owner, read)
    if "homogeneous_part" in row:
        # One World medium only (core/scene/media.py): the varying node's own values
        warnings.append(f"{owner}: a volume node of varying density or colour beside "
                        f"other volume shaders (Add / Mix) is not supported on the World; "
                        f"using the inputs' own values")
        m = _read(sock, owner, warnings)
        row = _row(m, world.name)
    else:
        warnings.extend(read)
    return {**row, "bounds": WORLD}


def material_medium(mat, warnings: list[str]) -> dict | None:
    """A material's Volume as a ``Media.from_list`` row without its bounds (the exporter
    adds the object and its boundary), or None when its active Material Output has no
    Volume linked."""
    sock = _volume_socket(compat.node_tree(mat), "ShaderNodeOutputMaterial")
    if sock is None:
        return None
    return _varying_row(mat, sock, f'Material "{mat.name}"', warnings)


def _varying_row(owner_id, sock, owner, warnings) -> dict:
    """The medium of the Volume socket ``sock`` of a material or World ``owner_id`` as a
    row (``_row``) with, where a volume node varies, its ``density_program`` (its row then
    holds the varying node's coefficients at density 1, and the rest of an Add / Mix is its
    ``homogeneous_part``); ``owner`` names it in ``warnings``."""
    linked = []
    m = _read(sock, owner, warnings, linked=linked)
    if not linked:
        return _row(m, owner_id.name)
    sockets, het = linked
    colour = [sockets[n] for n in ("Color", "Absorption Color")
              if n in sockets and _linked(sockets[n].node, n)]
    targets = [(sockets["Density"], pg.TARGET_DENSITY, 0, 0)]
    if colour:
        # Color and Absorption Color, slots 1-3 and 4-6 (a Volume Scatter has no
        # Absorption Color: its Color fills them, read by nothing since its sigma_a is 0; a
        # Volume Absorption's are 0: sigma_a = max(1 - C, 0) rho, Cycles' definition)
        if sockets["Color"].node.bl_idname == "ShaderNodeVolumeAbsorption":
            absorption = constant((0.0, 0.0, 0.0))
        else:
            absorption = sockets.get("Absorption Color", sockets["Color"])
        targets += [(sockets["Color"], pg.TARGET_DENSITY, 0, 1),
                    (absorption, pg.TARGET_DENSITY, 0, 4)]
    comp = compile_sockets(owner_id, targets)
    warnings.extend(comp.warnings)
    if comp.program is None:  # the graph folds to a constant density (and colour)
        rho = max(float(comp.constant[0][0]), 0.0)
        if colour:
            c = np.maximum(np.asarray(comp.constant[1], np.float64), 0.0)
            a = np.sqrt(np.maximum(np.asarray(comp.constant[2], np.float64), 0.0))
            het.g_weight *= float(np.mean(c))
            het.sigma_s = het.sigma_s * c
            het.sigma_a = het.sigma_a * np.maximum(1.0 - c, 0.0) * np.maximum(1.0 - a, 0.0)
        het.sigma_a, het.sigma_s, het.g_weight = het.sigma_a * rho, het.sigma_s * rho, \
            het.g_weight * rho  # the emission does not scale with the density
        m.add(het, 1.0)
        return _row(m, owner_id.name)
    row = _row(het, owner_id.name)
    row["density_program"] = comp.program
    if np.any(m.sigma_a > 0) or np.any(m.sigma_s > 0) or np.any(m.emission > 0):
        # The rest of an Add / Mix: a homogeneous medium in the same object (export.py
        # makes it a row of its own; overlapping media add, as in Cycles' volume stack)
        row["homogeneous_part"] = _row(m, owner_id.name)
    return row


def _row(m: _Medium, name: str) -> dict:
    return {"sigma_a": m.sigma_a, "sigma_s": m.sigma_s, "anisotropy": m.anisotropy,
            "emission": m.emission, "name": name}


def scene_has_medium(scene) -> bool:
    """The scene's World or a material of a visible mesh object has a Volume linked (the
    render then has the volume passes)."""
    world = getattr(scene, "world", None)
    if world is not None and _volume_socket(compat.node_tree(world),
                                            "ShaderNodeOutputWorld") is not None:
        return True
    seen = set()
    for obj in scene.objects:
        if obj.type != 'MESH' or obj.hide_render:
            continue
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or mat.name in seen:
                continue
            seen.add(mat.name)
            if _volume_socket(compat.node_tree(mat), "ShaderNodeOutputMaterial") is not None:
                return True
    return False

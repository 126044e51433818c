"""Blender shader node trees -> the core's material lobes (see core/scene.py, Materials).

A surface is read by following the active output's Surface input through the shader
nodes the core can express. Each node becomes a ``Closure``: the four lobe colours
(diffuse, specular, transmission, emission) plus the roughness and IOR they share.
Mix Shader interpolates closures, Add Shader sums them. Inputs driven by links that
cannot be evaluated here (textures, maths) fall back to the socket's own value with a
warning. A tree that cannot be read at all (unknown shader node, no output) renders as
grey diffuse with one warning naming the material, never an exception.

Mapping (Cycles' node semantics, ``docs/export.md`` has the table):
- Principled BSDF: diffuse = base (1 - metallic)(1 - transmission),
  specular = base metallic, transmission = base (1 - metallic) transmission,
  emission = emission colour x strength. Its dielectric specular layer
  (Specular IOR Level), coat, sheen and subsurface are not modelled yet.
- Diffuse BSDF -> diffuse; Glossy BSDF -> specular; Glass BSDF -> transmission;
  Emission -> emission (radiance W/(m^2 sr) = colour x strength).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEFAULT_GREY = 0.8
"""Albedo of the material used for empty slots and unreadable trees (Cycles' default surface)."""


class UnreadableTree(Exception):
    """Raised inside the evaluator when a node tree cannot be expressed as lobes."""


@dataclass
class Closure:
    """One shader's contribution, in the core's lobes. Colours are (3,) float64 linear RGB.

    roughness and ior are shared by the specular and transmission lobes; ``glossy_weight``
    is how much of the closure uses them (the luminance of specular + transmission), so a
    mix can average them sensibly.
    """

    diffuse: np.ndarray = field(default_factory=lambda: np.zeros(3))
    specular: np.ndarray = field(default_factory=lambda: np.zeros(3))
    transmission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    roughness: float = 0.0
    ior: float = 1.5
    glossy_weight: float = 0.0

    def scaled(self, w: float) -> "Closure":
        return Closure(self.diffuse * w, self.specular * w, self.transmission * w,
                       self.emission * w, self.roughness, self.ior, self.glossy_weight * w)

    def plus(self, other: "Closure") -> "Closure":
        wa, wb = self.glossy_weight, other.glossy_weight
        if wa + wb > 0:
            roughness = (wa * self.roughness + wb * other.roughness) / (wa + wb)
            ior = (wa * self.ior + wb * other.ior) / (wa + wb)
        else:
            roughness, ior = max(self.roughness, other.roughness), self.ior
        return Closure(self.diffuse + other.diffuse, self.specular + other.specular,
                       self.transmission + other.transmission, self.emission + other.emission,
                       roughness, ior, wa + wb)

    def as_row(self, name: str) -> dict:
        return {"name": name, "diffuse": self.diffuse, "specular": self.specular,
                "transmission": self.transmission, "emission": self.emission,
                "roughness": float(np.clip(self.roughness, 0.0, 1.0)), "ior": float(self.ior)}


def default_row(name="(default grey)") -> dict:
    return Closure(diffuse=np.full(3, DEFAULT_GREY)).as_row(name)


def _glossy(spec=None, trans=None, roughness=0.0, ior=1.5) -> Closure:
    c = Closure(roughness=float(roughness), ior=float(ior))
    if spec is not None:
        c.specular = spec
    if trans is not None:
        c.transmission = trans
    c.glossy_weight = float(_luminance(c.specular + c.transmission))
    return c


def _luminance(rgb) -> float:
    return float(np.dot(rgb, (0.2126, 0.7152, 0.0722)))


class _Reader:
    """Evaluates one node tree; collects the names of inputs it had to approximate."""

    def __init__(self):
        self.approximated: list[str] = []

    # Socket values ------------------------------------------------------------------
    def _input(self, node, *names):
        for name in names:
            sock = node.inputs.get(name)
            if sock is not None:
                return sock
        raise UnreadableTree(f"node '{node.name}' has none of the inputs {names}")

    def _value(self, node, *names, default=None):
        """The socket's own value; a link from anything we cannot evaluate is noted."""
        try:
            sock = self._input(node, *names)
        except UnreadableTree:
            if default is None:
                raise
            return default
        if sock.is_linked:
            linked = _follow_reroutes(sock)
            if linked is not None and linked.node.bl_idname in ("ShaderNodeRGB", "ShaderNodeValue"):
                return linked.default_value  # a constant RGB / Value node
            if linked is not None:
                self.approximated.append(f"{node.name}.{sock.name}")
        return getattr(sock, "default_value", default)

    def color(self, node, *names, default=None):
        v = self._value(node, *names, default=default)
        return np.maximum(np.asarray(tuple(v)[:3] if hasattr(v, "__len__") else (v, v, v), np.float64), 0.0)

    def scalar(self, node, *names, default=None) -> float:
        v = self._value(node, *names, default=default)
        return float(tuple(v)[0] if hasattr(v, "__len__") else v)

    # Closures -----------------------------------------------------------------------
    def shader_input(self, sock) -> Closure:
        """The closure arriving at a shader socket; unlinked = no closure (black)."""
        linked = _follow_reroutes(sock) if sock.is_linked else None
        if linked is None:
            return Closure()
        return self.closure(linked.node)

    def closure(self, node) -> Closure:
        handler = _HANDLERS.get(node.bl_idname)
        if handler is None:
            raise UnreadableTree(f"unsupported node '{node.name}' ({node.bl_idname})")
        if getattr(node, "mute", False):
            raise UnreadableTree(f"muted node '{node.name}'")
        return handler(self, node)

    def principled(self, node) -> Closure:
        base = self.color(node, "Base Color")
        metallic = float(np.clip(self.scalar(node, "Metallic"), 0.0, 1.0))
        roughness = float(np.clip(self.scalar(node, "Roughness"), 0.0, 1.0))
        transmission = float(np.clip(self.scalar(node, "Transmission Weight", "Transmission",
                                                 default=0.0), 0.0, 1.0))
        ior = max(self.scalar(node, "IOR", default=1.5), 1e-5)
        emission = self.color(node, "Emission Color", "Emission", default=(0.0, 0.0, 0.0))
        strength = self.scalar(node, "Emission Strength", default=1.0)
        c = _glossy(spec=np.minimum(base, 1.0) * metallic,
                    trans=base * (1 - metallic) * transmission, roughness=roughness, ior=ior)
        c.diffuse = base * (1 - metallic) * (1 - transmission)
        c.emission = emission * max(strength, 0.0)
        return c

    def diffuse(self, node) -> Closure:
        return Closure(diffuse=self.color(node, "Color"))

    def glossy(self, node) -> Closure:
        return _glossy(spec=self.color(node, "Color"),
                       roughness=np.clip(self.scalar(node, "Roughness"), 0.0, 1.0))

    def glass(self, node) -> Closure:
        return _glossy(trans=self.color(node, "Color"),
                       roughness=np.clip(self.scalar(node, "Roughness"), 0.0, 1.0),
                       ior=max(self.scalar(node, "IOR"), 1e-5))

    def emission(self, node) -> Closure:
        # Background (world) and Emission share the colour x strength radiance.
        return Closure(emission=self.color(node, "Color") * max(self.scalar(node, "Strength"), 0.0))

    def mix(self, node) -> Closure:
        fac = float(np.clip(self.scalar(node, "Fac", "Factor"), 0.0, 1.0))
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        if len(shaders) != 2:
            raise UnreadableTree(f"mix node '{node.name}' without two shader inputs")
        a, b = self.shader_input(shaders[0]), self.shader_input(shaders[1])
        return a.scaled(1.0 - fac).plus(b.scaled(fac))

    def add(self, node) -> Closure:
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        total = Closure()
        for s in shaders:
            total = total.plus(self.shader_input(s))
        return total


_HANDLERS = {
    "ShaderNodeBsdfPrincipled": _Reader.principled,
    "ShaderNodeBsdfDiffuse": _Reader.diffuse,
    "ShaderNodeBsdfGlossy": _Reader.glossy,
    "ShaderNodeBsdfAnisotropic": _Reader.glossy,  # 4.x: the Glossy BSDF's real idname
    "ShaderNodeBsdfGlass": _Reader.glass,
    "ShaderNodeEmission": _Reader.emission,
    "ShaderNodeBackground": _Reader.emission,
    "ShaderNodeMixShader": _Reader.mix,
    "ShaderNodeAddShader": _Reader.add,
}


def _follow_reroutes(sock):
    """The output socket feeding ``sock`` (through reroutes), or None if unlinked/invalid."""
    seen = 0
    while sock.is_linked and seen < 64:
        link = sock.links[0]
        if not link.is_valid or getattr(link, "is_muted", False):
            return None
        out = link.from_socket
        if out.node.bl_idname != "NodeReroute":
            return out
        sock = out.node.inputs[0]
        seen += 1
    return None


def _active_output(tree, idnames):
    output = None
    if hasattr(tree, "get_output_node"):
        output = tree.get_output_node('CYCLES')
    if output is None:
        for node in tree.nodes:
            if node.bl_idname in idnames and getattr(node, "is_active_output", True) \
                    and getattr(node, "target", 'ALL') in ('ALL', 'CYCLES'):
                output = node
                break
    return output


def read_surface(tree, output_idnames) -> tuple[Closure, list[str]]:
    """Evaluate a tree's active output Surface. Returns (closure, approximated inputs).

    Raises UnreadableTree when the tree has no usable output or an unsupported node.
    """
    output = _active_output(tree, output_idnames)
    if output is None:
        raise UnreadableTree("no active output node")
    reader = _Reader()
    return reader.shader_input(output.inputs["Surface"]), reader.approximated


def _node_tree(idblock):
    """The ID's node tree if Cycles would use it (5.0 always does; ``use_nodes`` is deprecated)."""
    import bpy

    tree = getattr(idblock, "node_tree", None)
    if tree is None or bpy.app.version >= (5, 0, 0):
        return tree
    return tree if idblock.use_nodes else None


def read_material(mat, warnings: list[str]) -> dict:
    """One material -> a row for ``Materials.from_list``; appends at most one warning.

    Without a node tree (legacy materials), Cycles renders ``diffuse_color`` as diffuse.
    """
    name = mat.name
    tree = _node_tree(mat)
    if tree is None:
        return Closure(diffuse=np.asarray(mat.diffuse_color[:3], np.float64)).as_row(name)
    try:
        closure, approximated = read_surface(tree, ("ShaderNodeOutputMaterial",))
    except UnreadableTree as exc:
        warnings.append(f"Material '{name}': cannot read its node tree ({exc}); "
                        f"rendering it as grey diffuse")
        return default_row(name)
    notes = []
    if approximated:
        notes.append("linked inputs replaced by their own values: " + ", ".join(approximated))
    for lobe in ("diffuse", "specular", "transmission"):
        v = getattr(closure, lobe)
        if np.any(v > 1.0):
            setattr(closure, lobe, np.minimum(v, 1.0))
            notes.append(f"{lobe} colour above 1 clamped to 1")
    if notes:
        warnings.append(f"Material '{name}': " + "; ".join(notes))
    return closure.as_row(name)


def read_world(world, warnings: list[str]) -> np.ndarray:
    """World -> background radiance (3,) float64, W/(m^2 sr); black when there is none.

    Follows the World Output's Surface (Background: colour x strength); a tree that
    cannot be read falls back to ``world.color`` with a warning.
    """
    if world is None:
        return np.zeros(3)
    tree = _node_tree(world)
    if tree is None:
        return np.asarray(world.color[:3], np.float64)
    try:
        closure, approximated = read_surface(tree, ("ShaderNodeOutputWorld",))
    except UnreadableTree as exc:
        warnings.append(f"World '{world.name}': cannot read its node tree ({exc}); "
                        f"using its viewport colour")
        return np.asarray(world.color[:3], np.float64)
    if approximated:
        warnings.append(f"World '{world.name}': linked inputs replaced by their own values: "
                        + ", ".join(approximated))
    # Only emission means anything for a background; BSDFs there render black in Cycles.
    return closure.emission


def read_light_nodes(light, warnings: list[str]) -> np.ndarray:
    """The colour factor (3,) a light's own node tree applies to its emission (1 if none)."""
    tree = light.node_tree if getattr(light, "use_nodes", False) else None
    if tree is None:
        return np.ones(3)
    try:
        closure, approximated = read_surface(tree, ("ShaderNodeOutputLight",))
    except UnreadableTree as exc:
        warnings.append(f"Light '{light.name}': cannot read its node tree ({exc}); ignoring it")
        return np.ones(3)
    if approximated:
        warnings.append(f"Light '{light.name}': linked inputs replaced by their own values: "
                        + ", ".join(approximated))
    return closure.emission

"""Blender shader node trees -> the core's material lobes (see core/scene/contract.py, Materials).

A surface is read by following the active output's Surface input through the shader
nodes the core can express. Each node becomes a ``Closure``: the four lobe colours
(diffuse, specular, transmission, emission) plus the roughness and IOR they share, the
image texture that multiplies the diffuse lobe and the transparency (straight
pass-through weight). Mix Shader interpolates closures, Add Shader sums them.

Image Texture nodes (directly or through Reroutes) feeding Principled Base Color or
Diffuse Color become a texture of the scene (``ImageTable``: each image's pixels read
once per export with ``foreach_get``, sRGB images linearised, Non-Color/linear ones
not); the lobe weights are stored with the base colour factored out, and the core
multiplies the diffuse lobe by the texel. Principled Alpha (a constant, or an Image
Texture's Alpha output) and Transparent BSDF make the surface a cut-out.

Every node the exporter cannot express is reported once per material, by material and
node name: a linked input falls back to its socket's own value, an unknown shader node
makes the material grey diffuse. Never an exception.

Mapping (Cycles' node semantics, ``docs/export.md`` has the table):
- Principled BSDF: diffuse = base (1 - metallic)(1 - transmission),
  specular = base metallic, transmission = base (1 - metallic) transmission,
  emission = emission colour x strength. Its dielectric specular layer
  (Specular IOR Level), coat, sheen and subsurface are not modelled yet. With an image
  as base colour the diffuse lobe is textured; the metallic and transmission tints use
  the image's mean colour (the core textures the diffuse lobe only).
  Alpha a: a x (the BSDF) + (1 - a) x transparent.
- Transparent BSDF: straight pass-through weighted by its colour's mean.
- Diffuse BSDF -> diffuse; Glossy BSDF -> specular; Glass BSDF -> transmission;
  Emission -> emission (radiance W/(m^2 sr) = colour x strength).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.color import luminance
from ..core.materials.textures import srgb_to_linear
from ..core.scene.contract import Textures
from . import compat

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
    diffuse_texture: int = -1   # index into the ImageTable, multiplies the diffuse lobe
    transparency: float = 0.0   # weight of the straight pass-through (1 - opacity)
    alpha_texture: int = -1     # image whose alpha multiplies the opacity

    def scaled(self, w: float) -> "Closure":
        return Closure(self.diffuse * w, self.specular * w, self.transmission * w,
                       self.emission * w, self.roughness, self.ior, self.glossy_weight * w,
                       self.diffuse_texture, self.transparency * w, self.alpha_texture)

    def plus(self, other: "Closure") -> "Closure":
        wa, wb = self.glossy_weight, other.glossy_weight
        if wa + wb > 0:
            roughness = (wa * self.roughness + wb * other.roughness) / (wa + wb)
            ior = (wa * self.ior + wb * other.ior) / (wa + wb)
        else:
            roughness, ior = max(self.roughness, other.roughness), self.ior
        tex = self.diffuse_texture if self.diffuse_texture >= 0 else other.diffuse_texture
        atex = self.alpha_texture if self.alpha_texture >= 0 else other.alpha_texture
        return Closure(self.diffuse + other.diffuse, self.specular + other.specular,
                       self.transmission + other.transmission, self.emission + other.emission,
                       roughness, ior, wa + wb, tex, self.transparency + other.transparency,
                       atex)

    def as_row(self, name: str) -> dict:
        """A ``Materials.from_list`` row. Transparency t becomes opacity 1 - t and the
        other lobes are divided by the opacity (the core scales what a hit sees by the
        opacity when it picks the surface instead of the pass-through)."""
        opacity = float(np.clip(1.0 - self.transparency, 0.0, 1.0))
        k = 1.0 / opacity if 0.0 < opacity < 1.0 else 1.0
        row = {"name": name, "diffuse": self.diffuse * k, "specular": self.specular * k,
               "transmission": self.transmission * k, "emission": self.emission * k,
               "roughness": float(np.clip(self.roughness, 0.0, 1.0)), "ior": float(self.ior),
               "diffuse_texture": int(self.diffuse_texture), "alpha": opacity,
               "alpha_texture": int(self.alpha_texture)}
        return row


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
    return float(luminance(rgb))


class _Reader:
    """Evaluates one node tree; collects what it had to approximate.

    unsupported: node name -> (bl_idname, [inputs it fed]) of every node that could not be
    evaluated (each reported once); notes: other approximations, one line each.
    images: the export's ImageTable (None: image textures are reported as unsupported).
    """

    def __init__(self, images=None, material=""):
        self.unsupported: dict[str, tuple[str, list[str]]] = {}
        self.notes: list[str] = []
        self.images = images
        self.material = material

    @property
    def approximated(self) -> list[str]:
        """"Node.Input" of every input replaced by its socket value (older callers)."""
        return [use for _, uses in self.unsupported.values() for use in uses]

    def _unsupported(self, node, use):
        idname, uses = self.unsupported.setdefault(node.name, (node.bl_idname, []))
        if use and use not in uses:
            uses.append(use)

    def note(self, text):
        if text not in self.notes:
            self.notes.append(text)

    # Socket values ------------------------------------------------------------------
    def _input(self, node, *names):
        sock = compat.input_socket(node, *names)
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
                self._unsupported(linked.node, f'input "{sock.name}" of node "{node.name}"')
        return getattr(sock, "default_value", default)

    def image_input(self, node, names, output):
        """(ImageTable index or -1, fed) for an input fed by an Image Texture node's
        ``output`` ("Color" or "Alpha"), directly or through reroutes. fed is False when
        the input is not fed that way (read its value instead); an image that cannot be
        read gives (-1, True), reported once by the ImageTable."""
        try:
            sock = self._input(node, *names)
        except UnreadableTree:
            return -1, False
        linked = _follow_reroutes(sock) if sock.is_linked else None
        if linked is None or linked.node.bl_idname != "ShaderNodeTexImage" \
                or self.images is None or getattr(linked.node, "mute", False):
            return -1, False
        tex = linked.node
        if linked.name != output:
            self._unsupported(tex, f'its "{linked.name}" output into input "{sock.name}" of '
                                   f'node "{node.name}" (only Color -> colour, Alpha -> Alpha)')
            return -1, False
        where = f'Material "{self.material}": node "{tex.name}"'
        if tex.inputs["Vector"].is_linked:
            self.note(f'{where}: its Vector input is ignored; using the active render UV map')
        if getattr(tex, "projection", "FLAT") != "FLAT":
            self.note(f'{where}: projection {tex.projection} is not supported; using FLAT')
        if getattr(tex, "extension", "REPEAT") != "REPEAT":
            self.note(f'{where}: extension {tex.extension} is not supported; using REPEAT')
        index = self.images.index(tex.image, where)
        return (-1 if index is None else index), True


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

    def _base_color(self, node, *names):
        """(colour (3,), texture index): the base colour, or white and the image that
        replaces it when an Image Texture feeds it (grey 0.8 for a missing image)."""
        tex, fed = self.image_input(node, names, "Color")
        if fed:
            return (np.ones(3), tex) if tex >= 0 else (np.full(3, DEFAULT_GREY), -1)
        return self.color(node, *names), -1

    def principled(self, node) -> Closure:
        base, tex = self._base_color(node, "Base Color")
        tint = base if tex < 0 else self.images.mean_rgb(tex)
        metallic = float(np.clip(self.scalar(node, "Metallic"), 0.0, 1.0))
        roughness = float(np.clip(self.scalar(node, "Roughness"), 0.0, 1.0))
        transmission = float(np.clip(self.scalar(node, "Transmission Weight",
                                                 default=0.0), 0.0, 1.0))
        ior = max(self.scalar(node, "IOR", default=1.5), 1e-5)
        emission = self.color(node, "Emission Color", default=(0.0, 0.0, 0.0))
        strength = self.scalar(node, "Emission Strength", default=1.0)
        c = _glossy(spec=np.minimum(tint, 1.0) * metallic,
                    trans=tint * (1 - metallic) * transmission, roughness=roughness, ior=ior)
        c.diffuse = base * (1 - metallic) * (1 - transmission)
        c.diffuse_texture = tex
        c.emission = emission * max(strength, 0.0)
        if transmission > 0 and compat.thin_wall(node):
            self.note(f'Material "{self.material}": node "{node.name}": Thin Wall is not '
                      f'supported yet; its transmission refracts as a solid volume')
        if tex >= 0 and (metallic > 0 or transmission > 0):
            self.note(f'Material "{self.material}": node "{node.name}": metallic and '
                      f'transmission use the image\'s mean colour (only the diffuse lobe '
                      f'is textured)')
        atex, linked_alpha = self.image_input(node, ("Alpha",), "Alpha")
        alpha = 1.0 if linked_alpha else float(np.clip(self.scalar(node, "Alpha", default=1.0),
                                                       0.0, 1.0))
        if alpha < 1.0:
            c = c.scaled(alpha)
            c.transparency = 1.0 - alpha
        c.alpha_texture = atex
        return c

    def transparent(self, node) -> Closure:
        return Closure(transparency=float(np.clip(np.mean(self.color(node, "Color")), 0.0, 1.0)))

    def diffuse(self, node) -> Closure:
        color, tex = self._base_color(node, "Color")
        return Closure(diffuse=color, diffuse_texture=tex)

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
        fac = float(np.clip(self.scalar(node, "Factor"), 0.0, 1.0))
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        if len(shaders) != 2:
            raise UnreadableTree(f"mix node '{node.name}' without two shader inputs")
        a, b = self.shader_input(shaders[0]), self.shader_input(shaders[1])
        self._check_textures(node, a, b)
        return a.scaled(1.0 - fac).plus(b.scaled(fac))

    def add(self, node) -> Closure:
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        total = Closure()
        for s in shaders:
            c = self.shader_input(s)
            self._check_textures(node, total, c)
            total = total.plus(c)
        return total

    def _check_textures(self, node, a: Closure, b: Closure):
        """One image per material multiplies the whole diffuse lobe: say so when a mix
        combines a textured diffuse with another diffuse."""
        ta, tb = a.diffuse_texture, b.diffuse_texture
        if (ta >= 0 or tb >= 0) and (ta != tb) and a.diffuse.any() and b.diffuse.any():
            self.note(f'Material "{self.material}": node "{node.name}" mixes diffuse shaders '
                      f'with different base colour images; the material\'s whole diffuse '
                      f'lobe uses one image')


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
    "ShaderNodeBsdfTransparent": _Reader.transparent,
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


def read_surface(tree, output_idnames, reader=None) -> tuple[Closure, list[str]]:
    """Evaluate a tree's active output Surface. Returns (closure, approximated inputs);
    ``reader`` (a _Reader) collects the details when given.

    Raises UnreadableTree when the tree has no usable output or an unsupported node.
    """
    output = _active_output(tree, output_idnames)
    if output is None:
        raise UnreadableTree("no active output node")
    reader = reader or _Reader()
    return reader.shader_input(output.inputs["Surface"]), reader.approximated


def _node_tree(idblock):
    """The ID's node tree if Cycles would use it (compat.node_tree)."""
    return compat.node_tree(idblock)


def read_material(mat, warnings: list[str], images: "ImageTable | None" = None) -> dict:
    """One material -> a row for ``Materials.from_list``; appends one warning per node
    it cannot express (by material and node name) and one per other approximation.

    images: the export's ImageTable (Image Texture nodes become textures); None reports
    them as unsupported like any other node. Without a node tree (legacy materials),
    Cycles renders ``diffuse_color`` as diffuse.
    """
    name = mat.name
    tree = _node_tree(mat)
    if tree is None:
        return Closure(diffuse=np.asarray(mat.diffuse_color[:3], np.float64)).as_row(name)
    reader = _Reader(images, name)
    try:
        closure, _ = read_surface(tree, ("ShaderNodeOutputMaterial",), reader)
    except UnreadableTree as exc:
        warnings.append(f'Material "{name}": cannot read its node tree ({exc}); '
                        f"rendering it as grey diffuse")
        return default_row(name)
    for node_name, (idname, uses) in reader.unsupported.items():
        warnings.append(f'Material "{name}": node "{node_name}" ({idname}) is not supported; '
                        f"using the socket value of " + ", ".join(uses))
    warnings.extend(reader.notes)
    notes = []
    for lobe in ("diffuse", "specular", "transmission"):
        v = getattr(closure, lobe)
        if np.any(v > 1.0):
            setattr(closure, lobe, np.minimum(v, 1.0))
            notes.append(f"{lobe} colour above 1 clamped to 1")
    if notes:
        warnings.append(f'Material "{name}": ' + "; ".join(notes))
    row = closure.as_row(name)
    for lobe in ("diffuse", "specular", "transmission"):
        row[lobe] = np.minimum(row[lobe], 1.0)  # the opacity division must not create energy
    return row


class ImageTable:
    """The images of one export, each read ONCE into numpy however many materials use it.

    ``index(image, where)`` returns the texture index (None for a missing image or one
    without pixels, reported once with ``where``, "Material ...: node ..."). Pixels are
    read with ``Image.pixels.foreach_get`` into float32 and decoded to linear: byte images
    tagged sRGB (or another sRGB-like display space) with the exact sRGB EOTF; Non-Color,
    Linear* and float images (Blender keeps those in scene linear) as they are.
    """

    LINEAR_SPACES = ("Non-Color", "Raw", "scene_linear", "Linear", "ACEScg", "ACES2065-1")

    def __init__(self, warnings: list[str]):
        self._warnings = warnings
        self._index: dict = {}
        self._images: list[np.ndarray] = []
        self._names: list[str] = []
        self._means: list[np.ndarray] = []

    def index(self, image, where: str) -> int | None:
        if image is None:
            msg = f"{where} has no image; using grey {DEFAULT_GREY}"
            if msg not in self._warnings:
                self._warnings.append(msg)
            return None
        image = getattr(image, "original", image) or image
        key = image.as_pointer()
        if key not in self._index:
            self._index[key] = self._read(image, where)
        elif self._index[key] is None:
            # Unreadable image used again: name this material and node too (once).
            msg = (f'{where}: image "{image.name}" has no pixels (missing file?); '
                   f"using grey {DEFAULT_GREY}")
            if msg not in self._warnings:
                self._warnings.append(msg)
        return self._index[key]

    def _read(self, image, where) -> int | None:
        try:
            w, h = (int(x) for x in image.size)
            channels = int(image.channels)
        except (AttributeError, ReferenceError):
            w = h = channels = 0
        n = w * h * channels
        buf = None
        if n > 0:
            buf = np.empty(n, np.float32)
            try:
                image.pixels.foreach_get(buf)
            except (RuntimeError, ValueError, TypeError):
                buf = None
        if buf is None:
            self._warnings.append(f'{where}: image "{image.name}" has no pixels (missing file?); '
                                  f"using grey {DEFAULT_GREY}")
            return None
        px = buf.reshape(h, w, channels)
        rgba = np.ones((h, w, 4), np.float32)
        if channels >= 3:
            rgba[..., :3] = px[..., :3]
        else:
            rgba[..., :3] = px[..., :1]
        if channels in (2, 4):
            rgba[..., 3] = px[..., -1]
        space = image.colorspace_settings.name
        linear = bool(getattr(image, "is_float", False)) or space.startswith(self.LINEAR_SPACES)
        if not linear:
            if space != "sRGB":
                self._warnings.append(f'{where}: image "{image.name}" colour space "{space}" '
                                      f"is decoded as sRGB")
            rgba[..., :3] = srgb_to_linear(rgba[..., :3])
        np.clip(rgba, 0.0, None, out=rgba)
        rgba[~np.isfinite(rgba)] = 0.0
        if getattr(image, "alpha_mode", "STRAIGHT") == "NONE":
            rgba[..., 3] = 1.0  # the image's alpha is ignored: opaque
        self._images.append(rgba)
        self._names.append(image.name)
        self._means.append(rgba[..., :3].reshape(-1, 3).mean(axis=0).astype(np.float64))
        return len(self._images) - 1

    def mean_rgb(self, index: int) -> np.ndarray:
        """(3,) float64 mean linear colour of texture ``index``."""
        return self._means[index]

    def textures(self) -> Textures:
        """The scene's Textures (images in index order, row 0 at the bottom)."""
        if not self._images:
            return Textures.empty()
        return Textures.from_images(self._images, self._names)


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
    tree = compat.node_tree(light)
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

"""Reading shader nodes: socket values with Cycles' ranges, links, images, and ``Closure``,
what one shader contributes to a material.

A ``Closure`` carries the material as the core reads it in two forms:
- ``bsdfs``: closure rows (core/scene/closures.py): kind, Mix/Add weight (3,), the node's
  inputs in the parameter slots, the texture multiplying the COLOR slot; Mix Shader and
  Add Shader scale and concatenate them;
- the legacy lobes (diffuse, specular, transmission, shared roughness and IOR), which the
  core's passes read until they read ``Materials.closure_table()``; both are written.
Emission and transparency are per material in both forms.

``NodeReader`` reads inputs the way Cycles' SVM does (core/scene/closures.py says what
each slot means): a constant RGB / Value node feeding an input is read, any other link
falls back to the socket's own value and is reported; a value outside the range Cycles
clamps it to is clamped and reported; an IOR <= 0 is read as 1 and reported. Every
message names the material, the node and the input, once per material.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.color import luminance
from ..core.scene import closures
from . import compat
from .export_images import DEFAULT_GREY


class UnreadableTree(Exception):
    """Raised inside the reader when a node tree cannot be expressed as closures."""


@dataclass
class Closure:
    """One shader's contribution. Colours are (3,) float64 linear RGB.

    bsdfs: closure rows, dicts with ``kind`` (closures.CLOSURE_*), ``weight`` (3,) float64
        >= 0, ``params`` (closures.PARAM_COUNT,) float32, ``texture`` int (-1 = none),
        and ``factors`` when a linked Mix Shader factor weights it (``factored``: dicts
        with the Mix ``node``, its factor ``socket`` and ``take``, True for fac, False
        for 1 - fac; ``weight`` is then the constant rest of the product).
    diffuse, specular, transmission, roughness, ior, glossy_weight, diffuse_texture: the
        legacy lobes; roughness and ior are shared by specular and transmission,
        ``glossy_weight`` (the luminance of specular + transmission) says how much of the
        closure uses them, so a mix can average them.
    emission: radiance W/(m^2 sr). transparency: weight of the straight pass-through
        (1 - opacity); alpha_texture: image whose alpha multiplies the opacity.
    emitters: the shader nodes that emit, for emission programs: dicts with ``node``,
        ``color`` / ``strength`` (their input socket names), ``weight`` (the Mix /
        Add factor product above them) and ``factors`` as a closure row's; ``emission``
        is their constant sum.
    cutouts: opacities a program computes (their constant part is 1): dicts with
        ``node``, ``socket`` (input name) and ``kind``: "alpha" (Principled Alpha:
        opacity = clamp(value)), "mix_a" / "mix_b" (a Mix Shader whose Factor is linked
        and whose first / second shader is a Transparent BSDF of mean colour ``mean``:
        opacity = 1 - (1 - fac) mean, resp. 1 - fac mean), ``weight`` (the constant Mix /
        Add factor product above it) and ``factors`` (the linked ones, as a row's). The
        closure rows and emitters it cuts hold its factor in their ``cuts`` (same form as
        ``factors``: fac, 1 - fac or clamp(Alpha)): their share inside the cut-out, which
        a cut-out nested under another Mix / Add needs (export_materials._program).
    """

    diffuse: np.ndarray = field(default_factory=lambda: np.zeros(3))
    specular: np.ndarray = field(default_factory=lambda: np.zeros(3))
    transmission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    roughness: float = 0.0
    ior: float = 1.5
    glossy_weight: float = 0.0
    diffuse_texture: int = -1
    transparency: float = 0.0
    alpha_texture: int = -1
    bsdfs: list = field(default_factory=list)
    emitters: list = field(default_factory=list)
    cutouts: list = field(default_factory=list)

    def scaled(self, w: float) -> "Closure":
        return Closure(self.diffuse * w, self.specular * w, self.transmission * w,
                       self.emission * w, self.roughness, self.ior, self.glossy_weight * w,
                       self.diffuse_texture, self.transparency * w, self.alpha_texture,
                       [dict(b, weight=b["weight"] * w) for b in self.bsdfs],
                       [dict(e, weight=e["weight"] * w) for e in self.emitters],
                       [dict(e, weight=e["weight"] * w) for e in self.cutouts])

    def factored(self, node, sock, take: bool, value: float) -> "Closure":
        """This closure under a Mix Shader ``node`` whose factor input ``sock`` is linked
        to a node graph: each closure row and emitter keeps its weight and gets the factor
        (clamped fac if ``take``, else 1 - fac) appended to its ``factors``, which a
        shader program evaluates per hit (``TARGET_WEIGHT`` / the emission program); the
        legacy lobes and transparency take ``value`` (the factor's constant stand-in, fac
        or 1 - fac of the socket's own value); a cut-out keeps its weight and gets the
        factor too (the program computes its share)."""
        f = {"node": node, "socket": sock, "take": bool(take)}
        c = self.scaled(value)
        c.bsdfs = [dict(b, factors=b.get("factors", []) + [f]) for b in self.bsdfs]
        c.emitters = [dict(e, factors=e.get("factors", []) + [f]) for e in self.emitters]
        c.cutouts = [dict(e, factors=e.get("factors", []) + [f]) for e in self.cutouts]
        return c

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
                       atex, self.bsdfs + other.bsdfs, self.emitters + other.emitters,
                       self.cutouts + other.cutouts)

    def as_row(self, name: str) -> dict:
        """A ``Materials.from_list`` row with both forms. Transparency t becomes opacity
        1 - t, and the lobes and closure weights are divided by the opacity (the core
        scales what a hit sees by the opacity when it picks the surface instead of the
        pass-through). Closures of zero weight (a Mix at factor 0) are left out, as
        Cycles skips them (``kept_row``)."""
        opacity = float(np.clip(1.0 - self.transparency, 0.0, 1.0))
        k = 1.0 / opacity if 0.0 < opacity < 1.0 else 1.0
        rows = [{"kind": b["kind"], "weight": np.asarray(b["weight"], np.float64) * k,
                 "params": b["params"], "texture": int(b["texture"])}
                for b in self.bsdfs if kept_row(b)]
        return {"name": name, "diffuse": self.diffuse * k, "specular": self.specular * k,
                "transmission": self.transmission * k, "emission": self.emission * k,
                "roughness": float(np.clip(self.roughness, 0.0, 1.0)), "ior": float(self.ior),
                "diffuse_texture": int(self.diffuse_texture), "alpha": opacity,
                "alpha_texture": int(self.alpha_texture), "closures": rows}


def kept_row(b: dict) -> bool:
    """A closure row reaches the material: a weight > 0 somewhere, or a per-hit weight
    (``factors``, a linked Mix factor) even where its constant part folded to 0, so the
    program's closure indices stay those of ``Closure.as_row``."""
    return bool(np.any(np.asarray(b["weight"]) > 0) or b.get("factors"))


def closure_row(kind: int, weight=1.0, texture: int = -1, **values) -> dict:
    """A closure row: ``kind`` (closures.CLOSURE_*), Mix/Add ``weight`` (scalar or (3,)),
    the COLOR ``texture`` and slot ``values`` as ``closures.params`` takes them."""
    weight = np.broadcast_to(np.asarray(weight, np.float64), (3,)).copy()
    return {"kind": int(kind), "weight": weight,
            "params": closures.params(**values), "texture": int(texture)}


def diffuse_closure(color, texture: int = -1) -> Closure:
    """A Lambert closure of albedo ``color`` (3,) in both forms (texture multiplies it)."""
    color = np.asarray(color, np.float64)
    return Closure(diffuse=color, diffuse_texture=texture,
                   bsdfs=[closure_row(closures.CLOSURE_DIFFUSE, color=color, roughness=0.0,
                               texture=texture)])


def legacy_glossy(c: Closure, spec=None, trans=None, roughness=0.0, ior=1.5) -> Closure:
    """``c`` with its legacy specular / transmission lobes set (and their shared weight)."""
    c.roughness, c.ior = float(roughness), float(ior)
    if spec is not None:
        c.specular = np.asarray(spec, np.float64)
    if trans is not None:
        c.transmission = np.asarray(trans, np.float64)
    c.glossy_weight = float(luminance(c.specular + c.transmission))
    return c


def follow_reroutes(sock):
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


class NodeReader:
    """Reads one material's node inputs; collects what it had to approximate.

    unsupported: node name -> (bl_idname, [inputs it fed]) of every node that could not be
    evaluated (each reported once); notes: other approximations, one line each.
    images: the export's ImageTable (None: image textures are reported as unsupported).
    """

    def __init__(self, images=None, material=""):
        self.unsupported: dict[str, tuple[str, list[str]]] = {}
        self.notes: list[str] = []
        self.images = images
        self.material = material
        self.linked: list | None = None
        """None: a linked input is reported; a list: (node, socket) of each linked input
        read as its socket value, for the shader compiler (export_materials)."""
        self.program_images = False
        """True when the shader compiler reads images (export_images.ProgramImageTable):
        an Image Texture into a colour that the direct texture path ignores (its Vector
        linked, an extension other than Repeat) is then left to the program
        (``textured_color``). Its interpolation alone does not move it: a plain Closest
        image renders as before (Linear, the direct path)."""

    @property
    def approximated(self) -> list[str]:
        """"Node.Input" of every input replaced by its socket value (older callers)."""
        return [use for _, uses in self.unsupported.values() for use in uses]

    def unsupported_node(self, node, use):
        idname, uses = self.unsupported.setdefault(node.name, (node.bl_idname, []))
        if use and use not in uses:
            uses.append(use)

    def note(self, text):
        if text not in self.notes:
            self.notes.append(text)

    def note_node(self, node, text):
        """One line about ``node`` of this material."""
        self.note(f'Material "{self.material}": node "{node.name}": {text}')

    # Socket values ------------------------------------------------------------------
    def socket(self, node, *names):
        sock = compat.input_socket(node, *names)
        if sock is not None:
            return sock
        raise UnreadableTree(f"node '{node.name}' has none of the inputs {names}")

    def value(self, node, *names, default=None):
        """The socket's own value (or a constant RGB / Value node's); any other link is
        reported. ``default`` is returned when the node has none of ``names`` (an input
        of a newer Blender); without it a missing input raises UnreadableTree."""
        sock = compat.input_socket(node, *names)
        if sock is None:
            if default is None:
                raise UnreadableTree(f"node '{node.name}' has none of the inputs {names}")
            return default
        if sock.is_linked:
            linked = follow_reroutes(sock)
            if linked is not None and linked.node.bl_idname in ("ShaderNodeRGB", "ShaderNodeValue"):
                return linked.default_value  # a constant RGB / Value node
            if linked is not None and self.linked is not None:
                self.linked.append((node, sock))
            elif linked is not None:
                self.unsupported_node(linked.node, f'input "{sock.name}" of node "{node.name}"')
        return getattr(sock, "default_value", default)

    def color(self, node, *names, default=None) -> np.ndarray:
        """(3,) float64 linear RGB of a colour input, as given (not clamped)."""
        return np.asarray(tuple(self.value(node, *names, default=default))[:3], np.float64)

    def scalar(self, node, *names, default=None) -> float:
        v = self.value(node, *names, default=default)
        return float(tuple(v)[0] if hasattr(v, "__len__") else v)

    def ranged(self, node, name, lo=0.0, hi=1.0, default=None) -> float:
        """A scalar input clamped to [lo, hi] (Cycles' clamp of that input; a Value node
        or a driver can go past the slider's range), reported when it had to be."""
        v = self.scalar(node, name, default=default)
        c = float(np.clip(v, lo, hi)) if np.isfinite(v) else (lo if np.isfinite(lo) else 0.0)
        if c != v:
            span = f"[{lo:g}, {hi:g}]" if np.isfinite(hi) else f">= {lo:g}"
            self.note_node(node, f'input "{name}" = {v:g} is outside {span}; clamped to {c:g}')
        return c

    def ranged_color(self, node, name, hi=1.0, default=None) -> np.ndarray:
        """(3,) colour input clamped to [0, hi] per channel, reported when it had to be
        (negative colours mean nothing; reflectances above 1 create energy)."""
        v = self.color(node, name, default=default)
        c = np.clip(np.nan_to_num(v, nan=0.0), 0.0, hi)
        if not np.array_equal(c, v):
            shown = ", ".join(f"{x:g}" for x in v)
            span = f"[0, {hi:g}]" if np.isfinite(hi) else ">= 0"
            self.note_node(node, f'input "{name}" = ({shown}) is outside {span}; clamped')
        return c

    def tint(self, node, name, base, default=(1.0, 1.0, 1.0)) -> np.ndarray:
        """(3,) a tint colour input (Specular / Sheen Tint), clamped to >= 0. Blender 3.x's
        Principled (v1) has a scalar there instead, t in [0, 1]: the tint goes from white
        (t = 0) to the base colour's hue (base / its luminance, t = 1), as Cycles 3.x."""
        sock = compat.input_socket(node, name)
        if sock is None or sock.type != 'VALUE':
            return self.ranged_color(node, name, float("inf"), default=default)
        t = self.ranged(node, name)
        lum = float(luminance(base))
        hue = base / lum if lum > 0 else np.ones(3)
        return (1.0 - t) + t * hue

    def ior(self, node, name="IOR", default=None) -> float:
        """An index of refraction: <= 0 (or not finite) means nothing and renders as 1
        (no refraction, no reflection), reported; Cycles would clamp it to 1e-5, which
        gives fireflies."""
        v = self.scalar(node, name, default=default)
        if not (np.isfinite(v) and v > 0.0):
            self.note_node(node, f'input "{name}" = {v:g} is not > 0; rendering it as IOR 1')
            return 1.0
        return v

    def enum(self, node, prop, table: dict, fallback):
        """``table[node.<prop>]``; an unknown value (a newer Blender) is reported and
        rendered as ``fallback``."""
        value = getattr(node, prop, None)
        if value in table:
            return table[value]
        self.note_node(node, f'{prop} "{value}" is not supported; rendering it as '
                             f'{next(k for k, v in table.items() if v == fallback)}')
        return fallback

    def ignored_links(self, node, *names):
        """Report each input among ``names`` that is linked but not read. A linked
        "Normal" goes to the shader program instead when programs are compiled
        (``linked`` is a list: export_materials._program makes it the shading normal), so
        does a linked "Tangent" (the closure's TANGENT slots, core ``HitShader.tangents``)
        and a linked "Coat Normal" (the COAT_NORMAL slots, core ``prepared.coat_normals``).
        Without programs each is reported and the shading normal / radial tangent used."""
        for name in names:
            sock = node.inputs.get(name)
            if sock is not None and sock.is_linked and follow_reroutes(sock) is not None:
                if name in ("Normal", "Tangent", "Coat Normal") and self.linked is not None:
                    # the program's shading normal; the closure's TANGENT / COAT_NORMAL slots
                    self.linked.append((node, sock))
                    continue
                what = "the shading normal" if "Normal" in name else "the radial tangent"
                self.note_node(node, f'input "{name}" is linked; normal and tangent inputs '
                                     f'are not supported yet, using {what}')

    def thin_film(self, node):
        """Report a Thin Film Thickness > 0 (4.2+): thin-film interference is ignored."""
        thickness = self.scalar(node, "Thin Film Thickness", default=0.0)
        if thickness > 0.0:
            self.note_node(node, f"thin film ({thickness:g} nm) is not supported yet; ignored")

    def image_input(self, node, names, output):
        """(ImageTable index or -1, fed) for an input fed by an Image Texture node's
        ``output`` ("Color" or "Alpha"), directly or through reroutes. fed is False when
        the input is not fed that way (read its value instead); an image that cannot be
        read gives (-1, True), reported once by the ImageTable."""
        sock = compat.input_socket(node, *names)
        if sock is None:
            return -1, False
        linked = follow_reroutes(sock) if sock.is_linked else None
        if linked is None or linked.node.bl_idname != "ShaderNodeTexImage" \
                or self.images is None or getattr(linked.node, "mute", False):
            return -1, False
        tex = linked.node
        if linked.name != output:
            self.unsupported_node(tex, f'its "{linked.name}" output into input "{sock.name}" of '
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

    def textured_color(self, node, name) -> tuple[np.ndarray, int, np.ndarray]:
        """(COLOR slot (3,), texture index, legacy tint (3,)) of a colour input: an Image
        Texture feeding it gives white and its index (the core multiplies by the texel)
        and, for the legacy lobes, the image's mean colour; a missing image grey 0.8."""
        sock = compat.input_socket(node, name)
        linked = follow_reroutes(sock) if sock is not None and sock.is_linked else None
        if self.program_images and self.linked is not None and linked is not None \
                and linked.node.bl_idname == "ShaderNodeTexImage" \
                and not getattr(linked.node, "mute", False) and linked.name == "Color" \
                and (linked.node.inputs["Vector"].is_linked
                     or linked.node.extension != "REPEAT"):
            c = self.ranged_color(node, name)  # linked: compiled into the program
            return c, -1, c
        tex, fed = self.image_input(node, (name,), "Color")
        if fed:
            if tex < 0:
                grey = np.full(3, DEFAULT_GREY)
                return grey, -1, grey
            return np.ones(3), tex, np.minimum(self.images.mean_rgb(tex), 1.0)
        c = self.ranged_color(node, name)
        return c, -1, c

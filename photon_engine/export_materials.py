"""Blender shader node trees -> the core's materials (core/scene/contract.py, Materials).

A surface is read by following the active Material Output's Surface input (through
Reroutes) to shader nodes: each BSDF node becomes closure rows with Cycles' semantics
(export_shaders.py, one function per node; core/scene/closures.py for the slots), Mix
Shader scales its two inputs by 1 - Factor and Factor, Add Shader concatenates them, so a
material is the weighted sum Cycles' SVM builds. Emission (colour x strength, W/(m^2 sr))
and opacity (Principled Alpha, Transparent BSDF: a cut-out) are per material. Each row
also carries the legacy lobes (diffuse, specular, transmission) that the core's passes
read until they read ``Materials.closure_table()`` (export_nodes.Closure).

Image Texture nodes (directly or through Reroutes) feeding a node's Base Color / Color
become textures of the scene (export_images.ImageTable, each image read once per export):
the closure's ``texture``, COLOR stored with the image factored out. Principled Alpha (a
constant, or an Image Texture's Alpha output) and Transparent BSDF make the surface a
cut-out.

Every node the exporter cannot express is reported once per material, by material and
node name: a linked input falls back to its socket's own value, an unknown shader node
makes the material grey diffuse; approximations (linked Normal inputs, values clamped,
an IOR <= 0, subsurface, thin film) are one line each. A material whose output has only a
Volume is left out of the render (``volume_only``; export.py drops its faces). Never an
exception. ``docs/export.md`` has the tables.
"""

from __future__ import annotations

import numpy as np

from . import compat
from .export_images import DEFAULT_GREY, ImageTable  # noqa: F401  (ImageTable re-exported)
from .export_nodes import Closure, NodeReader, UnreadableTree, diffuse_closure, \
    follow_reroutes, kept_row
from .export_shaders import HANDLERS as BSDF_HANDLERS
from .export_shader import AttributeNames, UVMapNames, compile_sockets, mix_weight, \
    nested_opacity, opacity_product, weighted_sum
from ..core.scene import closures as cl
from ..core.shading import program as pg


def default_row(name="(default grey)") -> dict:
    """The row of an empty slot or an unreadable tree: grey diffuse, as Cycles renders it."""
    return diffuse_closure(np.full(3, DEFAULT_GREY)).as_row(name)


class TreeReader(NodeReader):
    """Walks one node tree from an output's shader socket to closures."""

    def shader_input(self, sock) -> Closure:
        """The closure arriving at a shader socket; unlinked = no closure (black)."""
        linked = follow_reroutes(sock) if sock.is_linked else None
        if linked is None:
            return Closure()
        return self.closure(linked.node)

    def closure(self, node) -> Closure:
        handler = _HANDLERS.get(node.bl_idname)
        if handler is None:
            raise UnreadableTree(f"unsupported node '{node.name}' ({node.bl_idname})")
        if getattr(node, "mute", False):
            raise UnreadableTree(f"muted node '{node.name}'")
        c = handler(self, node)
        for b in c.bsdfs:  # which node's inputs a closure row holds (shader programs)
            b.setdefault("node", node)
        return c

    def transparent(self, node) -> Closure:
        """Transparent BSDF: a straight pass-through (cut-out) weighted by its colour's mean."""
        return Closure(transparency=float(np.clip(np.mean(self.color(node, "Color")), 0.0, 1.0)))

    def emission(self, node) -> Closure:
        # Background (world) and Emission share the colour x strength radiance.
        return Closure(emission=self.color(node, "Color") * max(self.scalar(node, "Strength"), 0.0),
                       emitters=[{"node": node, "color": "Color", "strength": "Strength",
                                  "weight": 1.0}])

    def mix(self, node) -> Closure:
        shaders = [s for s in node.inputs if s.type == 'SHADER']
        if len(shaders) != 2:
            raise UnreadableTree(f"mix node '{node.name}' without two shader inputs")
        a, b = self.shader_input(shaders[0]), self.shader_input(shaders[1])
        sock = compat.input_socket(node, "Factor", "Fac")
        linked = follow_reroutes(sock) if sock is not None and sock.is_linked else None
        if self.linked is not None and linked is not None and linked.node.bl_idname not in (
                "ShaderNodeRGB", "ShaderNodeValue"):
            # A node graph into the factor of a mix with a Transparent BSDF: a cut-out
            # whose opacity a program computes; the other shader at full weight (the
            # core divides what a hit sees by the opacity).
            for first, clear, other in ((True, a, b), (False, b, a)):
                if _pure_transparent(clear):
                    self.linked.append((node, sock))
                    cut = {"node": node, "socket": sock, "take": first}  # other's share
                    other.bsdfs = [dict(b, cuts=b.get("cuts", []) + [cut])
                                   for b in other.bsdfs]
                    other.emitters = [dict(e, cuts=e.get("cuts", []) + [cut])
                                      for e in other.emitters]
                    other.cutouts = other.cutouts + [{
                        "node": node, "socket": sock.name, "weight": 1.0,
                        "kind": "mix_a" if first else "mix_b", "mean": clear.transparency}]
                    return other
            # A node graph into the factor: each closure's weight gets fac or 1 - fac
            # per hit (the program's TARGET_WEIGHT, ``_program``); the legacy lobes take
            # the socket's own value, as before.
            value = float(np.clip(np.nan_to_num(float(getattr(sock, "default_value", 0.5))),
                                  0.0, 1.0))
            self._check_textures(node, a, b)
            return a.factored(node, sock, False, 1.0 - value).plus(
                b.factored(node, sock, True, value))
        fac = self.ranged(node, "Factor")
        self._check_textures(node, a, b)
        return a.scaled(1.0 - fac).plus(b.scaled(fac))

    def add(self, node) -> Closure:
        total = Closure()
        for s in (s for s in node.inputs if s.type == 'SHADER'):
            c = self.shader_input(s)
            self._check_textures(node, total, c)
            total = total.plus(c)
        return total

    def _check_textures(self, node, a: Closure, b: Closure):
        """The legacy lobes have one image per material on the whole diffuse lobe: say
        so when a mix combines a textured diffuse with another diffuse."""
        ta, tb = a.diffuse_texture, b.diffuse_texture
        if (ta >= 0 or tb >= 0) and (ta != tb) and a.diffuse.any() and b.diffuse.any():
            self.note(f'Material "{self.material}": node "{node.name}" mixes diffuse shaders '
                      f'with different base colour images; the material\'s whole diffuse '
                      f'lobe uses one image')


def _pure_transparent(c: Closure) -> bool:
    """The closure is only a Transparent BSDF (no BSDF, no emission, no cut-out)."""
    return (c.transparency > 0 and not c.bsdfs and not c.emitters and not c.cutouts
            and not np.any(c.emission > 0) and not np.any(c.diffuse > 0))


_HANDLERS = dict(BSDF_HANDLERS) | {
    "ShaderNodeEmission": TreeReader.emission,
    "ShaderNodeBackground": TreeReader.emission,
    "ShaderNodeMixShader": TreeReader.mix,
    "ShaderNodeAddShader": TreeReader.add,
    "ShaderNodeBsdfTransparent": TreeReader.transparent,
}


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
    ``reader`` (a TreeReader) collects the details when given.

    Raises UnreadableTree when the tree has no usable output or an unsupported node.
    """
    output = _active_output(tree, output_idnames)
    if output is None:
        raise UnreadableTree("no active output node")
    reader = reader or TreeReader()
    return reader.shader_input(output.inputs["Surface"]), reader.approximated


def _linked(sock) -> bool:
    return sock is not None and sock.is_linked and follow_reroutes(sock) is not None


def volume_only(mat) -> bool:
    """True when Cycles would render ``mat`` as a volume without a surface: its active
    Material Output has a Volume link and no Surface link."""
    tree = compat.node_tree(mat) if mat is not None else None
    output = _active_output(tree, ("ShaderNodeOutputMaterial",)) if tree is not None else None
    if output is None:
        return False
    return _linked(output.inputs.get("Volume")) and not _linked(output.inputs.get("Surface"))


def read_material(mat, warnings: list[str], images: "ImageTable | None" = None,
                  program_images=None, attributes=None, view=None,
                  tangent_maps=None, uv_maps=None) -> dict:
    """One material -> a row for ``Materials.from_list`` (closures and legacy lobes);
    appends one warning per node it cannot express (by material and node name) and one
    per other approximation.

    images: the export's ImageTable (Image Texture nodes become textures); None reports
    them as unsupported like any other node. program_images: the export's
    ``export_images.ProgramImageTable`` (Image Texture nodes inside shader programs);
    None: such a node gives the missing-image magenta, reported. attributes: the export's
    ``export_shader.AttributeNames`` (the mesh attributes programs read); tangent_maps
    likewise, the UV maps whose MikkTSpace tangents they read (Normal Map nodes). view:
    the render camera (``export_camera.CameraView``) for Texture Coordinate Camera / Window.
    uv_maps: the export's ``export_shader.UVMapNames`` (the UV maps programs name).
    Without a node tree (legacy materials),
    Cycles renders ``diffuse_color`` as diffuse.
    """
    name = mat.name
    tree = compat.node_tree(mat)
    if tree is None:
        return diffuse_closure(np.clip(np.asarray(mat.diffuse_color[:3], np.float64),
                                       0.0, 1.0)).as_row(name)
    reader = TreeReader(images, name)
    reader.linked = []
    reader.program_images = program_images is not None
    try:
        closure, _ = read_surface(tree, ("ShaderNodeOutputMaterial",), reader)
    except UnreadableTree as exc:
        warnings.append(f'Material "{name}": cannot read its node tree ({exc}); '
                        f"rendering it as grey diffuse")
        return default_row(name)
    program = _program(mat, closure, reader, warnings, program_images, attributes,
                       view=view, tangent_maps=tangent_maps, uv_maps=uv_maps)
    for node_name, (idname, uses) in reader.unsupported.items():
        warnings.append(f'Material "{name}": node "{node_name}" ({idname}) is not supported; '
                        f"using the socket value of " + ", ".join(uses))
    warnings.extend(reader.notes)
    output = _active_output(tree, ("ShaderNodeOutputMaterial",))
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
    row["program"] = program
    row["pass_index"] = float(getattr(mat, "pass_index", 0))  # Object Info Material Index
    settings = getattr(mat, "photon_map", None)  # None: the extension's properties absent
    if settings is not None and settings.dispersion != 0.0:
        row["dispersion"] = float(settings.dispersion)
    return row


def _slot(node, sock):
    """The closure parameter slot of a BSDF node's input socket, or None."""
    if node.bl_idname == "ShaderNodeBsdfMetallic":
        special = {"IOR": cl.METAL_N, "Extinction": cl.METAL_K}
        if sock.name in special:
            return special[sock.name]
    if node.bl_idname == "ShaderNodeBsdfSheen" and sock.name == "Roughness":
        return cl.ROUGHNESS
    return PROGRAM_SLOTS.get(sock.name)


PROGRAM_SLOTS = {
    "Base Color": cl.COLOR, "Color": cl.COLOR, "Roughness": cl.ROUGHNESS,
    "Metallic": cl.METALLIC, "IOR": cl.IOR, "Specular IOR Level": cl.SPECULAR_LEVEL,
    "Specular Tint": cl.SPECULAR_TINT, "Edge Tint": cl.SPECULAR_TINT,
    "Transmission Weight": cl.TRANSMISSION, "Coat Weight": cl.COAT_WEIGHT,
    "Coat Roughness": cl.COAT_ROUGHNESS, "Coat IOR": cl.COAT_IOR, "Coat Tint": cl.COAT_TINT,
    "Sheen Weight": cl.SHEEN_WEIGHT, "Sheen Roughness": cl.SHEEN_ROUGHNESS,
    "Sheen Tint": cl.SHEEN_TINT, "Anisotropic": cl.ANISOTROPIC, "Anisotropy": cl.ANISOTROPIC,
    "Anisotropic Rotation": cl.ANISOTROPIC_ROTATION, "Rotation": cl.ANISOTROPIC_ROTATION,
    "Diffuse Roughness": cl.DIFFUSE_ROUGHNESS, "Tangent": cl.TANGENT,
    "Coat Normal": cl.COAT_NORMAL,
}
"""BSDF input socket name -> the closure slot a shader program writes (``_program``)."""


def _may_emit(e) -> bool:
    """An emitter (``Closure.emitters``) whose colour or strength is linked, or whose
    constant colour x strength is not black (a Principled BSDF without emission is one)."""
    color = compat.input_socket(e["node"], e["color"])
    strength = compat.input_socket(e["node"], e["strength"])
    if any(s is not None and s.is_linked for s in (color, strength)):
        return True
    c = np.asarray(color.default_value[:3], np.float64) if color is not None else np.ones(3)
    k = float(strength.default_value) if strength is not None else 1.0
    return bool(np.any(c * k != 0.0))


def _program(mat, closure: Closure, reader: TreeReader, warnings: list[str],
             program_images=None, attributes=None, view=None, tangent_maps=None,
             uv_maps=None):
    """The ShaderProgram of the BSDF inputs fed by node graphs (``reader.linked``), or
    None. Each input becomes a TARGET_CLOSURE output for the closure row its node made (the
    row's index among the rows ``Closure.as_row`` keeps); a graph that folds to a
    constant is written into the row instead. Linked inputs with no slot (a Mix factor,
    emission, alpha) are reported as before: their socket value is used. A linked Normal
    input is the material's shading normal (TARGET_NORMAL): one per material, the first
    BSDF's; another BSDF's different Normal link is reported and takes that one too."""
    kept = [b for b in closure.bsdfs if kept_row(b)]
    index = {}
    for i, b in enumerate(kept):
        if "node" in b:
            index.setdefault(b["node"].as_pointer(), []).append(i)
    targets, rows, seen = [], [], set()
    normal = None
    emitting = {(e["node"].as_pointer(), name) for e in closure.emitters
                for name in (e["color"], e["strength"])}
    # An emitter under a linked Mix factor: the emission is the program's.
    emission_linked = any(e.get("factors") for e in closure.emitters)
    cutting = {(e["node"].as_pointer(), e["socket"]) for e in closure.cutouts}
    for node, sock in reader.linked:
        key = (node.as_pointer(), sock.as_pointer())
        slot = _slot(node, sock)
        if key in seen:
            continue
        seen.add(key)
        if sock.name == "Normal":
            source = follow_reroutes(sock)
            if normal is None:
                normal = source
                targets.append((sock, pg.TARGET_NORMAL, 0, 0))
                rows.append("normal")
            elif (source.node.name, source.identifier) != (normal.node.name,
                                                           normal.identifier):
                warnings.append(f'Material "{mat.name}": node "{node.name}" has a Normal '
                                f'of its own; one shading normal per material is supported, '
                                f'the first BSDF\'s ("{normal.node.name}") is used')
            continue
        if (node.as_pointer(), sock.name) in emitting:
            emission_linked = True
            continue
        if (node.as_pointer(), sock.name) in cutting:
            continue
        if slot is None or node.as_pointer() not in index:
            linked = follow_reroutes(sock)
            reader.unsupported_node(linked.node, f'input "{sock.name}" of node "{node.name}"')
            continue
        for i in index[node.as_pointer()]:
            targets.append((sock, pg.TARGET_CLOSURE, i, slot))
            rows.append(kept[i])
    cutouts = [e for e in closure.cutouts if e["weight"] > 0 or e.get("factors")]
    emitting = [e for e in closure.emitters if (e["weight"] > 0 or e.get("factors"))
                and _may_emit(e)]
    # nested: a cut-out under a Mix (its weight not 1, or linked factors above it), or
    # a row / emitter outside some cut-out (beside it under an Add)
    nested = cutouts if cutouts and (
        any(abs(e["weight"] - 1.0) > 1e-9 or e.get("factors") for e in cutouts)
        or any(len(b.get("cuts", [])) < len(cutouts) for b in kept + emitting)) else []
    if nested and emitting:
        # an emitter beside a nested cut-out: its emission is not divided by the opacity
        for e in cutouts:
            reader.unsupported_node(e["node"], f'input "{e["socket"]}" of node '
                                    f'"{e["node"].name}" under another Mix or Add Shader '
                                    f'in a material that emits (a programmed cut-out '
                                    f'there must be the whole material)')
        cutouts = nested = []
    opacity_terms = None
    if nested:
        # A cut-out under another Mix / Add (issue 14): the opacity is 1 - the sum of
        # the cut-outs' transparent shares, each times the factors above it, over the
        # material's constant opacity (which ``Closure.as_row`` divides the rows by and
        # the core multiplies the program's by); every row's per-hit weight is its
        # factors times its share inside the cut-outs it is in (``cuts``) over that
        # opacity, so a hit that picks the surface (probability opacity) sees the
        # closures' own weights on average, as Cycles' Transparent BSDF mix.
        base = float(np.clip(1.0 - closure.transparency, 0.0, 1.0))
        opacity_terms = [(compat.input_socket(e["node"], e["socket"]), e["kind"],
                          e.get("mean", 1.0), e["weight"] / base if base > 0 else 0.0,
                          [(f["socket"], f["take"]) for f in e.get("factors", [])])
                         for e in cutouts]
    for i, b in enumerate(kept):
        if nested:
            factors = [(f["socket"], f["take"]) for f in b.get("factors", [])
                       + b.get("cuts", [])]
            targets.append((mix_weight(factors, opacity_terms), pg.TARGET_WEIGHT, i, 0))
            rows.append(("weight", b))
        elif b.get("factors"):  # its weight's linked Mix factors, per hit (TARGET_WEIGHT)
            targets.append((mix_weight([(f["socket"], f["take"]) for f in b["factors"]]),
                            pg.TARGET_WEIGHT, i, 0))
            rows.append(("weight", b))
    if emission_linked:
        # The whole emission (every emitting node, weighted by the Mix / Add factors
        # above it, over the opacity as ``Closure.as_row`` divides it) becomes the
        # program's TARGET_EMISSION, replacing the material's constant emission.
        opacity = float(np.clip(1.0 - closure.transparency, 0.0, 1.0))
        k = 1.0 / opacity if 0.0 < opacity < 1.0 else 1.0
        terms = [(compat.input_socket(e["node"], e["color"]),
                  compat.input_socket(e["node"], e["strength"]), e["weight"] * k,
                  [(f["socket"], f["take"]) for f in e.get("factors", [])])
                 for e in closure.emitters if e["weight"] > 0]
        targets.append((weighted_sum(terms), pg.TARGET_EMISSION, 0, 0))
        rows.append(None)
    if nested:
        targets.append((nested_opacity(opacity_terms), pg.TARGET_ALPHA, 0, 0))
        rows.append("alpha")
    elif cutouts:
        terms = [(compat.input_socket(e["node"], e["socket"]), e["kind"], e.get("mean", 1.0))
                 for e in cutouts]
        targets.append((opacity_product(terms), pg.TARGET_ALPHA, 0, 0))
        rows.append("alpha")
    if not targets:
        return None
    compiled = compile_sockets(mat, targets, images=program_images,
                               attributes=AttributeNames() if attributes is None else attributes,
                               view=view, tangent_maps=tangent_maps,
                               uv_maps=UVMapNames() if uv_maps is None else uv_maps)
    warnings.extend(compiled.warnings)
    for (sock, _, _, slot), b, value in zip(targets, rows, compiled.constant):
        if isinstance(b, str) and b == "normal":
            continue  # the shading normal: a constant one is not a closure parameter
        if isinstance(b, tuple):  # a closure's Mix factors: the program applies them
            if value is not None and compiled.program is None:  # unless none is left
                b[1]["weight"] = b[1]["weight"] * float(np.clip(value[0], 0.0, 1.0))
            continue
        if value is not None and isinstance(b, str):  # a folded opacity: the constant form
            a = float(np.clip(value[0], 0.0, 1.0))
            for lobe in ("diffuse", "specular", "transmission", "emission"):
                setattr(closure, lobe, getattr(closure, lobe) * a)
            closure.glossy_weight *= a
            for row in closure.bsdfs:
                row["weight"] = row["weight"] * a
            closure.transparency = 1.0 - (1.0 - closure.transparency) * a
        elif value is not None and b is None:  # a folded emission: the constant is exact
            closure.emission = np.maximum(np.asarray(value, np.float64), 0.0) / k
        elif value is not None:  # folded: the constant is the closure's own parameter
            b["params"][slot:slot + len(value)] = value
    return compiled.program


def read_world(world, warnings: list[str]) -> np.ndarray:
    """World -> background radiance (3,) float64, W/(m^2 sr); black when there is none.

    Follows the World Output's Surface (Background: colour x strength); a tree that
    cannot be read falls back to ``world.color`` with a warning.
    """
    if world is None:
        return np.zeros(3)
    tree = compat.node_tree(world)
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

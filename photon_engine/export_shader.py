"""The shader compiler: a material's node graph, from the sockets its closures read, into a
``core.shading.program.ShaderProgram`` (docs/shading.md).

``compile_sockets(material, targets, ...)`` follows each target socket's links
backwards: Reroutes, muted nodes (their internal links), node groups recursively (a
group node's inputs bind the inner Group Input's outputs; the inner active Group Output
gives its outputs; unlinked inner sockets keep the inner defaults), in topological order
(a value is compiled once per group instance, before its users). Nodes outside
``SUPPORTED`` are reported once by material and node name and their outputs take the
sockets' default values; a node cycle is reported and broken the same way. Never raises on
a node graph.

Then the constant subgraphs are folded: instructions reading only constants run once (in
the core interpreter, at one dummy point) and their results become constants. A target
whose value folds to a constant costs one register read; when every target is constant,
no program is made (``ShaderCompile.program`` is None and ``constant`` holds the values).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.shading import program as pg
from ..core.shading import light_path
from ..core.shading import converters as cn
from ..core.shading import color as cc
from ..core.shading import textures as ct
from ..core.shading.interpreter import evaluate
from ..core.shading.inputs import ShadingInputs
from ..core.shading.noise import NOISE_TYPES
from ..core.shading.voronoi import FEATURES, METRICS
from ..core.shading import images as ci
from . import compat
from .export_images import is_raw_space

RAMP_TABLE_SIZE = 256
"""Rows per baked ColorRamp (Cycles' RAMP_TABLE_SIZE)."""


@dataclass
class ShaderCompile:
    """program: the ShaderProgram, or None when every target is constant. constant: one
    tuple of floats per target (its value when constant, else None). warnings: messages
    naming the material and node."""
    program: pg.ShaderProgram | None
    constant: list
    warnings: list = field(default_factory=list)


class AttributeNames:
    """The mesh attribute names the programs of one export read, in the order of
    ``Mesh.attributes`` / ``ShadingInputs.attributes`` ("" = the render colour
    attribute). ``index(name)`` adds a name on first use."""

    def __init__(self, names=()):
        self.names: list[str] = list(names)
        self.layer = ()  # the IDs a View Layer attribute is looked up in (view layer, scene)

    def index(self, name: str) -> int:
        if name not in self.names:
            self.names.append(name)
        return self.names.index(name)


OBJECT_ATTRIBUTE = "@object/"
INSTANCER_ATTRIBUTE = "@instancer/"
"""Prefixes of the ``AttributeNames`` of the Attribute node's Object and Instancer types:
a per-object value (``rna_attribute``) that export.py writes at every corner of the
object's triangles (``Mesh.attributes``), so the core reads it like a mesh attribute."""
PARAMETRIC_ATTRIBUTE = "@parametric"
"""The Geometry node's Parametric output as a corner attribute (``export.read_attributes``
writes (1, 0, 0), (0, 1, 0), (0, 0, 0) at each triangle's corners): interpolated over the
triangle it is Cycles' (1 - u - v, u, 0) of the hit's barycentrics."""
POINTINESS_ATTRIBUTE = "@pointiness"
"""The Geometry node's Pointiness as a point attribute (``export.pointiness``)."""


def rna_attribute(ids, name: str):
    """(4,) float32 RGBA of the Attribute node's Object / Instancer / View Layer types, as
    Cycles' lookup_property / lookup_instance_property: in each ID of ``ids`` in turn
    (None skipped), the custom property ``["name"]`` then the RNA path ``name``; a float
    or int is (v, v, v, 1), a float array of at most 4 fills (0, 0, 0, 1); anything else
    (a bool, a string, an int array) is not found. None when no ID has it (Cycles: 0)."""
    for id_ in ids:
        if id_ is None:
            continue
        for path in (f'["{name}"]', name):
            try:
                value = id_.path_resolve(path)
            except (ValueError, TypeError):
                continue
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                return np.array([value, value, value, 1.0], np.float32)
            try:
                items = [] if isinstance(value, str) else list(value)
            except TypeError:
                items = []
            if 0 < len(items) <= 4 and all(isinstance(v, float) for v in items):
                out = np.array([0.0, 0.0, 0.0, 1.0], np.float32)
                out[:len(items)] = items
                return out
    return None


class UVMapNames:
    """The UV map names the programs of one export read, in the order of ``Mesh.uv_maps``
    (``ShadingInputs.uv`` is [active render map, ``names``...]). ``index(name)`` is the
    map's index in ``ShadingInputs.uv``: 0 for "" (the active render map: Texture
    Coordinate UV, an unlinked Image Texture Vector), 1 + j for ``names[j]``, adding a
    name on first use; ``readers[name]`` the materials that read it (for the warning
    where a mesh lacks the map)."""

    def __init__(self, names=()):
        self.names: list[str] = [n for n in names if n]
        self.readers: dict[str, list[str]] = {}

    def index(self, name: str, material: str = "") -> int:
        if not name:
            return 0
        if name not in self.names:
            self.names.append(name)
        readers = self.readers.setdefault(name, [])
        if material and material not in readers:
            readers.append(material)
        return 1 + self.names.index(name)


class _Value:
    """An operand: a virtual register of width 1 ('f') or 3 ('v' vector, 'c' colour)."""
    __slots__ = ("vreg", "kind")

    def __init__(self, vreg, kind):
        self.vreg = vreg
        self.kind = kind


class _Builder:
    def __init__(self, name, uv_maps, attributes, luminance, warnings, images=None,
                 tangent_maps=None):
        self.name = name
        self.tangent_maps = tangent_maps if isinstance(tangent_maps, AttributeNames) else \
            AttributeNames(tangent_maps or ())
        self.images = images
        self.uv_maps = uv_maps if isinstance(uv_maps, UVMapNames) else UVMapNames(uv_maps)
        self.attributes = attributes if isinstance(attributes, AttributeNames) else \
            AttributeNames(attributes)
        self.luminance = tuple(float(x) for x in luminance)
        self.warnings = warnings
        self.reported = set()
        self.vregs = []       # [width, constant tuple or None]
        self.code = []        # [op, ints, [vreg operands]]
        self.tables = []
        self.memo = {}
        self.visiting = set()
        self.bump = (0, 0.0)  # (offset axis, filter width) while compiling a Bump's Height

    # --- registers -------------------------------------------------------------------
    def const(self, values, kind):
        values = tuple(float(v) for v in np.atleast_1d(values))
        self.vregs.append([len(values), values])
        return _Value(len(self.vregs) - 1, kind)

    def new(self, kind):
        self.vregs.append([1 if kind == "f" else 3, None])
        return _Value(len(self.vregs) - 1, kind)

    def emit(self, op, ints, operands, outs):
        self.code.append([op, list(ints), [v.vreg for v in operands + outs]])
        return outs

    def warn(self, key, message):
        if key not in self.reported:
            self.reported.add(key)
            self.warnings.append(f"Material '{self.name}': {message}")

    # --- conversions -----------------------------------------------------------------
    def as_kind(self, value, kind):
        if value.kind == kind or (value.kind != "f" and kind != "f"):
            return value if value.kind == kind else _Value(value.vreg, kind)
        if kind == "f":  # colour -> luminance, vector -> average (Cycles' conversions)
            w = self.luminance if value.kind == "c" else (1 / 3, 1 / 3, 1 / 3)
            out = self.new("f")
            if value.kind == "c":
                return self.emit(pg.OP_RGB_TO_BW, [], [value, self.const(w, "v")], [out])[0]
            junk = self.new("v")
            zero = self.const((0, 0, 0), "v")
            self.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS["DOT_PRODUCT"]],
                      [value, self.const(w, "v"), zero, self.const(0, "f")], [junk, out])
            return out
        out = self.new(kind)
        return self.emit(pg.OP_COMBINE, [0], [value, value, value], [out])[0]

    def default(self, socket):
        kind = _socket_kind(socket)
        if kind is None or not hasattr(socket, "default_value"):
            return self.const((0, 0, 0), "c") if kind != "f" else self.const(0, "f")
        v = socket.default_value
        if kind == "f":
            return self.const(float(v), "f")
        return self.const(tuple(v)[:3], kind)

    # --- graph walk ------------------------------------------------------------------
    def input(self, node, key, path, kind=None):
        """The value of input ``key`` (name, identifier or index) of ``node``."""
        sock = _find_input(node, key)
        if sock is None:  # not declared for this mode (5.x drops unavailable sockets)
            k = kind or "f"
            return self.const(0.0 if k == "f" else (0.0, 0.0, 0.0), k)
        value = self.socket_value(sock, path)
        return self.as_kind(value, kind or _socket_kind(sock) or "f")

    def socket_value(self, sock, path):
        links = [lk for lk in sock.links if not getattr(lk, "is_muted", False)]
        if not links:
            return self.default(sock)
        link = links[0]
        return self.output_value(link.from_node, link.from_socket, path)

    def output_value(self, node, out_sock, path):
        key = (path, node.name, out_sock.identifier)
        if key in self.memo:
            return self.memo[key]
        if (path, node.name) in self.visiting:
            self.warn(("cycle", path, node.name),
                      f"node cycle through '{node.name}': its output takes the default value")
            return self.default(out_sock)
        self.visiting.add((path, node.name))
        try:
            value = self.node_output(node, out_sock, path)
        finally:
            self.visiting.discard((path, node.name))
        if value is None:
            value = self.default(out_sock)
        self.memo[key] = value
        return value

    def node_output(self, node, out_sock, path):
        idname = node.bl_idname
        if idname == "NodeReroute":
            return self.socket_value(node.inputs[0], path)
        if getattr(node, "mute", False):
            for lk in getattr(node, "internal_links", ()):
                if lk.to_socket.identifier == out_sock.identifier:
                    return self.as_kind(self.socket_value(lk.from_socket, path),
                                        _socket_kind(out_sock) or "f")
            return self.default(out_sock)
        if idname == "ShaderNodeGroup":
            return self.group_output(node, out_sock, path)
        if idname == "NodeGroupInput":
            return self.group_input(out_sock, path)
        handler = SUPPORTED.get(idname)
        if handler is None:
            self.warn(("node", path, node.name),
                      f"node '{node.name}' ({idname}) is not supported: its output takes "
                      f"the socket's default value")
            return self.default(out_sock)
        outs = handler(self, node, path)
        index = list(node.outputs).index(out_sock) if out_sock in list(node.outputs) else -1
        if isinstance(outs, dict):
            value = outs.get(out_sock.identifier, outs.get(out_sock.name))
        else:
            value = outs[index] if 0 <= index < len(outs) else None
        if value is None:
            self.warn(("output", path, node.name, out_sock.name),
                      f"output '{out_sock.name}' of node '{node.name}' is not supported: it "
                      f"takes its default value")
            return self.default(out_sock)
        # later outputs of the same node reuse this evaluation
        if not isinstance(outs, dict):
            for i, v in enumerate(outs):
                if v is not None and i < len(node.outputs):
                    self.memo[(path, node.name, node.outputs[i].identifier)] = v
        return value

    def group_output(self, node, out_sock, path):
        tree = node.node_tree
        if tree is None:
            return self.default(out_sock)
        inner = (path + (node.name,))
        self.group_bindings[inner] = (node, path)
        outputs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
        active = next((n for n in outputs if getattr(n, "is_active_output", False)),
                      outputs[0] if outputs else None)
        if active is None:
            return self.default(out_sock)
        sock = next((s for s in active.inputs if s.identifier == out_sock.identifier), None)
        if sock is None:
            return self.default(out_sock)
        return self.as_kind(self.socket_value(sock, inner), _socket_kind(out_sock) or "f")

    def group_input(self, out_sock, path):
        mark = ()
        if path and path[-1] in _BUMP_MARKS:  # a Bump's Height offset at this group level
            path, mark = path[:-1], path[-1:]
        node, outer = self.group_bindings.get(path, (None, None))
        if node is None:
            return self.default(out_sock)
        sock = next((s for s in node.inputs if s.identifier == out_sock.identifier), None)
        if sock is None:
            return self.default(out_sock)
        return self.as_kind(self.socket_value(sock, outer + mark),
                            _socket_kind(out_sock) or "f")

    # --- inputs ----------------------------------------------------------------------
    def source(self, src, index=0, kind="v"):
        """Input ``src`` at the point, or at the bump offset being compiled
        (``self.bump``: (axis 1 or 2, filter width) inside a Bump node's Height)."""
        axis, width = self.bump
        key = ("source", src, index, axis, width)
        if key not in self.memo:
            out = self.new("v")
            self.emit(pg.OP_INPUT, [src, index, axis,
                                    int(round(width / pg.BUMP_WIDTH_UNIT)) if axis else 0],
                      [], [out])
            self.memo[key] = out
        v = self.memo[key]
        return _Value(v.vreg, kind)

    def texture_vector(self, node, path):
        """A texture's Vector input; unlinked: the Generated coordinates (as Cycles)."""
        sock = _find_input(node, "Vector")
        if sock is None or not sock.links:
            return self.source(pg.SOURCE_GENERATED)
        return self.as_kind(self.socket_value(sock, path), "v")

    # --- folding and layout ----------------------------------------------------------
    def finish(self, targets):
        """(program or None, constants per target) for target values [(value, rows)]."""
        # Fold: run the instructions whose operands are all constant.
        const_code, live = [], []
        for op, ints, regs in self.code:
            sig = pg.SIGNATURES[op]
            n_in = len(sig.split(">")[0])
            if op not in _NOT_FOLDED and all(self.vregs[r][1] is not None for r in regs[:n_in]):
                const_code.append((op, ints, regs))
            else:
                live.append((op, ints, regs))
            if const_code and const_code[-1][2] is regs:
                self._fold(const_code[-1])
        self.code = live
        # Keep only what the targets need (folded nodes leave dead code behind).
        needed = {v.vreg for v, _ in targets}
        kept = []
        for op, ints, regs in reversed(self.code):
            n_in = len(pg.SIGNATURES[op].split(">")[0])
            if any(r in needed for r in regs[n_in:]):
                kept.append((op, ints, regs))
                needed.update(regs[:n_in])
        kept.reverse()
        for op, ints, regs in kept:  # Noise: the two colour fractals only when read
            if op == pg.OP_NOISE:
                ints[3] = int(regs[-1] in needed)
        constant = [self.vregs[v.vreg][1] for v, _ in targets]
        if not kept:
            return None, constant
        # Layout: the constants the program reads first, then the computed registers.
        used = set(needed) | {r for _, _, regs in kept for r in regs}
        address, consts, n = {}, [], 0
        for r in sorted(used):
            if self.vregs[r][1] is not None:
                address[r] = n
                consts.extend(self.vregs[r][1])
                n += self.vregs[r][0]
        for r in sorted(used):
            if r not in address:
                address[r] = n
                n += self.vregs[r][0]
        rows = []
        for op, ints, regs in kept:
            row = [op] + list(ints) + [0] * (4 - len(ints)) + [address[r] for r in regs]
            rows.append(row + [-1] * (pg.INSTRUCTION_WIDTH - len(row)))
        outputs = []
        for value, trows in targets:
            for c, (target, closure, slot) in enumerate(trows):
                outputs.append([address[value.vreg] + c, target, closure, slot])
        prog = pg.ShaderProgram.build(rows, consts, outputs, n,
                                      tables=np.array(self.tables, np.float32).reshape(-1, 4),
                                      name=self.name)
        return prog, [None if self.vregs[v.vreg][1] is None else self.vregs[v.vreg][1]
                      for v, _ in targets]

    def _fold(self, instruction):
        """Evaluate one constant instruction and turn its outputs into constants."""
        op, ints, regs = instruction
        n_in = len(pg.SIGNATURES[op].split(">")[0])
        address, consts, n = {}, [], 0
        for r in regs[:n_in]:
            if r not in address:
                address[r] = n
                consts.extend(self.vregs[r][1])
                n += self.vregs[r][0]
        for r in regs[n_in:]:
            address[r] = n
            n += self.vregs[r][0]
        row = [op] + list(ints) + [0] * (4 - len(ints)) + [address[r] for r in regs]
        row += [-1] * (pg.INSTRUCTION_WIDTH - len(row))
        outs = [[address[r] + c, pg.TARGET_EMISSION, 0, 0] for r in regs[n_in:]
                for c in range(self.vregs[r][0])]
        prog = pg.ShaderProgram.build([row], consts, outs, n,
                                      tables=np.array(self.tables, np.float32).reshape(-1, 4),
                                      name=self.name)
        one = ShadingInputs.build(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))
        values = evaluate(prog, one)[0]
        i = 0
        for r in regs[n_in:]:
            w = self.vregs[r][0]
            self.vregs[r][1] = tuple(float(x) for x in values[i:i + w])
            i += w


_NOT_FOLDED = (pg.OP_INPUT, pg.OP_IMAGE, pg.OP_IMAGE_PROJECTED)
"""Instructions never run at export time (per-point inputs; images live in the scene)."""
_BUMP_MARKS = ("@bump dx", "@bump dy")
"""Path elements under which a Bump node's Height subgraph is compiled again, its inputs
read at P + w dPdx and P + w dPdy (``_bump``)."""


def _socket_kind(sock):
    t = getattr(sock, "type", "VALUE")
    if t in ("VALUE", "INT", "BOOLEAN"):
        return "f"
    if t == "VECTOR":
        return "v"
    if t == "RGBA":
        return "c"
    return None


def _find_input(node, key):
    if isinstance(key, int):
        enabled = list(node.inputs)
        return enabled[key] if key < len(enabled) else None
    for s in node.inputs:
        if s.identifier == key and getattr(s, "enabled", True):
            return s
    for s in node.inputs:
        if s.name == key and getattr(s, "enabled", True):
            return s
    return node.inputs.get(key)


# --- node handlers: (builder, node, path) -> [output values by index] or {identifier: value}

def _transform(b, point, matrix, projective=False):
    """OP_TRANSFORM of vector value ``point`` by the constant (4, 4) ``matrix`` (rows)."""
    m = np.asarray(matrix, np.float64)
    rows = []
    for i in range(4):
        rows += [b.const(m[i, :3], "v"), b.const(m[i, 3], "f")]
    out = b.new("v")
    b.emit(pg.OP_TRANSFORM, [int(projective)], [point] + rows, [out])
    return out


def _tex_coord(b, node, path):
    """Texture Coordinate (Cycles' svm_node_tex_coord). Camera and Window read the render
    camera (``b.view``: export_camera.CameraView); Object with the node's ``object``
    set is that object's inverse world matrix at the point, as Cycles."""
    position = b.source(pg.SOURCE_POSITION)
    other = getattr(node, "object", None)
    if other is not None:
        obj = _transform(b, position, np.linalg.inv(np.array(other.matrix_world, np.float64)))
    else:
        obj = b.source(pg.SOURCE_OBJECT)
    outs = {"Generated": b.source(pg.SOURCE_GENERATED),
            "Normal": b.source(pg.SOURCE_OBJECT_NORMAL), "UV": b.source(pg.SOURCE_UV, 0),
            "Object": obj}
    for name in ("Camera", "Window"):
        if not node.outputs[name].is_linked:
            continue
        if b.view is None:
            b.warn(("view", path, node.name), f"node '{node.name}': no scene camera for "
                   f"its {name} output, which takes its default value")
            continue
        outs[name] = _transform(b, position, b.view.world_to_camera) if name == "Camera" \
            else _transform(b, position, b.view.world_to_ndc, projective=True)
    if node.outputs["Reflection"].is_linked:  # 2 dot(N, I) N - I = -reflect(I, N)
        zero, one = b.const((0, 0, 0), "v"), b.const(1.0, "f")
        mirrored, minus, junk = b.new("v"), b.new("v"), b.new("f")
        b.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS["REFLECT"]],
               [b.source(pg.SOURCE_INCOMING), b.source(pg.SOURCE_NORMAL), zero, one],
               [mirrored, junk])
        b.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS["SCALE"]],
               [mirrored, zero, zero, b.const(-1.0, "f")], [minus, b.new("f")])
        outs["Reflection"] = minus
    return outs


def _view_normal(b, node, path):
    """A Fresnel / Layer Weight Normal input: the linked vector as it is, else the
    shading normal (Cycles' sd->N)."""
    sock = _find_input(node, "Normal")
    if sock is None or not [lk for lk in sock.links if not getattr(lk, "is_muted", False)]:
        return b.source(pg.SOURCE_NORMAL)
    return b.as_kind(b.socket_value(sock, path), "v")


def _fresnel(b, node, path):
    out = b.new("f")
    b.emit(pg.OP_FRESNEL, [], [b.input(node, "IOR", path, "f"), _view_normal(b, node, path),
                               b.source(pg.SOURCE_INCOMING),
                               b.source(pg.SOURCE_BACKFACING, 0, "f")], [out])
    return [out]


def _layer_weight(b, node, path):
    fres, facing = b.new("f"), b.new("f")
    b.emit(pg.OP_LAYER_WEIGHT, [], [b.input(node, "Blend", path, "f"),
                                    _view_normal(b, node, path), b.source(pg.SOURCE_INCOMING),
                                    b.source(pg.SOURCE_BACKFACING, 0, "f")], [fres, facing])
    return {"Fresnel": fres, "Facing": facing}


def _uv_map(b, node, path):
    """UV Map node: the map it names (``Mesh.uv_maps``), or the active render map when
    it names none; a mesh without that map reads (0, 0), reported by ``export``."""
    index = b.uv_maps.index(getattr(node, "uv_map", ""), b.name)
    return {"UV": b.source(pg.SOURCE_UV, index)}


def _tangent_out(b, mode, vector):
    """OP_TANGENT (core/shading/normals.py ``tangent``) of ``vector`` (Generated for the
    radial modes, the UV map's world-space tangent for UV_MAP)."""
    out = b.new("v")
    b.emit(pg.OP_TANGENT, [mode], [vector, *[b.source(pg.SOURCE_NORMAL_TO_WORLD, i)
                                             for i in range(3)],
                                   b.source(pg.SOURCE_NORMAL)], [out])
    return out


def _tangent(b, node, path):
    """Tangent node (Cycles' svm_node_tangent): radial about the object's X / Y / Z axis
    from Generated, or the MikkTSpace tangent of the node's UV map ("" = the active
    render one, as the Normal Map reads it)."""
    if node.direction_type == 'UV_MAP':
        g = b.tangent_maps.index(getattr(node, "uv_map", "") or "")
        return {"Tangent": _tangent_out(b, pg.TANGENT_MODES["UV_MAP"],
                                        b.source(pg.SOURCE_TANGENT, g))}
    return {"Tangent": _tangent_out(b, pg.TANGENT_MODES[node.axis],
                                    b.source(pg.SOURCE_GENERATED))}


def _light_path(b, node, path):
    """Light Path node: each output is a column of ``ShadingInputs.light_path``, filled by
    the caller for the ray that reached the hit (core/shading/light_path.py); an output
    the engine does not track reads 0, reported once per material and output."""
    outs = {name: b.source(pg.SOURCE_LIGHT_PATH, k, "f")
            for k, name in enumerate(light_path.OUTPUTS)}

    def on_read(name):
        if name in light_path.UNANSWERED:
            b.warn(("lightpath", name), f"node '{node.name}': Light Path '{name}' is not "
                   f"tracked by the engine; 0 is used")
    return _ReadOutputs(outs, on_read)


class _ReadOutputs(dict):
    """A handler's outputs that call ``on_read(name)`` when one is read (a warning only
    for the outputs a graph uses)."""

    def __init__(self, values, on_read):
        super().__init__(values)
        self.on_read = on_read

    def get(self, name, default=None):
        if name in self:
            self.on_read(name)
        return super().get(name, default)


def _geometry(b, node, path):
    return {"Position": b.source(pg.SOURCE_POSITION), "Normal": b.source(pg.SOURCE_NORMAL),
            "Tangent": _tangent_out(b, pg.TANGENT_MODES["Z"], b.source(pg.SOURCE_GENERATED)),
            "True Normal": b.source(pg.SOURCE_TRUE_NORMAL),
            "Incoming": b.source(pg.SOURCE_INCOMING),
            "Backfacing": b.source(pg.SOURCE_BACKFACING, 0, "f"),
            "Parametric": _attribute_outputs(b, PARAMETRIC_ATTRIBUTE)["Vector"],
            "Pointiness": _attribute_outputs(b, POINTINESS_ATTRIBUTE)["Fac"]}


def _object_info(b, node, path):
    """Location, Color, Alpha (the object colour's alpha), Random, Object Index
    (``export.object_info`` for the values), Material Index (the material's
    ``pass_index``, ``Materials.pass_index``), as Cycles' svm_node_object_info."""
    return {"Location": b.source(pg.SOURCE_OBJECT_LOCATION),
            "Color": b.source(pg.SOURCE_OBJECT_COLOR, 0, "c"),
            "Alpha": b.source(pg.SOURCE_OBJECT_ALPHA, 0, "f"),
            "Random": b.source(pg.SOURCE_OBJECT_RANDOM, 0, "f"),
            "Object Index": b.source(pg.SOURCE_OBJECT_INDEX, 0, "f"),
            "Material Index": b.source(pg.SOURCE_MATERIAL_INDEX, 0, "f")}


def _attribute_outputs(b, name):
    """Color, Vector, Fac (Cycles: the colour's average), Alpha of attribute ``name``."""
    index = b.attributes.index(name)
    color = b.source(pg.SOURCE_ATTRIBUTE_COLOR, index, "c")
    return {"Color": color, "Vector": _Value(color.vreg, "v"),
            "Fac": b.as_kind(_Value(color.vreg, "v"), "f"),
            "Alpha": b.source(pg.SOURCE_ATTRIBUTE_ALPHA, index, "f")}


def _attribute(b, node, path):
    """Attribute node: Geometry (mesh attributes, ``export.read_attributes``), Object and
    Instancer (per-object values, ``OBJECT_ATTRIBUTE``), View Layer (one value per render,
    a constant: the view layer's then the scene's property, ``rna_attribute``)."""
    kind = getattr(node, "attribute_type", "GEOMETRY")
    name = node.attribute_name
    if kind == "GEOMETRY":
        return _attribute_outputs(b, name)
    if kind in ("OBJECT", "INSTANCER"):
        prefix = OBJECT_ATTRIBUTE if kind == "OBJECT" else INSTANCER_ATTRIBUTE
        return _attribute_outputs(b, prefix + name)
    if kind == "VIEW_LAYER":
        rgba = rna_attribute(b.attributes.layer, name)
        if rgba is None:
            b.warn(("attr", name), f"node '{node.name}': View Layer attribute '{name}' not "
                   f"found on the view layer or the scene; 0 is used, as Cycles")
            rgba = np.zeros(4, np.float32)
        color = b.const(tuple(float(v) for v in rgba[:3]), "c")
        return {"Color": color, "Vector": _Value(color.vreg, "v"),
                "Fac": b.const(float(np.mean(rgba[:3])), "f"),
                "Alpha": b.const(float(rgba[3]), "f")}
    b.warn(("attr", path, node.name), f"node '{node.name}': attribute type '{kind}' is not "
           f"supported; 0 is used")
    return {}


def _color_attribute(b, node, path):
    """Color Attribute node; no name: the mesh's render colour attribute."""
    outs = _attribute_outputs(b, getattr(node, "layer_name", ""))
    return {"Color": outs["Color"], "Alpha": outs["Alpha"]}


def _value(b, node, path):
    return [b.const(float(node.outputs[0].default_value), "f")]


def _rgb(b, node, path):
    return [b.const(tuple(node.outputs[0].default_value)[:3], "c")]


def _math(b, node, path):
    ins = [b.input(node, i, path, "f") for i in range(3)]
    out = b.new("f")
    b.emit(pg.OP_MATH, [cn.MATH_OPS[node.operation], int(node.use_clamp)], ins, [out])
    return [out]


def _vector_math(b, node, path):
    ins = [b.input(node, i, path, "v") for i in ("Vector", "Vector_001", "Vector_002")]
    scale = b.input(node, "Scale", path, "f")
    vec, val = b.new("v"), b.new("f")
    b.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS[node.operation]], ins + [scale], [vec, val])
    return {"Vector": vec, "Value": val}


def _map_range(b, node, path):
    kind = cn.MAP_RANGE_TYPES[node.interpolation_type]
    if node.data_type == "FLOAT_VECTOR":
        names = ("Vector", "From_Min_FLOAT3", "From_Max_FLOAT3", "To_Min_FLOAT3",
                 "To_Max_FLOAT3", "Steps_FLOAT3")
        ins = [b.input(node, n, path, "v") for n in names]
        out = b.new("v")
        b.emit(pg.OP_VECTOR_MAP_RANGE, [kind, int(node.clamp)], ins, [out])
        return {"Vector": out}
    names = ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")
    ins = [b.input(node, n, path, "f") for n in names]
    out = b.new("f")
    b.emit(pg.OP_MAP_RANGE, [kind, int(node.clamp)], ins, [out])
    return {"Result": out}


def _clamp(b, node, path):
    ins = [b.input(node, n, path, "f") for n in ("Value", "Min", "Max")]
    out = b.new("f")
    b.emit(pg.OP_CLAMP, [1 if node.clamp_type == "RANGE" else 0], ins, [out])
    return [out]


def _mix(b, node, path):
    dt = node.data_type
    if dt == "FLOAT":
        ins = [b.input(node, n, path, "f") for n in ("Factor_Float", "A_Float", "B_Float")]
        out = b.new("f")
        b.emit(pg.OP_MIX_FLOAT, [int(node.clamp_factor)], ins, [out])
        return {"Result_Float": out}
    if dt == "VECTOR":
        nonuniform = node.factor_mode == "NON_UNIFORM"
        fac = b.input(node, "Factor_Vector" if nonuniform else "Factor_Float", path,
                      "v" if nonuniform else "f")
        ins = [fac] + [b.input(node, n, path, "v") for n in ("A_Vector", "B_Vector")]
        out = b.new("v")
        b.emit(pg.OP_MIX_VECTOR_NONUNIFORM if nonuniform else pg.OP_MIX_VECTOR,
               [int(node.clamp_factor)], ins, [out])
        return {"Result_Vector": out}
    if dt == "RGBA":
        ins = [b.input(node, "Factor_Float", path, "f")] + \
              [b.input(node, n, path, "c") for n in ("A_Color", "B_Color")]
        out = b.new("c")
        b.emit(pg.OP_MIX_COLOR, [cc.BLEND_TYPES[node.blend_type], int(node.clamp_factor),
                                 int(node.clamp_result)], ins, [out])
        return {"Result_Color": out}
    return {}


def _mix_rgb(b, node, path):
    ins = [b.input(node, "Fac", path, "f")] + [b.input(node, n, path, "c")
                                                for n in ("Color1", "Color2")]
    out = b.new("c")
    b.emit(pg.OP_MIX_COLOR, [cc.BLEND_TYPES[node.blend_type], 1, int(node.use_clamp)], ins,
           [out])
    return [out]


def _separate(kind, mode_of):
    def handler(b, node, path):
        mode = mode_of(node)
        if mode is None:
            b.warn(("mode", path, node.name), f"node '{node.name}': mode "
                   f"'{getattr(node, 'mode', '')}' is not supported")
            return []
        v = b.input(node, 0, path, kind)
        outs = [b.new("f") for _ in range(3)]
        b.emit(pg.OP_SEPARATE, [mode], [v], outs)
        return outs
    return handler


def _combine(kind, mode_of):
    def handler(b, node, path):
        mode = mode_of(node)
        if mode is None:
            b.warn(("mode", path, node.name), f"node '{node.name}': mode "
                   f"'{getattr(node, 'mode', '')}' is not supported")
            return []
        ins = [b.input(node, i, path, "f") for i in range(3)]
        out = b.new(kind)
        b.emit(pg.OP_COMBINE, [mode], ins, [out])
        return [out]
    return handler


def _color_mode(node):
    return {"RGB": 0, "HSV": 1, "HSL": 2}.get(node.mode)


def _ramp(b, node, path):
    ramp = node.color_ramp
    first = len(b.tables)
    for i in range(RAMP_TABLE_SIZE):
        b.tables.append(tuple(ramp.evaluate(i / (RAMP_TABLE_SIZE - 1))))
    fac = b.input(node, "Fac", path, "f") or b.input(node, 0, path, "f")
    color, alpha = b.new("c"), b.new("f")
    b.emit(pg.OP_RAMP, [first, RAMP_TABLE_SIZE, int(ramp.interpolation != "CONSTANT")],
           [fac], [color, alpha])
    return [color, alpha]


def _mapping(b, node, path):
    vec = b.input(node, "Vector", path, "v")
    loc = b.input(node, "Location", path, "v") if _find_input(node, "Location") and \
        _find_input(node, "Location").enabled else b.const((0, 0, 0), "v")
    rot = b.input(node, "Rotation", path, "v")
    scale = b.input(node, "Scale", path, "v")
    out = b.new("v")
    b.emit(pg.OP_MAPPING, [cn.MAPPING_TYPES[node.vector_type]], [vec, loc, rot, scale], [out])
    return [out]


def _simple(op, names, kinds, out_kind):
    def handler(b, node, path):
        ins = [b.input(node, n, path, k) for n, k in zip(names, kinds)]
        out = b.new(out_kind)
        b.emit(op, [], ins, [out])
        return [out]
    return handler


def _rgb_to_bw(b, node, path):
    out = b.new("f")
    b.emit(pg.OP_RGB_TO_BW, [], [b.input(node, "Color", path, "c"),
                                 b.const(b.luminance, "v")], [out])
    return [out]


def _checker(b, node, path):
    ins = [b.texture_vector(node, path), b.input(node, "Color1", path, "c"),
           b.input(node, "Color2", path, "c"), b.input(node, "Scale", path, "f")]
    color, fac = b.new("c"), b.new("f")
    b.emit(pg.OP_CHECKER, [], ins, [color, fac])
    return [color, fac]


def _gradient(b, node, path):
    color, fac = b.new("c"), b.new("f")
    b.emit(pg.OP_GRADIENT, [ct.GRADIENT_TYPES[node.gradient_type]],
           [b.texture_vector(node, path)], [color, fac])
    return [color, fac]


def _dims(node, attr):
    return int(str(getattr(node, attr, "3"))[0])


def _white_noise(b, node, path):
    value, color = b.new("f"), b.new("c")
    b.emit(pg.OP_WHITE_NOISE, [_dims(node, "noise_dimensions")],
           [b.texture_vector(node, path), b.input(node, "W", path, "f")], [value, color])
    return [value, color]


def _noise(b, node, path):
    dims = _dims(node, "noise_dimensions")
    kind = NOISE_TYPES.get(getattr(node, "noise_type", "FBM"), 1)
    names = ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain",
             "Distortion")
    ins = [b.texture_vector(node, path)] + [
        b.input(node, n, path, "f") if _find_input(node, n) is not None else
        b.const({"Lacunarity": 2.0, "Gain": 1.0}.get(n, 0.0), "f") for n in names]
    value, color = b.new("f"), b.new("c")
    b.emit(pg.OP_NOISE, [dims, kind, int(getattr(node, "normalize", True)), 1], ins,
           [value, color])
    return [value, color]


def _voronoi(b, node, path):
    dims = _dims(node, "voronoi_dimensions")
    if dims not in (1, 2, 3, 4) or node.feature not in FEATURES:
        b.warn(("voronoi", path, node.name), f"node '{node.name}': Voronoi "
               f"{dims}D {node.feature} is not supported (1D-4D F1, F2, Smooth F1, "
               f"Distance to Edge, N-Sphere Radius are)")
        return []
    names = ("W", "Scale", "Detail", "Roughness", "Lacunarity", "Smoothness", "Exponent",
             "Randomness")
    ins = [b.texture_vector(node, path)] + [b.input(node, n, path, "f") for n in names]
    dist, color, pos, w = b.new("f"), b.new("c"), b.new("v"), b.new("f")
    b.emit(pg.OP_VORONOI, [dims, FEATURES[node.feature], METRICS[node.distance],
                           int(node.normalize) | (0 if compat.VORONOI_PCG_HASH else 2)],
           ins, [dist, color, pos, w])
    if node.feature == "N_SPHERE_RADIUS":  # the kernel returns the radius as distance
        return {"Radius": dist}
    return {"Distance": dist, "Color": color, "Position": pos, "W": w}


def _wave(b, node, path):
    names = ("Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness",
             "Phase Offset")
    ins = [b.texture_vector(node, path)] + [b.input(node, n, path, "f") for n in names]
    color, fac = b.new("c"), b.new("f")
    b.emit(pg.OP_WAVE, [ct.WAVE_TYPES[node.wave_type],
                        ct.WAVE_BANDS_DIRECTIONS[node.bands_direction],
                        ct.WAVE_RINGS_DIRECTIONS[node.rings_direction],
                        ct.WAVE_PROFILES[node.wave_profile]], ins, [color, fac])
    return [color, fac]


def _magic(b, node, path):
    ins = [b.texture_vector(node, path), b.input(node, "Scale", path, "f"),
           b.input(node, "Distortion", path, "f")]
    color, fac = b.new("c"), b.new("f")
    b.emit(pg.OP_MAGIC, [int(node.turbulence_depth)], ins, [color, fac])
    return [color, fac]


def _brick(b, node, path):
    ins = [b.texture_vector(node, path)] + \
        [b.input(node, n, path, "c") for n in ("Color1", "Color2", "Mortar")] + \
        [b.input(node, n, path, "f") for n in ("Scale", "Mortar Size", "Mortar Smooth",
                                               "Bias", "Brick Width", "Row Height")] + \
        [b.const(float(node.offset), "f"), b.const(float(node.squash), "f")]
    color, fac = b.new("c"), b.new("f")
    b.emit(pg.OP_BRICK, [int(node.offset_frequency), int(node.squash_frequency)], ins,
           [color, fac])
    return [color, fac]


REC709_TO_SCENE_LINEAR = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
"""Blackbody's Rec.709 -> scene linear matrix: identity for Blender's default OCIO
configuration (scene linear = Linear Rec.709)."""


def _blackbody(b, node, path):
    rows = [b.const(row, "v") for row in REC709_TO_SCENE_LINEAR]
    out = b.new("c")
    b.emit(pg.OP_BLACKBODY, [], [b.input(node, "Temperature", path, "f")] + rows, [out])
    return [out]


def _curve_table(b, mapping, curves, rgb, vector=False):
    """Bake a CurveMapping like Cycles' curvemapping_*_to_array: 256 rows over the x range
    spanned by the curves' end points (RGB: the combined curve, then R, G, B; vector:
    the X, Y, Z curves each in its channel). Returns (first row, min x, max x)."""
    mapping.update()
    lo = min(c.points[0].location[0] for c in curves)
    hi = max(c.points[len(c.points) - 1].location[0] for c in curves)
    first = len(b.tables)
    for i in range(RAMP_TABLE_SIZE):
        t = lo + i / (RAMP_TABLE_SIZE - 1) * (hi - lo)
        if vector:
            b.tables.append(tuple(mapping.evaluate(mapping.curves[c], t)
                                  for c in range(3)) + (0.0,))
        elif rgb:
            combined = mapping.evaluate(mapping.curves[3], t)
            b.tables.append(tuple(mapping.evaluate(mapping.curves[c], combined)
                                  for c in range(3)) + (0.0,))
        else:
            b.tables.append((mapping.evaluate(mapping.curves[0], t), 0.0, 0.0, 0.0))
    return first, lo, hi


def _rgb_curves(b, node, path):
    m = node.mapping
    first, lo, hi = _curve_table(b, m, list(m.curves), True)
    ins = [b.input(node, "Fac", path, "f"), b.input(node, "Color", path, "c"),
           b.const(lo, "f"), b.const(hi, "f")]
    out = b.new("c")
    b.emit(pg.OP_CURVES, [first, RAMP_TABLE_SIZE, int(m.extend == "EXTRAPOLATED")], ins,
           [out])
    return [out]


def _vector_curves(b, node, path):
    """Vector Curves: Cycles' svm_node_curves on a table of the X, Y, Z curves over the
    x range of the three."""
    m = node.mapping
    first, lo, hi = _curve_table(b, m, list(m.curves)[:3], False, vector=True)
    ins = [b.input(node, "Fac", path, "f"), b.input(node, "Vector", path, "v"),
           b.const(lo, "f"), b.const(hi, "f")]
    out = b.new("v")
    b.emit(pg.OP_CURVES, [first, RAMP_TABLE_SIZE, int(m.extend == "EXTRAPOLATED")], ins,
           [out])
    return [out]


XYZ_TO_SCENE_LINEAR = ((3.2409699, -1.5373832, -0.4986108),
                       (-0.9692436, 1.8759675, 0.0415551),
                       (0.0556301, -0.2039770, 1.0569715))
"""Wavelength's CIE XYZ (D65) -> scene linear matrix for Blender's default OCIO
configuration (scene linear = Linear Rec.709: its config.ocio's CIE-XYZ-D65 -> Rec.709
matrix, which Cycles' init_xyz_transforms obtains through the aces_interchange role)."""


def _wavelength(b, node, path):
    rows = [b.const(row, "v") for row in XYZ_TO_SCENE_LINEAR]
    out = b.new("c")
    b.emit(pg.OP_WAVELENGTH, [], [b.input(node, "Wavelength", path, "f")] + rows, [out])
    return [out]


def _float_curve(b, node, path):
    m = node.mapping
    first, lo, hi = _curve_table(b, m, [m.curves[0]], False)
    ins = [b.input(node, "Factor", path, "f"), b.input(node, "Value", path, "f"),
           b.const(lo, "f"), b.const(hi, "f")]
    out = b.new("f")
    b.emit(pg.OP_FLOAT_CURVE, [first, RAMP_TABLE_SIZE, int(m.extend == "EXTRAPOLATED")],
           ins, [out])
    return [out]


def _image(b, node, path):
    """Image Texture (core/shading/images.py for the sampling). Unlinked Vector: the
    first (active render) UV map, as Cycles. No image table, no image or no pixels:
    Cycles' magenta and alpha 1."""
    where = f"Material '{b.name}': node '{node.name}'"
    image = getattr(node, "image", None)
    slot = None
    if b.images is not None:
        slot = b.images.slot(image, where)
    else:
        b.warn(("image", path, node.name), f"node '{node.name}': no image table to read "
               f"'{getattr(image, 'name', '')}' into; it gives the missing-image magenta")
    if slot is None:
        return {"Color": b.const(ci.MISSING[:3], "c"), "Alpha": b.const(1.0, "f")}
    interp = ci.INTERPOLATIONS.get(node.interpolation, 1)
    ext = ci.EXTENSIONS.get(node.extension)
    if ext is None:
        b.warn(("ext", path, node.name), f"node '{node.name}': extension "
               f"'{node.extension}' is not supported; Repeat is used")
        ext = 0
    data = is_raw_space(image.colorspace_settings.name)
    alpha_out = node.outputs.get("Alpha")
    unassociate = int(alpha_out is not None and alpha_out.is_linked and not data
                      and image.alpha_mode not in ("CHANNEL_PACKED", "NONE"))
    sock = _find_input(node, "Vector")
    vec = b.source(pg.SOURCE_UV, 0) if sock is None or not sock.links else \
        b.as_kind(b.socket_value(sock, path), "v")
    color, alpha = b.new("c"), b.new("f")
    projection = ci.PROJECTIONS.get(node.projection, 0)
    if projection == 0:
        b.emit(pg.OP_IMAGE, [slot, interp, ext, unassociate], [vec], [color, alpha])
    else:  # Box reads the object-space normal (Cycles' svm_node_tex_image_box)
        b.emit(pg.OP_IMAGE_PROJECTED, [slot, interp, ext, unassociate | (projection << 1)],
               [vec, b.source(pg.SOURCE_OBJECT_NORMAL),
                b.const(float(node.projection_blend), "f")], [color, alpha])
    return {"Color": color, "Alpha": alpha}


def _normal_map(b, node, path):
    """Normal Map (core/shading/normals.py): tangent space reads the MikkTSpace tangent
    map of the node's UV map ("" = the active render one, as Cycles' default)."""
    space = pg.NORMAL_MAP_SPACES.get(getattr(node, "space", "TANGENT"))
    if space is None:
        b.warn(("nmspace", path, node.name), f"node '{node.name}': space "
               f"'{node.space}' is not supported; Tangent is used")
        space = 0
    invert_green = int(getattr(node, "convention", "OPENGL") == "DIRECTX")  # Blender 5.x
    colour = b.input(node, "Color", path, "c")
    strength = b.input(node, "Strength", path, "f")
    if space == 0:
        g = b.tangent_maps.index(getattr(node, "uv_map", "") or "")
        tangent, sign = b.source(pg.SOURCE_TANGENT, g), b.source(pg.SOURCE_TANGENT_SIGN, g, "f")
    else:
        tangent, sign = b.const((0.0, 0.0, 0.0), "v"), b.const(0.0, "f")
    rows = [b.source(pg.SOURCE_NORMAL_TO_WORLD, i) for i in range(3)]
    out = b.new("v")
    b.emit(pg.OP_NORMAL_MAP, [space, invert_green], [colour, strength, tangent, sign,
                                       b.source(pg.SOURCE_NORMAL),
                                       b.source(pg.SOURCE_BACKFACING, 0, "f"), *rows], [out])
    return {"Normal": out}


def _bump(b, node, path):
    """Bump (core/shading/normals.py ``bump``): the Height subgraph is compiled three
    times, at the point and with every input read at P + w dPdx and P + w dPdy (w the
    Filter Width, dPdx / dPdy the hit's footprint: core ``HitShader.footprint``), as
    Cycles evaluates it at the ray differential's offsets. Before 4.5 the node has no
    Filter Width: that Cycles' constant (``compat.BUMP_FILTER_WIDTH``: 1 up to 4.3, 0.1
    in 4.4)."""
    sock = _find_input(node, "Filter Width")
    width = float(sock.default_value) if sock is not None else compat.BUMP_FILTER_WIDTH
    if sock is not None and sock.is_linked:
        b.warn(("bumpw", path, node.name), f"node '{node.name}': a linked Filter Width is "
               f"not supported; its value {width:g} is used (Cycles reads it as a constant)")
    width = max(width, pg.BUMP_WIDTH_UNIT)
    saved = b.bump
    if saved[0]:
        b.warn(("bumpnest", path, node.name), f"node '{node.name}': a Bump inside another "
               f"Bump's Height is evaluated at the outer offset")
    heights = []
    for axis, mark in ((0, None), (1, _BUMP_MARKS[0]), (2, _BUMP_MARKS[1])):
        if axis:
            b.bump = (axis, width)
        try:
            heights.append(b.input(node, "Height", path + ((mark,) if mark else ()), "f"))
        finally:
            b.bump = saved
    nsock = _find_input(node, "Normal")
    normal = b.as_kind(b.socket_value(nsock, path), "v") if nsock is not None and \
        nsock.is_linked else b.source(pg.SOURCE_NORMAL)
    out = b.new("v")
    b.emit(pg.OP_BUMP, [int(bool(getattr(node, "invert", False)))],
           [b.input(node, "Strength", path, "f"), b.input(node, "Distance", path, "f"),
            b.const(width, "f"), *heights, normal, b.source(pg.SOURCE_BUMP_DPDX),
            b.source(pg.SOURCE_BUMP_DPDY)], [out])
    return {"Normal": out}


SUPPORTED = {
    "ShaderNodeNormalMap": _normal_map, "ShaderNodeBump": _bump,
    "ShaderNodeTexImage": _image, "ShaderNodeAttribute": _attribute,
    "ShaderNodeVertexColor": _color_attribute,
    "ShaderNodeTexCoord": _tex_coord, "ShaderNodeUVMap": _uv_map,
    "ShaderNodeNewGeometry": _geometry, "ShaderNodeObjectInfo": _object_info,
    "ShaderNodeValue": _value, "ShaderNodeRGB": _rgb, "ShaderNodeMath": _math,
    "ShaderNodeVectorMath": _vector_math, "ShaderNodeMapRange": _map_range,
    "ShaderNodeClamp": _clamp, "ShaderNodeMix": _mix, "ShaderNodeMixRGB": _mix_rgb,
    "ShaderNodeSeparateXYZ": _separate("v", lambda n: 0),
    "ShaderNodeCombineXYZ": _combine("v", lambda n: 0),
    "ShaderNodeSeparateColor": _separate("c", _color_mode),
    "ShaderNodeCombineColor": _combine("c", _color_mode),
    "ShaderNodeValToRGB": _ramp, "ShaderNodeMapping": _mapping,
    "ShaderNodeInvert": _simple(pg.OP_INVERT, ("Fac", "Color"), "fc", "c"),
    "ShaderNodeGamma": _simple(pg.OP_GAMMA, ("Color", "Gamma"), "cf", "c"),
    "ShaderNodeHueSaturation": _simple(pg.OP_HSV, ("Hue", "Saturation", "Value", "Fac",
                                                   "Color"), "ffffc", "c"),
    "ShaderNodeBrightContrast": _simple(pg.OP_BRIGHT_CONTRAST, ("Color", "Bright",
                                                                "Contrast"), "cff", "c"),
    "ShaderNodeRGBToBW": _rgb_to_bw, "ShaderNodeTexChecker": _checker,
    "ShaderNodeTexGradient": _gradient, "ShaderNodeTexWhiteNoise": _white_noise,
    "ShaderNodeTexNoise": _noise, "ShaderNodeTexVoronoi": _voronoi,
    "ShaderNodeTexWave": _wave, "ShaderNodeTexMagic": _magic, "ShaderNodeTexBrick": _brick,
    "ShaderNodeBlackbody": _blackbody, "ShaderNodeRGBCurve": _rgb_curves,
    "ShaderNodeFloatCurve": _float_curve, "ShaderNodeFresnel": _fresnel,
    "ShaderNodeLayerWeight": _layer_weight, "ShaderNodeVectorCurve": _vector_curves,
    "ShaderNodeWavelength": _wavelength, "ShaderNodeTangent": _tangent,
    "ShaderNodeLightPath": _light_path,
}
"""bl_idname -> handler of every node the compiler translates (plus Reroute, Group,
Group Input / Output and muted nodes, handled by the walk itself)."""


def _factor_product(b, factors):
    """The register value of the product over [(factor socket, take)] of clamp(fac, 0, 1)
    (take) or 1 - clamp(fac, 0, 1) (Cycles clamps a Mix Shader's factor); 1 for none."""
    one, zero = b.const((1.0,), "f"), b.const((0.0,), "f")
    total = None
    for sock, take in factors:
        v = b.as_kind(b.socket_value(sock, ()), "f")
        c = b.new("f")
        b.emit(pg.OP_CLAMP, [0], [v, zero, one], [c])
        if not take:
            s = b.new("f")
            b.emit(pg.OP_MATH, [cn.MATH_OPS["SUBTRACT"], 0], [one, c, zero], [s])
            c = s
        if total is not None:
            t = b.new("f")
            b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY"], 0], [total, c, zero], [t])
            c = t
        total = c
    return one if total is None else total


def mix_weight(factors, opacity_terms=None):
    """A ``compile_sockets`` target (TARGET_WEIGHT) computing a closure's share under
    linked Mix Shader factors, [(factor socket, take)] (``export_nodes.Closure.factored``):
    the product of clamp(fac) (take) or 1 - clamp(fac) along its path; divided by the
    opacity of ``nested_opacity(opacity_terms)`` when given (0 where it is 0)."""
    def build(b):
        w = _factor_product(b, factors)
        if opacity_terms is None:
            return w
        out = b.new("f")
        b.emit(pg.OP_MATH, [cn.MATH_OPS["DIVIDE"], 0],
               [w, _nested_opacity(b, opacity_terms), b.const((0.0,), "f")], [out])
        return out
    return build


def _nested_opacity(b, terms):
    """The register value of 1 - sum over cut-outs [(socket, kind, mean, scale,
    factors)] of scale x (its transparent share) x the product of ``factors`` (as
    ``_factor_product``): the share is 1 - clamp(Alpha) ("alpha"), (1 - clamp(fac)) mean
    ("mix_a"), clamp(fac) mean ("mix_b")."""
    one, zero = b.const((1.0,), "f"), b.const((0.0,), "f")
    total = one
    for sock, kind, mean, scale, factors in terms:
        v = b.as_kind(b.socket_value(sock, ()), "f")
        c = b.new("f")
        b.emit(pg.OP_CLAMP, [0], [v, zero, one], [c])
        if kind != "mix_b":  # the transparent share 1 - alpha, 1 - fac
            s = b.new("f")
            b.emit(pg.OP_MATH, [cn.MATH_OPS["SUBTRACT"], 0], [one, c, zero], [s])
            c = s
        k = scale * (1.0 if kind == "alpha" else float(mean))
        if factors:
            t = b.new("f")
            b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY"], 0],
                   [c, _factor_product(b, factors), zero], [t])
            c = t
        t = b.new("f")  # total - k x share
        b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY_ADD"], 0],
               [c, b.const((-k,), "f"), total], [t])
        total = t
    c = b.new("f")
    b.emit(pg.OP_CLAMP, [0], [total, zero, one], [c])
    return c


def nested_opacity(terms):
    """A ``compile_sockets`` target (TARGET_ALPHA) computing the opacity of programmed
    cut-outs nested under other Mix / Add Shaders (``_nested_opacity``; export_materials
    ``_program``)."""
    def build(b):
        return _nested_opacity(b, terms)
    return build


def constant(values):
    """A ``compile_sockets`` target of a constant: a float or a colour (3,) (where a node
    has no socket for a slot the program fills, e.g. a Volume Absorption's Absorption
    Color)."""
    values = tuple(float(v) for v in np.atleast_1d(values))
    kind = "f" if len(values) == 1 else "c"
    return lambda b: b.const(values, kind)


def weighted_sum(terms):
    """A ``compile_sockets`` target computing sum_k weight_k x colour_k x strength_k (a
    colour) from [(colour socket, strength socket or None, weight float[, factors])]: a
    material's emission over its emitting nodes; ``factors`` (as ``mix_weight``) the
    linked Mix Shader factors above a node, multiplying its term per hit."""
    def build(b):
        total = None
        for color_sock, strength_sock, weight, *factors in terms:
            c = b.as_kind(b.socket_value(color_sock, ()), "c")
            s = b.const((float(weight),), "f") if strength_sock is None else \
                b.as_kind(b.socket_value(strength_sock, ()), "f")
            if strength_sock is not None and weight != 1.0:
                w = b.new("f")
                b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY"], 0],
                       [s, b.const((float(weight),), "f"), b.const((0.0,), "f")], [w])
                s = w
            if factors and factors[0]:
                w = b.new("f")
                b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY"], 0],
                       [s, _factor_product(b, factors[0]), b.const((0.0,), "f")], [w])
                s = w
            term, junk = b.new("c"), b.new("f")
            zero = b.const((0.0, 0.0, 0.0), "v")
            b.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS["SCALE"]], [c, zero, zero, s],
                   [term, junk])
            if total is not None:
                out, junk2 = b.new("c"), b.new("f")
                b.emit(pg.OP_VECTOR_MATH, [cn.VECTOR_MATH_OPS["ADD"]], [total, term, zero,
                                                                       b.const((0.0,), "f")],
                       [out, junk2])
                term = out
            total = term
        return total if total is not None else b.const((0.0, 0.0, 0.0), "c")
    return build


def opacity_product(terms):
    """A ``compile_sockets`` target computing a material's opacity as the product over
    its programmed cut-outs [(socket, kind, mean)] (``export_nodes.Closure.cutouts``):
    "alpha" clamp(value, 0, 1); "mix_a" 1 - (1 - clamp(fac)) mean; "mix_b"
    1 - clamp(fac) mean (Cycles clamps a Mix Shader's factor)."""
    def build(b):
        total = None
        for sock, kind, mean in terms:
            v = b.as_kind(b.socket_value(sock, ()), "f")
            one, zero = b.const((1.0,), "f"), b.const((0.0,), "f")
            c = b.new("f")
            b.emit(pg.OP_CLAMP, [0], [v, zero, one], [c])
            if kind != "alpha":
                if kind == "mix_a":  # the transparent share 1 - fac
                    s = b.new("f")
                    b.emit(pg.OP_MATH, [cn.MATH_OPS["SUBTRACT"], 0], [one, c, zero], [s])
                    c = s
                a = b.new("f")  # 1 - share x mean
                b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY_ADD"], 0],
                       [c, b.const((-float(mean),), "f"), one], [a])
                c = a
            if total is not None:
                t = b.new("f")
                b.emit(pg.OP_MATH, [cn.MATH_OPS["MULTIPLY"], 0], [total, c, zero], [t])
                c = t
            total = c
        return total
    return build


def compile_sockets(material, targets, uv_maps=(), attributes=(),
                    luminance=cn.LUMINANCE_REC709, images=None, view=None,
                    tangent_maps=None) -> ShaderCompile:
    """Compile the values of input sockets of ``material``'s node tree.

    targets: [(socket, target, closure, slot)]: an input socket of a node of the
      material's tree, its TARGET_* (core.shading.program), the closure index and the
      first slot (a colour or vector socket fills slot, slot + 1, slot + 2).
    uv_maps: a ``UVMapNames`` (names are added as nodes read them) or the named maps, in
      the order of ``ShadingInputs.uv`` after the active render map. attributes: an ``AttributeNames`` (names are added as nodes read
      them) or names, in the order of ``ShadingInputs.attributes``. luminance: the scene-linear RGB -> Y weights.
    images: the export's ``export_images.ProgramImageTable`` Image Texture nodes read
      their images into (None: such a node gives the missing-image magenta, reported).
    view: the render camera (``export_camera.CameraView``) for Texture Coordinate Camera
      and Window; None: those outputs take their defaults, reported.
    tangent_maps: an ``AttributeNames`` of the UV maps whose MikkTSpace tangents the
      programs read (``Mesh.tangent_maps``; "" the active render UV map), names added as
      Normal Map nodes read them.
    """
    warnings: list[str] = []
    b = _Builder(material.name, uv_maps, attributes, luminance, warnings, images,
                 tangent_maps)
    b.group_bindings = {}
    b.view = view
    values = []
    for sock, target, closure, slot in targets:
        if callable(sock):  # an expression over sockets (``weighted_sum``)
            value = sock(b)
            kind = value.kind
        else:
            kind = _socket_kind(sock) or "f"
            value = b.as_kind(b.socket_value(sock, ()), kind)
        width = 1 if kind == "f" else 3
        values.append((value, [(target, closure, slot + c) for c in range(width)]))
    program, constant = b.finish(values)
    return ShaderCompile(program, constant, warnings)

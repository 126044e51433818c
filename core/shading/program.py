"""The compiled shader program: the format that crosses the boundary (docs/shading.md).

A program is a flat list of instructions over float registers (one value each; a vector
or colour takes 3 consecutive registers). Registers [0, K) hold the constant table,
loaded before the first instruction; the others are written by instructions, in order
(the compiler sorts the nodes topologically, so an instruction only reads registers
written before it).

instructions: (I, INSTRUCTION_WIDTH) int32. Column 0 is the opcode (OP_*), columns
  1 to 4 the opcode's integer parameters (enum codes, table rows; unused = 0), columns
  5 onwards its register operands in the order of SIGNATURES[op] (inputs, then outputs;
  a ``v`` operand is the first of 3 registers; unused columns = -1).
constants: (K,) float32, the values of registers [0, K).
tables: (T, 4) float32, rows baked by the exporter (ColorRamp: RGBA at 256 evenly spaced
  factors, Cycles' RAMP_TABLE_SIZE; RGB / Float Curves: the curve at 256 evenly spaced x
  over [min x, max x]), indexed by integer parameters.
n_registers: int >= K.
outputs: (O, 4) int32, one row per output value: register, target (TARGET_*), closure
  index (the material's closure it feeds, for TARGET_CLOSURE and TARGET_WEIGHT; else
  0), slot (a ``core.scene.closures`` parameter slot for TARGET_CLOSURE; the component
  0-2 of the emission colour or shading normal; 0 for alpha and a closure's weight
  factor). ``interpreter.evaluate`` returns
  (N, O) float32, column o for output row o.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import closures
from ..scene.media import DENSITY_SLOTS  # TARGET_DENSITY's slots (core/scene/media.py)
from . import light_path

INSTRUCTION_WIDTH = 20
FIRST_OPERAND = 5

(OP_INPUT, OP_MATH, OP_VECTOR_MATH, OP_MIX_FLOAT, OP_MIX_VECTOR, OP_MIX_VECTOR_NONUNIFORM,
 OP_MIX_COLOR, OP_MAP_RANGE, OP_VECTOR_MAP_RANGE, OP_CLAMP, OP_SEPARATE, OP_COMBINE, OP_RAMP,
 OP_MAPPING, OP_INVERT, OP_GAMMA, OP_HSV, OP_BRIGHT_CONTRAST, OP_RGB_TO_BW, OP_CHECKER,
 OP_GRADIENT, OP_WHITE_NOISE, OP_NOISE, OP_VORONOI, OP_WAVE, OP_MAGIC, OP_BRICK, OP_BLACKBODY,
 OP_CURVES, OP_FLOAT_CURVE, OP_IMAGE, OP_FRESNEL, OP_LAYER_WEIGHT, OP_TRANSFORM,
 OP_WAVELENGTH, OP_IMAGE_PROJECTED, OP_NORMAL_MAP, OP_BUMP, OP_TANGENT) = range(39)

SIGNATURES = {
    OP_INPUT: ">v",                  # ints: source (SOURCE_*), index (UV map / attribute)
    OP_MATH: "fff>f",                # ints: MATH_OPS code, clamp
    OP_VECTOR_MATH: "vvvf>vf",       # ints: VECTOR_MATH_OPS code
    OP_MIX_FLOAT: "fff>f",           # factor, a, b; ints: clamp factor
    OP_MIX_VECTOR: "fvv>v",          # ints: clamp factor
    OP_MIX_VECTOR_NONUNIFORM: "vvv>v",
    OP_MIX_COLOR: "fvv>v",           # ints: BLEND_TYPES code, clamp factor, clamp result
    OP_MAP_RANGE: "ffffff>f",        # value, from min/max, to min/max, steps; ints: type, clamp
    OP_VECTOR_MAP_RANGE: "vvvvvv>v",
    OP_CLAMP: "fff>f",               # value, min, max; ints: 0 MINMAX, 1 RANGE
    OP_SEPARATE: "v>fff",            # ints: 0 RGB/XYZ, 1 HSV
    OP_COMBINE: "fff>v",             # ints: 0 RGB/XYZ, 1 HSV
    OP_RAMP: "f>vf",                 # ints: first table row, rows, interpolate
    OP_MAPPING: "vvvv>v",            # vector, location, rotation, scale; ints: MAPPING_TYPES
    OP_INVERT: "fv>v",
    OP_GAMMA: "vf>v",
    OP_HSV: "ffffv>v",               # hue, saturation, value, factor, colour
    OP_BRIGHT_CONTRAST: "vff>v",
    OP_RGB_TO_BW: "vv>f",            # colour, luminance weights
    OP_CHECKER: "vvvf>vf",           # vector, colour 1, colour 2, scale
    OP_GRADIENT: "v>vf",             # ints: GRADIENT_TYPES code
    OP_WHITE_NOISE: "vf>fv",         # vector, W; ints: dimensions
    OP_NOISE: "vffffffff>fv",        # vector, W, scale, detail, roughness, lacunarity,
                                     # offset, gain, distortion; ints: dims, type, normalize,
                                     # colour needed (0: the colour's G and B are 0)
    OP_VORONOI: "vffffffff>fvvf",    # vector, W, scale, detail, roughness, lacunarity,
                                     # smoothness, exponent, randomness -> distance, colour,
                                     # position, W; ints: dims, feature, metric, flags
                                     # (1: normalize, 2: Blender 4.x feature points)
    OP_WAVE: "vffffff>vf",           # vector, scale, distortion, detail, detail scale,
                                     # detail roughness, phase; ints: WAVE_TYPES,
                                     # bands direction, rings direction, profile
    OP_MAGIC: "vff>vf",              # vector, scale, distortion; ints: depth
    OP_BRICK: "vvvvffffffff>vf",     # vector, colour 1, 2, mortar, scale, mortar size,
                                     # mortar smooth, bias, brick width, row height, offset,
                                     # squash; ints: offset frequency, squash frequency
    OP_BLACKBODY: "fvvv>v",          # temperature (K), the 3 rows of Rec.709 -> scene linear
    OP_CURVES: "fvff>v",             # factor, colour, min x, max x; ints: first row, rows,
                                     # extrapolate (RGB Curves, the table holds R, G, B)
    OP_FLOAT_CURVE: "ffff>f",        # factor, value, min x, max x; ints as OP_CURVES
    OP_IMAGE: "v>vf",                # vector -> colour, alpha; ints: image slot
                                     # (core.scene.images; -1 missing), interpolation,
                                     # extension (core.shading.images), unassociate alpha
    OP_FRESNEL: "fvvf>f",            # IOR, normal, incoming, backfacing (core.shading.facing)
    OP_LAYER_WEIGHT: "fvvf>ff",      # blend, normal, incoming, backfacing -> Fresnel, Facing
    OP_TRANSFORM: "vvfvfvfvf>v",     # point, the 4 rows of a 4 x 4 matrix (xyz, w each);
                                     # ints: 0 affine (rows 0-2), 1 projective (rows 0-2
                                     # divided by row 3 at the point; 0 where it is 0)
    OP_WAVELENGTH: "fvvv>v",         # wavelength (nm), the 3 rows of XYZ -> scene linear
    OP_IMAGE_PROJECTED: "vvf>vf",    # vector, object-space normal, blend -> colour, alpha;
                                     # ints as OP_IMAGE but column 4: unassociate (bit 0)
                                     # | projection << 1 (core.shading.images.PROJECTIONS)
    OP_NORMAL_MAP: "vfvfvfvvv>v",    # colour, strength, tangent, sign, shading normal N,
                                     # backfacing, the 3 rows of the object's normal
                                     # transform -> normal; ints: NORMAL_MAP_SPACES code,
                                     # invert green (DirectX convention)
    OP_BUMP: "ffffffvvv>v",          # strength, distance, filter width, height at the
                                     # point, at P + w dPdx, at P + w dPdy, normal, dPdx,
                                     # dPdy -> normal; ints: invert
    OP_TANGENT: "vvvvv>v",           # vector (Generated, or a world-space tangent), the 3
                                     # rows of the object's normal transform, shading
                                     # normal N -> tangent; ints: TANGENT_MODES code
}
"""Register operands of each opcode: ``f`` one register, ``v`` three; ``>`` separates the
inputs from the outputs."""

OP_NAMES = {OP_INPUT: "INPUT", OP_MATH: "MATH", OP_VECTOR_MATH: "VECTOR_MATH",
            OP_MIX_FLOAT: "MIX_FLOAT", OP_MIX_VECTOR: "MIX_VECTOR",
            OP_MIX_VECTOR_NONUNIFORM: "MIX_VECTOR_NONUNIFORM", OP_MIX_COLOR: "MIX_COLOR",
            OP_MAP_RANGE: "MAP_RANGE", OP_VECTOR_MAP_RANGE: "VECTOR_MAP_RANGE",
            OP_CLAMP: "CLAMP", OP_SEPARATE: "SEPARATE", OP_COMBINE: "COMBINE",
            OP_RAMP: "RAMP", OP_MAPPING: "MAPPING", OP_INVERT: "INVERT", OP_GAMMA: "GAMMA",
            OP_HSV: "HSV", OP_BRIGHT_CONTRAST: "BRIGHT_CONTRAST", OP_RGB_TO_BW: "RGB_TO_BW",
            OP_CHECKER: "CHECKER", OP_GRADIENT: "GRADIENT", OP_WHITE_NOISE: "WHITE_NOISE",
            OP_NOISE: "NOISE", OP_VORONOI: "VORONOI", OP_WAVE: "WAVE", OP_MAGIC: "MAGIC",
            OP_BRICK: "BRICK", OP_BLACKBODY: "BLACKBODY", OP_CURVES: "CURVES",
            OP_FLOAT_CURVE: "FLOAT_CURVE", OP_IMAGE: "IMAGE", OP_FRESNEL: "FRESNEL",
            OP_LAYER_WEIGHT: "LAYER_WEIGHT", OP_TRANSFORM: "TRANSFORM",
            OP_WAVELENGTH: "WAVELENGTH", OP_IMAGE_PROJECTED: "IMAGE_PROJECTED",
            OP_NORMAL_MAP: "NORMAL_MAP", OP_BUMP: "BUMP", OP_TANGENT: "TANGENT"}

NORMAL_MAP_SPACES = {"TANGENT": 0, "OBJECT": 1, "WORLD": 2, "BLENDER_OBJECT": 3,
                     "BLENDER_WORLD": 4}
"""Normal Map node space -> OP_NORMAL_MAP's int (Cycles' NodeNormalMapSpace order)."""

TANGENT_MODES = {"X": 0, "Y": 1, "Z": 2, "UV_MAP": 3}
"""OP_TANGENT's int (core.shading.normals.tangent): radial about the object's X / Y / Z
axis from Generated (Cycles' NODE_TANGENT_RADIAL), or the UV map's tangent as it is."""

# --- OP_INPUT sources (ints column 1); all write 3 registers, scalars in the first -------
(SOURCE_POSITION, SOURCE_NORMAL, SOURCE_TRUE_NORMAL, SOURCE_INCOMING, SOURCE_BACKFACING,
 SOURCE_GENERATED, SOURCE_OBJECT, SOURCE_OBJECT_NORMAL, SOURCE_UV, SOURCE_OBJECT_LOCATION,
 SOURCE_OBJECT_RANDOM, SOURCE_ATTRIBUTE_COLOR, SOURCE_ATTRIBUTE_ALPHA, SOURCE_OBJECT_COLOR,
 SOURCE_OBJECT_INDEX, SOURCE_TANGENT, SOURCE_TANGENT_SIGN, SOURCE_NORMAL_TO_WORLD,
 SOURCE_BUMP_DPDX, SOURCE_BUMP_DPDY, SOURCE_OBJECT_ALPHA, SOURCE_MATERIAL_INDEX,
 SOURCE_LIGHT_PATH) = range(23)
SOURCE_COUNT = 23
BUMP_WIDTH_UNIT = 1e-6
"""OP_INPUT's int 3 is the bump offset (0: at the point, 1: at P + w dPdx, 2: at P + w
dPdy: the Bump node's Height subgraph is compiled three times), int 4 the filter width w
in these units (Cycles' bump_filter_width). SOURCE_BUMP_DPDX / DPDY: the footprint
vectors dPdx, dPdy (ShadingInputs.bump_points)."""
# SOURCE_TANGENT / SOURCE_TANGENT_SIGN (index: the tangent map, ShadingInputs.tangents):
# the interpolated MikkTSpace tangent (world space, unnormalised) and bitangent sign (0:
# no tangent there); SOURCE_NORMAL_TO_WORLD (index 0-2): row i of the object's normal
# transform inv(A)^T (ShadingInputs.normal_to_world). SOURCE_LIGHT_PATH (index: the Light
# Path output, core.shading.light_path column): the ray that reached the point
# (ShadingInputs.light_path).

# --- output targets ----------------------------------------------------------------------
TARGET_CLOSURE = 0    # closure parameter slot (core.scene.closures)
TARGET_EMISSION = 1   # the material's emission colour, component 0-2 (radiance)
TARGET_ALPHA = 2      # the material's opacity in [0, 1]
TARGET_NORMAL = 3     # the shading normal, component 0-2 (world space, unnormalised)
TARGET_DENSITY = 4    # a medium's density rho(x) >= 0 (core/scene/media.py), slot 0; a
                      # varying colour adds slots 1-3 (Color) and 4-6 (Absorption Color)
TARGET_WEIGHT = 5     # a per-hit factor of closure row ``closure``'s weight, slot 0: the
                      # product of the linked Mix Shader factors above it (clamped f or
                      # 1 - f each); rows without one keep their constant weight
TARGET_COUNT = 6


def _widths(op: int) -> list[int]:
    return [3 if c == "v" else 1 for c in SIGNATURES[op].replace(">", "")]


@dataclass(frozen=True)
class ShaderProgram:
    """One material's compiled node graph (module doc for every field)."""
    instructions: np.ndarray
    constants: np.ndarray
    tables: np.ndarray
    n_registers: int
    outputs: np.ndarray
    name: str = ""

    @classmethod
    def build(cls, instructions, constants, outputs, n_registers, tables=None, name=""):
        """A validated program from lists or arrays (dtypes as the module doc)."""
        ins = np.asarray(instructions, np.int32).reshape(-1, INSTRUCTION_WIDTH)
        tab = np.zeros((0, 4), np.float32) if tables is None else \
            np.asarray(tables, np.float32).reshape(-1, 4)
        prog = cls(np.ascontiguousarray(ins), np.asarray(constants, np.float32).ravel(),
                   np.ascontiguousarray(tab), int(n_registers),
                   np.asarray(outputs, np.int32).reshape(-1, 4), name)
        prog.validate()
        return prog

    def validate(self):
        """Raise ValueError naming the program, instruction and operand at fault."""
        who = f"shader program {self.name!r}"
        if self.instructions.ndim != 2 or self.instructions.shape[1] != INSTRUCTION_WIDTH:
            raise ValueError(f"{who}: instructions must be (I, {INSTRUCTION_WIDTH}) int32, "
                             f"got {self.instructions.shape}")
        k = self.constants.shape[0]
        if self.n_registers < k:
            raise ValueError(f"{who}: n_registers {self.n_registers} < {k} constants")
        if not np.all(np.isfinite(self.constants)):
            raise ValueError(f"{who}: a constant is not finite")
        if self.tables.ndim != 2 or self.tables.shape[1] != 4:
            raise ValueError(f"{who}: tables must be (T, 4) float32, got {self.tables.shape}")
        written = np.zeros(self.n_registers, bool)
        written[:k] = True
        for i, row in enumerate(self.instructions):
            op = int(row[0])
            if op not in SIGNATURES:
                raise ValueError(f"{who}: instruction {i} has unknown opcode {op}")
            sig = SIGNATURES[op]
            n_in = len(sig.split(">")[0])
            widths = _widths(op)
            for j, w in enumerate(widths):
                reg = int(row[FIRST_OPERAND + j])
                if not 0 <= reg <= self.n_registers - w:
                    raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) operand {j} "
                                     f"register {reg} outside [0, {self.n_registers - w}]")
                if j < n_in and not written[reg:reg + w].all():
                    raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) reads "
                                     f"register {reg} before it is written")
                if j >= n_in:
                    if reg < k:
                        raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) writes "
                                         f"constant register {reg}")
                    written[reg:reg + w] = True
            if np.any(row[FIRST_OPERAND + len(widths):] != -1):
                raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) has operands "
                                 f"beyond its signature {sig!r}")
            if op == OP_INPUT and not (0 <= row[1] < SOURCE_COUNT and 0 <= row[3] <= 2
                                       and row[4] >= 0):
                raise ValueError(f"{who}: instruction {i} reads unknown input source {row[1]} "
                                 f"(bump offset {row[3]}, filter width {row[4]})")
            if op in (OP_IMAGE, OP_IMAGE_PROJECTED) and not (row[1] >= -1 and 0 <= row[2] <= 2
                                                       and 0 <= row[3] <= 3):
                raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) has image slot "
                                 f"{row[1]}, interpolation {row[2]}, extension {row[3]}")
            if op == OP_INPUT and row[1] == SOURCE_LIGHT_PATH and not \
                    0 <= row[2] < light_path.COUNT:
                raise ValueError(f"{who}: instruction {i} reads Light Path output {row[2]} "
                                 f"outside [0, {light_path.COUNT})")
            if op == OP_TANGENT and not 0 <= row[1] < len(TANGENT_MODES):
                raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) has unknown "
                                 f"mode {row[1]}")
            if op == OP_NORMAL_MAP and not 0 <= row[1] < len(NORMAL_MAP_SPACES):
                raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) has unknown "
                                 f"space {row[1]}")
            if op in (OP_RAMP, OP_CURVES, OP_FLOAT_CURVE) and not (row[2] >= 2 and 0 <= row[1]
                                      and row[1] + row[2] <= self.tables.shape[0]):
                raise ValueError(f"{who}: instruction {i} ({OP_NAMES[op]}) rows [{row[1]}, "
                                 f"{row[1] + row[2]}) outside the {self.tables.shape[0]}-row "
                                 f"table")
        if self.outputs.ndim != 2 or self.outputs.shape[1] != 4:
            raise ValueError(f"{who}: outputs must be (O, 4) int32, got {self.outputs.shape}")
        for o, (reg, target, closure, slot) in enumerate(self.outputs.tolist()):
            if not 0 <= reg < self.n_registers or not written[reg]:
                raise ValueError(f"{who}: output {o} reads register {reg}, never written")
            if not 0 <= target < TARGET_COUNT:
                raise ValueError(f"{who}: output {o} has unknown target {target}")
            limit = closures.PARAM_COUNT if target == TARGET_CLOSURE else \
                (DENSITY_SLOTS if target == TARGET_DENSITY else
                 1 if target in (TARGET_ALPHA, TARGET_WEIGHT) else 3)
            if not 0 <= slot < limit:
                raise ValueError(f"{who}: output {o} slot {slot} outside [0, {limit})")
            if closure < 0:
                raise ValueError(f"{who}: output {o} closure index {closure} < 0")

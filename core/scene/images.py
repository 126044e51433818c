"""The images shader programs sample (Image Texture nodes): ``ProgramImages``, part of the
data contract (``Scene.program_images``; docs/shading.md, "Image Texture").

Every image is stored once per render in its native precision, as Cycles keeps it on the
device (``ImageManager``): 8-bit images as uint8, 16-bit as uint16, float images as
float32, always 4 channels (RGBA), row-major with row 0 at the BOTTOM (Blender's
``Image.pixels`` order, so UV (0, 0) is texel (0, 0)). Colour data an image keeps
sRGB-encoded (Cycles' ``compress_as_srgb``: 8 and 16-bit images in the sRGB space) is
decoded AFTER filtering, as Cycles does; every other image holds scene-linear values (or
data). Alpha is stored as Cycles holds it after loading: associated (premultiplied in
the stored encoding) unless the image is premultiplied already, channel-packed or data.

An image *slot* is what one Image Texture node names: one tile, or the tiles of a UDIM
image (tile number 1001 + u + 10 v). The program's OP_IMAGE instruction carries the slot.

bytes: (B,) uint8; shorts: (S,) uint16; floats: (F,) float32: the texel channels of
  every tile of each kind, one tile after the other.
tiles: (R, 6) int64, one row per tile: kind (KIND_*), offset (first element in its
  kind's array), width, height (texels >= 1), UDIM tile number (0: not tiled), encoding
  (1: sRGB-encoded colour, decoded after filtering; 0: linear / data).
slot_first, slot_count: (K,) int64, slot k's tiles are rows [first, first + count).
names: tuple of K str, the images' names (messages).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import SceneError, check_array

KIND_BYTE, KIND_SHORT, KIND_FLOAT = 0, 1, 2
BYTES_PER_TEXEL = {KIND_BYTE: 4, KIND_SHORT: 8, KIND_FLOAT: 16}


@dataclass(frozen=True)
class ProgramImages:
    """The images of a render's shader programs (module doc for every field)."""
    bytes: np.ndarray
    shorts: np.ndarray
    floats: np.ndarray
    tiles: np.ndarray
    slot_first: np.ndarray
    slot_count: np.ndarray
    names: tuple = ()

    @staticmethod
    def empty() -> "ProgramImages":
        return ProgramImages(np.zeros(0, np.uint8), np.zeros(0, np.uint16),
                             np.zeros(0, np.float32), np.zeros((0, 6), np.int64),
                             np.zeros(0, np.int64), np.zeros(0, np.int64), ())

    @staticmethod
    def pack(slots, names=()) -> "ProgramImages":
        """Pack K slots, each a list of (tile number, texels, encoding): texels (H, W, 4)
        uint8, uint16 or float32 (row 0 at the bottom), tile number 0 for an untiled image,
        encoding 1 for sRGB-encoded colour (decoded after filtering)."""
        parts = {KIND_BYTE: [], KIND_SHORT: [], KIND_FLOAT: []}
        sizes = dict.fromkeys(parts, 0)
        kinds = {np.dtype(np.uint8): KIND_BYTE, np.dtype(np.uint16): KIND_SHORT,
                 np.dtype(np.float32): KIND_FLOAT}
        rows, first, count = [], [], []
        for tiles in slots:
            first.append(len(rows))
            count.append(len(tiles))
            for number, texels, encoding in tiles:
                a = np.ascontiguousarray(texels)
                if a.ndim != 3 or a.shape[2] != 4 or a.dtype not in kinds:
                    raise SceneError(f"program image tile must be (H, W, 4) uint8, uint16 or "
                                     f"float32, got {a.shape} {a.dtype}")
                kind = kinds[a.dtype]
                rows.append([kind, sizes[kind], a.shape[1], a.shape[0], int(number),
                             int(encoding)])
                parts[kind].append(a.ravel())
                sizes[kind] += a.size
        cat = [np.concatenate(parts[k]) if parts[k] else np.zeros(0, dt)
               for k, dt in ((KIND_BYTE, np.uint8), (KIND_SHORT, np.uint16),
                             (KIND_FLOAT, np.float32))]
        return ProgramImages(cat[0], cat[1], cat[2],
                             np.array(rows, np.int64).reshape(-1, 6),
                             np.array(first, np.int64), np.array(count, np.int64),
                             tuple(names))

    @property
    def count(self) -> int:
        """Slots."""
        return int(self.slot_first.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes of texel storage."""
        return int(self.bytes.nbytes + self.shorts.nbytes + self.floats.nbytes)

    def texels(self) -> int:
        """Texels over every tile."""
        return int((self.tiles[:, 2] * self.tiles[:, 3]).sum()) if self.tiles.size else 0

    def validate(self) -> None:
        """Raise SceneError naming the tile or slot at fault."""
        check_array("program_images.bytes", self.bytes, (None,), dtype=np.uint8)
        check_array("program_images.shorts", self.shorts, (None,), dtype=np.uint16)
        check_array("program_images.floats", self.floats, (None,), dtype=np.float32)
        check_array("program_images.tiles", self.tiles, (None, 6), dtype=np.int64)
        k = self.count
        check_array("program_images.slot_first", self.slot_first, (k,), dtype=np.int64)
        check_array("program_images.slot_count", self.slot_count, (k,), dtype=np.int64)
        if not np.all(np.isfinite(self.floats)) or np.any(self.floats < 0):
            raise SceneError("program_images.floats: texels must be finite and >= 0")
        size = {KIND_BYTE: self.bytes.size, KIND_SHORT: self.shorts.size,
                KIND_FLOAT: self.floats.size}
        for r, (kind, off, w, h, number, enc) in enumerate(self.tiles.tolist()):
            if kind not in size or w < 1 or h < 1 or off < 0 or off + 4 * w * h > size[kind] \
                    or enc not in (0, 1) or number < 0:
                raise SceneError(f"program_images.tiles row {r} {self.tiles[r].tolist()} is "
                                 f"invalid (kind, offset, width, height, tile, encoding)")
        end = self.slot_first + self.slot_count
        bad = (self.slot_first < 0) | (self.slot_count < 1) | (end > self.tiles.shape[0])
        if np.any(bad):
            i = int(np.argmax(bad))
            name = self.names[i] if i < len(self.names) else i
            raise SceneError(f"program_images slot {name!r}: tiles [{self.slot_first[i]}, "
                             f"{end[i]}) outside the {self.tiles.shape[0]} tiles")

"""Images of Image Texture nodes -> the scene's Textures, each image read once per export.

Used by the node reader (export_nodes.NodeReader.image_input): an Image Texture feeding a
colour input becomes a texture index; ``ImageTable.textures()`` packs them for the core.
"""

from __future__ import annotations

import os
import tempfile

import bpy
import numpy as np

from ..core.io.exr import srgb_encode
from ..core.materials.textures import srgb_to_linear
from ..core.scene.contract import Textures
from ..core.scene.images import ProgramImages

DEFAULT_GREY = 0.8
"""Albedo used for a missing image (Cycles' default surface)."""


class ImageTable:
    """The images of one export, each read ONCE into numpy however many materials use it.

    ``index(image, where)`` returns the texture index (None for a missing image or one
    without pixels, reported once with ``where``, "Material ...: node ..."). Pixels are
    read with ``Image.pixels.foreach_get`` into float32 and decoded to linear: byte images
    tagged sRGB with the exact sRGB EOTF; Non-Color, Linear Rec.709 and float images
    (Blender keeps those in scene linear) as they are; byte images in any other OCIO space
    converted by Blender (``_scene_linear``), or decoded as sRGB with a warning if that
    fails.
    """

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
        linear = bool(getattr(image, "is_float", False)) or is_raw_space(space)
        if not linear and space != "sRGB":  # Rec.2020, ACEScg, a log space...: Blender's
            converted = _scene_linear(rgba[..., :3], space)  # conversion, as Cycles'
            if converted is not None and np.all(np.isfinite(converted)):
                rgba[..., :3] = converted
                linear = True
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


RAW_SPACES = ("Non-Color", "Raw", "scene_linear", "Linear", "Linear Rec.709")
"""OCIO colour spaces whose texels Cycles takes as they are (data, or scene linear in
Blender's default configuration): no conversion, no alpha association."""


def is_raw_space(space: str) -> bool:
    """The program images' test for ``RAW_SPACES``."""
    return space in RAW_SPACES


class ProgramImageTable:
    """The images Image Texture nodes inside shader programs sample, each read ONCE per
    export and stored as Cycles keeps it (core/scene/images.py): byte images as uint8 (4
    bytes per texel), 16-bit images as uint16 (8), float images as float32 (16).

    ``slot(image, where)`` returns the image's slot, or None (reported once with
    ``where``) for no image or one without pixels: the node then gives Cycles' magenta.

    What Blender gives and how it is stored: ``Image.pixels`` of a byte image are the
    stored bytes / 255 (still sRGB-encoded), so the bytes are recovered exactly. A 16-bit
    PNG is a float image in Blender (the only PNG that is): as data (Non-Color, the
    scene-linear spaces of ``RAW_SPACES``) the file's values / 65535, in sRGB
    decoded to linear on load (measured: within 1.7e-5 of the exact EOTF), so it is
    re-encoded (exact sRGB OETF) and rounded back to the file's 16-bit values. sRGB byte
    and 16-bit images stay sRGB-encoded and are decoded after filtering, as Cycles'
    compress_as_srgb does (measured: filtering a 16-bit one in linear is 0.2 off Cycles
    between texel centres). Other float images (EXR, HDR, 16-bit TIFF) are scene linear,
    float32 (Blender converted them from their space on load). A byte or 16-bit image in
    another space (Linear Rec.2020, ACEScg, Display P3, Filmic / AgX Log, ...) is
    converted to scene linear per texel by Blender (``_scene_linear``), float32 (Cycles
    converts per texel too, with OCIO, and keeps half floats). Alpha as Cycles loads it: Straight images are associated in
    the stored encoding (integers: c * a // max, as Cycles' image.cpp), Premultiplied and
    Channel Packed kept, None (ignored) set to opaque, Non-Color not associated.
    """

    def __init__(self, warnings: list[str]):
        self._warnings = warnings
        self._slot: dict = {}
        self._slots: list = []
        self._names: list[str] = []

    def _warn(self, msg):
        if msg not in self._warnings:
            self._warnings.append(msg)

    def slot(self, image, where: str) -> int | None:
        if image is None:
            self._warn(f"{where} has no image; it gives Cycles' missing-image magenta")
            return None
        image = getattr(image, "original", image) or image
        key = image.as_pointer()
        if key not in self._slot:
            tiles = self._read_tiles(image, where)
            if tiles:
                self._slots.append(tiles)
                self._names.append(image.name)
                self._slot[key] = len(self._slots) - 1
            else:
                self._slot[key] = None
        if self._slot[key] is None:
            self._warn(f'{where}: image "{image.name}" has no pixels (missing file?); it '
                       f"gives Cycles' missing-image magenta")
        return self._slot[key]

    def _read_tiles(self, image, where):
        if getattr(image, "source", "FILE") != "TILED":
            px = _pixels(image)
            return [] if px is None else [(0, *self._encode(image, px, where))]
        out = []
        path = image.filepath_raw
        for tile in image.tiles:
            px = None
            if "<UDIM>" in path:
                px = _tile_pixels(image, path.replace("<UDIM>", str(tile.number)))
            elif tile.number == 1001:
                px = _pixels(image)
            if px is None:
                self._warn(f'{where}: tile {tile.number} of image "{image.name}" has no '
                           f"pixels; it gives Cycles' missing-image magenta")
                continue
            out.append((tile.number, *self._encode(image, px, where)))
        return out

    def _encode(self, image, px, where):
        """(texels (H, W, 4) uint8 / uint16 / float32, encoding) from Blender's float
        pixels ``px`` (H, W, 4)."""
        space = image.colorspace_settings.name
        data = is_raw_space(space)
        is_float = bool(getattr(image, "is_float", False))
        # Blender loads only 16-bit PNGs into float buffers (8-bit ones stay bytes)
        sixteen = is_float and getattr(image, "file_format", "") == "PNG"
        alpha_mode = getattr(image, "alpha_mode", "STRAIGHT")
        if alpha_mode == "NONE":
            px[..., 3] = 1.0
        if not data and space != "sRGB" and not (is_float and not sixteen):
            # Another OCIO space (Rec.2020, P3, a log encoding, ...): Cycles converts each
            # texel to scene linear at load (and keeps half floats); so do we, with
            # Blender's own conversion (a float buffer is made scene linear on load), in
            # float32 (rounding to half did not bring us closer to Cycles: measured 99th
            # percentiles 1.1e-4 to 5.5e-4 either way).
            linear = px[..., :3] if is_float else _scene_linear(px[..., :3], space)
            if linear is None or not np.all(np.isfinite(linear)):
                self._warn(f'{where}: image "{image.name}" colour space "{space}" could not '
                           f"be converted; it is decoded as sRGB")
            else:
                rgba = np.array(px, np.float32)
                rgba[..., :3] = linear
                if alpha_mode == "STRAIGHT":
                    rgba[..., :3] *= rgba[..., 3:4]
                return np.clip(rgba, 0.0, None), 0
        if not is_float or sixteen:
            top = 255 if not is_float else 65535
            if is_float and not data:  # Blender decoded it: back to the file's encoding
                px[..., :3] = srgb_encode(px[..., :3])
            q = np.rint(np.clip(px, 0.0, 1.0) * top).astype(np.int64)
            if alpha_mode == "STRAIGHT" and not data:
                q[..., :3] = q[..., :3] * q[..., 3:4] // top
            return q.astype(np.uint8 if top == 255 else np.uint16), int(not data)
        rgba = np.array(px, np.float32)
        rgba[~np.isfinite(rgba)] = 0.0
        np.clip(rgba, 0.0, None, out=rgba)
        if alpha_mode == "STRAIGHT" and not data:
            rgba[..., :3] *= rgba[..., 3:4]
        return rgba, 0

    def images(self) -> ProgramImages:
        """The scene's ProgramImages (slots in index order)."""
        if not self._slots:
            return ProgramImages.empty()
        return ProgramImages.pack(self._slots, self._names)


def _pixels(image):
    """(H, W, 4) float32 RGBA of Blender's ``Image.pixels`` (row 0 at the bottom; grey
    and grey-alpha images spread to RGB), or None without pixels."""
    try:
        w, h = (int(x) for x in image.size)
        channels = int(image.channels)
    except (AttributeError, ReferenceError):
        return None
    if w * h * channels == 0:
        return None
    buf = np.empty(w * h * channels, np.float32)
    try:
        image.pixels.foreach_get(buf)
    except (RuntimeError, ValueError, TypeError):
        return None
    px = buf.reshape(h, w, channels)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = px[..., :3] if channels >= 3 else px[..., :1]
    if channels in (2, 4):
        rgba[..., 3] = px[..., -1]
    return rgba


def _scene_linear(rgb: np.ndarray, space: str) -> np.ndarray:
    """(H, W, 3) float32 texel values encoded in OCIO colour space ``space`` -> scene
    linear, by Blender's own colour management: written to a temporary float EXR, loaded
    with ``space`` as its colour space (Blender converts a float image to scene linear on
    load), read back. The values are converted texel by texel, as Cycles does."""
    import OpenEXR  # bundled with the extension (core/io/exr.py reads it the same way)

    h, w = rgb.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "texels.exr")
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        OpenEXR.File(header, {"RGBA": rgba[::-1].copy()}).write(path)
        tmp = bpy.data.images.load(path, check_existing=False)
        try:
            tmp.colorspace_settings.name = space
            out = _pixels(tmp)
        finally:
            bpy.data.images.remove(tmp)
    return None if out is None else out[..., :3]


def _tile_pixels(image, path):
    """The pixels of one UDIM tile's file (loaded as a temporary image with the tiled
    image's colour space), or None."""
    try:
        tmp = bpy.data.images.load(bpy.path.abspath(path), check_existing=False)
    except RuntimeError:
        return None
    try:
        tmp.colorspace_settings.name = image.colorspace_settings.name
        tmp.alpha_mode = image.alpha_mode
        return _pixels(tmp)
    finally:
        bpy.data.images.remove(tmp)

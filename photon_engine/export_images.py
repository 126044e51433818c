"""Images of Image Texture nodes -> the scene's Textures, each image read once per export.

Used by the node reader (export_nodes.NodeReader.image_input): an Image Texture feeding a
colour input becomes a texture index; ``ImageTable.textures()`` packs them for the core.
"""

from __future__ import annotations

import numpy as np

from ..core.materials.textures import srgb_to_linear
from ..core.scene.contract import Textures

DEFAULT_GREY = 0.8
"""Albedo used for a missing image (Cycles' default surface)."""


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

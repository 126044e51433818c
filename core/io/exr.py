"""Image output: multilayer 32-bit float OpenEXR laid out like Blender's, and PNG previews.

Blender 5.0 writes a multilayer EXR as a multi-part file: one part per pass, named
``<ViewLayer>.<Pass>``, with channels ``<ViewLayer>.<Pass>.R/G/B`` (Combined also has
``.A``), ZIP compression, float32 (checked against a Cycles render saved by bpy 5.0.1).
``write_exr`` does the same, so tools that read Blender's files read ours.
"""

from __future__ import annotations

import os

import numpy as np

from ..passes import BLENDER_PASS_NAMES

_CHANNEL_ORDER = {"R": 0, "G": 1, "B": 2, "A": 3}


def _blender_name(key: str) -> str:
    return BLENDER_PASS_NAMES.get(key, key[:1].upper() + key[1:])


def write_exr(path: str, passes: dict[str, np.ndarray], view_layer: str = "ViewLayer",
              metadata: dict[str, str] | None = None) -> str:
    """Write passes {name: (H, W, 3) float} as a multilayer float32 EXR; returns the path.

    Our pass keys ("combined", "emission", ...) become Blender's pass names ("Combined",
    "Emission", ...; see ``passes.BLENDER_PASS_NAMES``); other keys are capitalised.
    "combined" gains an alpha channel of 1 (an opaque render), like Blender's Combined.
    metadata: extra string header attributes (e.g. {"Scene": "Scene", "Frame": "001"}).
    """
    import OpenEXR

    if not passes:
        raise ValueError("write_exr needs at least one pass")
    shapes = {k: np.shape(v) for k, v in passes.items()}
    first = next(iter(shapes.values()))
    for k, s in shapes.items():
        if len(s) != 3 or s[2] not in (3, 4) or s[:2] != first[:2]:
            raise ValueError(f"pass '{k}' must be (H, W, 3) like the others {first}, got {s}")
    # Combined first, as Blender writes it.
    keys = sorted(passes, key=lambda k: (k != "combined", list(passes).index(k)))
    parts = []
    for i, key in enumerate(keys):
        rgb = np.asarray(passes[key], np.float32)
        name = f"{view_layer}.{_blender_name(key)}"
        channels = {f"{name}.{c}": np.ascontiguousarray(rgb[:, :, j]) for j, c in enumerate("RGB")}
        if rgb.shape[2] == 4:
            channels[f"{name}.A"] = np.ascontiguousarray(rgb[:, :, 3])
        elif key == "combined":
            channels[f"{name}.A"] = np.ones(rgb.shape[:2], np.float32)
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        if i == 0:
            header["BlenderMultiChannel"] = "Blender V2.55.1 and newer"
            header["Software"] = "Photon Map"
            for k, v in (metadata or {}).items():
                header[str(k)] = str(v)
        parts.append(OpenEXR.Part(header, channels, name))
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    with OpenEXR.File(parts) as f:
        f.write(path)
    return path


def read_exr(path: str, strip_view_layer: bool = True) -> dict[str, np.ndarray]:
    """Read an EXR (ours, Blender's, single- or multi-part) into {layer: (H, W, C) float32}.

    Channels ``<layer>.R/G/B/A`` are grouped per layer in R, G, B, A order (other channel
    letters follow, sorted). With ``strip_view_layer`` and every layer named
    ``<view layer>.<pass>`` with the same view layer, the keys are the pass names
    ("Combined", "Emission", ...). Plain ``R/G/B`` channels give the key "".
    """
    import OpenEXR

    layers: dict[str, dict[str, np.ndarray]] = {}
    with OpenEXR.File(path, separate_channels=True) as f:
        for part in f.parts:
            for cname, ch in part.channels.items():
                layer, _, letter = cname.rpartition(".")
                layers.setdefault(layer, {})[letter] = np.array(ch.pixels, np.float32, copy=True)
    out = {}
    for layer, chans in layers.items():
        order = sorted(chans, key=lambda c: (_CHANNEL_ORDER.get(c, 4), c))
        out[layer] = np.stack([chans[c] for c in order], axis=-1)
    if strip_view_layer and out:
        prefixes = {k.split(".", 1)[0] for k in out if "." in k}
        if len(prefixes) == 1 and all("." in k for k in out):
            out = {k.split(".", 1)[1]: v for k, v in out.items()}
    return out


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear Rec.709 radiance -> sRGB-encoded values in [0, 1] (float32).

    This is Blender's "Standard" view transform (no Filmic/AgX tone mapping, exposure 0,
    gamma 1): clip to [0, 1], then the piecewise sRGB curve.
    """
    x = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return y.astype(np.float32)


def save_png(path: str, rgb: np.ndarray) -> str:
    """Write a linear (H, W, 3) image as an 8-bit sRGB PNG ("Standard" view); returns path.

    matplotlib is imported here, only when a PNG is wanted.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] < 3:
        raise ValueError(f"save_png needs an (H, W, 3) image, got {img.shape}")
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    encoded = np.round(srgb_encode(img[:, :, :3]) * 255.0).astype(np.uint8)
    plt.imsave(path, encoded)
    return path

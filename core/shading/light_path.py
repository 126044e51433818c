"""The Light Path node's answers at a hit: what ray reached the point (docs/shading.md,
"Light Path").

``ShadingInputs.light_path`` is (N, COUNT) float32, one column per output of Cycles'
Light Path node (Blender 5.2, in the node's order): flags 0 / 1, Ray Length in metres
(the hit distance from the ray's origin), the depths as counts. Each caller fills it
for the rays it traces with the helpers below; a program reads column c through
``SOURCE_LIGHT_PATH`` with index c.

Per context (Cycles' ``svm_node_light_path`` and the path flags of path_state_next):
- ``camera``: a camera ray's first hit: Is Camera Ray 1, Ray Length the hit distance
  (from the near clip plane, as Cycles' camera rays), depths 0;
- ``after_bounce``: a hit after a bounce of the given kind (the camera paths beyond a
  mirror or glass: singular, glossy; final-gather hits: diffuse reflection, depth 1):
  Cycles sets Is Glossy Ray with Is Singular Ray, Reflection / Transmission from the
  lobe, and counts the bounce in Ray Depth and the kind's own depth (a transmission in
  Transmission Depth too);
- ``shadow``: a shadow ray's hit (the transmittance through cut-outs): Is Shadow Ray 1
  only (Cycles evaluates shadow-ray shaders with PATH_RAY_SHADOW alone), Ray Length the
  segment's distance; Ray Depth 0 (we do not know the bounce of the vertex the shadow
  ray leaves; Cycles reads it there);
- ``emission_sample``: light sampling and photon emission at a textured emitter: every
  flag 0, as Cycles' light samples (PATH_RAY_EMISSION alone), Ray Length 0.
Never answered (always 0, reported by the compiler when read): Is Volume Scatter Ray and
Transparent Depth. Portal Depth is 0: there are no portals.
"""

from __future__ import annotations

import numpy as np

OUTPUTS = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray",
           "Is Singular Ray", "Is Reflection Ray", "Is Transmission Ray",
           "Is Volume Scatter Ray", "Ray Length", "Ray Depth", "Diffuse Depth",
           "Glossy Depth", "Transparent Depth", "Transmission Depth", "Portal Depth")
"""The Light Path node's outputs, in its order (Blender 5.2; 4.2 has no Portal Depth)."""
COUNT = len(OUTPUTS)
(CAMERA, SHADOW, DIFFUSE, GLOSSY, SINGULAR, REFLECTION, TRANSMISSION, VOLUME_SCATTER,
 RAY_LENGTH, RAY_DEPTH, DIFFUSE_DEPTH, GLOSSY_DEPTH, TRANSPARENT_DEPTH, TRANSMISSION_DEPTH,
 PORTAL_DEPTH) = range(COUNT)
UNANSWERED = ("Is Volume Scatter Ray", "Transparent Depth")
"""Outputs the engine does not track: they read 0 (reported by the compiler)."""

BOUNCE_DIFFUSE, BOUNCE_GLOSSY, BOUNCE_SINGULAR = range(3)


def _length(n, length) -> np.ndarray:
    return np.broadcast_to(np.nan_to_num(np.asarray(length, np.float64), nan=0.0,
                                         posinf=0.0), (n,))


def empty(n: int) -> np.ndarray:
    """(n, COUNT) float32 zeros: no flag, length and depths 0 (``emission_sample``)."""
    return np.zeros((n, COUNT), np.float32)


def camera(length) -> np.ndarray:
    """(N, COUNT) float32 for camera rays' first hits at distances length (N,) metres."""
    length = np.atleast_1d(length)
    out = empty(length.shape[0])
    out[:, CAMERA] = 1.0
    out[:, RAY_LENGTH] = _length(length.shape[0], length)
    return out


def shadow(length) -> np.ndarray:
    """(N, COUNT) float32 for shadow rays' hits at distances length (N,) metres from the
    segment's origin."""
    length = np.atleast_1d(length)
    out = empty(length.shape[0])
    out[:, SHADOW] = 1.0
    out[:, RAY_LENGTH] = _length(length.shape[0], length)
    return out


def with_length(path, length) -> np.ndarray:
    """(N, COUNT) float32: a copy of the contexts path (N, COUNT) with Ray Length set to
    length (N,) metres (a ray's segment behind a cut-out it passed)."""
    out = np.array(path, np.float32)
    out[:, RAY_LENGTH] = _length(out.shape[0], length)
    return out


def emission_sample(n: int) -> np.ndarray:
    """(n, COUNT) float32 for light samples and photon emission on textured emitters."""
    return empty(n)


def after_bounce(length, kind, transmitted, depth, diffuse_depth=0, glossy_depth=0,
                 transmission_depth=0) -> np.ndarray:
    """(N, COUNT) float32 for hits of rays leaving a bounce: length (N,) metres; kind
    BOUNCE_* (a scalar or (N,)); transmitted (N,) bool, the bounce went through the
    surface; depth, diffuse_depth, glossy_depth, transmission_depth (scalars or (N,)) the
    bounces before, this one included (Cycles counts at the scatter)."""
    length = np.atleast_1d(length)
    n = length.shape[0]
    kind = np.broadcast_to(np.asarray(kind), (n,))
    tr = np.broadcast_to(np.asarray(transmitted, bool), (n,))
    out = empty(n)
    out[:, DIFFUSE] = kind == BOUNCE_DIFFUSE
    out[:, GLOSSY] = kind != BOUNCE_DIFFUSE
    out[:, SINGULAR] = kind == BOUNCE_SINGULAR
    out[:, REFLECTION] = ~tr
    out[:, TRANSMISSION] = tr
    out[:, RAY_LENGTH] = _length(n, length)
    out[:, RAY_DEPTH] = depth
    out[:, DIFFUSE_DEPTH] = diffuse_depth
    out[:, GLOSSY_DEPTH] = glossy_depth
    out[:, TRANSMISSION_DEPTH] = transmission_depth
    return out

"""Denoising feature passes as Cycles defines them (kernel/film/denoising_passes.h), for
the compositor's Denoise node (OpenImageDenoise): "denoising_albedo" and
"denoising_normal", (H, W, 3) float32, the means over each pixel's camera samples.

Along a camera path, at each surface hit until the features are written:
- a lobe is diffuse-like when it is diffuse or its GGX alpha exceeds 0.075 (Cycles:
  alpha_x alpha_y > 0.075^2), specular-like otherwise; its weight is its colour's mean;
- when diffuse-like lobes hold more than a quarter of the weight (or there is none), the
  albedo feature is the feature throughput x the diffuse-like colours (textured diffuse
  albedo included), the normal feature the shading normal in camera space (x right,
  y up, z forward: Cycles' camera space), and the path writes no more;
- otherwise the feature throughput is multiplied by the specular-like colours and the
  path goes on through the mirror or glass.
Paths that escape, or end before writing, leave both features 0 (the background has no
albedo or normal there either).
"""

from __future__ import annotations

import numpy as np

FEATURES = ("denoising_albedo", "denoising_normal")

ROUGH_ALPHA = 0.075
"""GGX alpha above which a specular lobe counts as diffuse-like (Cycles' threshold)."""


class FeatureAccumulator:
    """Per-sample features of one tile: albedo, normal (N, 3) float64, the feature
    throughput (N, 3) and whether each sample has written (N,) bool."""

    def __init__(self, n: int, camera_axes):
        self.albedo = np.zeros((n, 3))
        self.normal = np.zeros((n, 3))
        self.throughput = np.ones((n, 3))
        self.written = np.zeros(n, bool)
        right, up, back = camera_axes
        self.to_camera = np.stack([right, up, -back])  # (3, 3): world -> camera space

    def surface(self, rows, diffuse, specular, transmission, alpha, normal):
        """Hits of the samples ``rows`` (K,): diffuse albedo (K, 3) (textured), specular
        and transmission colours (K, 3), their GGX alpha (K,), shading normals (K, 3)."""
        todo = ~self.written[rows]
        if not np.any(todo):
            return
        rows = rows[todo]
        diffuse, specular, transmission = diffuse[todo], specular[todo], transmission[todo]
        rough = (alpha[todo] > ROUGH_ALPHA)[:, None]
        glossy = specular + transmission
        diffuse_like = diffuse + np.where(rough, glossy, 0.0)
        specular_like = np.where(rough, 0.0, glossy)
        weight = diffuse.mean(axis=1) + glossy.mean(axis=1)
        nonspecular = diffuse_like.mean(axis=1)
        write = (weight == 0.0) | (4.0 * nonspecular > weight)
        w = rows[write]
        self.albedo[w] = self.throughput[w] * diffuse_like[write]
        self.normal[w] = normal[todo][write] @ self.to_camera.T
        self.written[w] = True
        go = rows[~write]
        self.throughput[go] *= specular_like[~write]

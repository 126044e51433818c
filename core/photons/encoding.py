"""Compact codes for a photon's power and incident direction (Jensen's "compact photon").

Power (flux): three float16 numbers, 6 bytes, after multiplying the whole map by one
power-of-two ``scale`` chosen so that the map's largest channel lands in [2^14, 2^15).
Every channel keeps its own exponent, so each channel is exact to 2^-11 (0.049 %) of
ITSELF for all values down to 2^-29 (1.9e-9) of the map's largest channel; smaller values
(far below anything visible) keep an absolute error under 2^-39 of that largest channel.
Zero encodes to zero, the code is never negative, and the scale is a power of two, so
decoding is exact arithmetic.

Why not Jensen's 4-byte RGBE: its three 8-bit mantissas share one exponent, so only the
largest channel is exact to 2^-8 of itself; a channel at a fraction f of the largest has
a relative error up to 2^-8 / f (5 % at f = 0.08), which misses "power within 1 %" for
any saturated colour (a caustic through tinted glass). Two more bytes buy per-channel
accuracy and still fit the 24-byte budget (see ``photon_map.BYTES_PER_PHOTON``).

Direction: the octahedral map (Meyer et al. 2010; Cigolle et al. 2014, "oct32"), two
uint16 per unit vector, 4 bytes; measured maximum error 0.0037 degrees (4 million random
directions, tests/core/photons/test_photon_map.py).

numpy encoders / decoders work on whole arrays; ``half_to_float`` and ``oct_decode`` are
numba-callable scalars for kernels that read the compact arrays directly.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

_OCT_MAX = 65535.0


def flux_scale(flux: np.ndarray) -> float:
    """The power of two that puts the largest channel of ``flux`` in [2^14, 2^15).

    flux: (N, 3) finite, non-negative, watts. Returns 1.0 for an empty or all-zero map.
    """
    peak = float(flux.max()) if flux.size else 0.0
    if peak <= 0.0:
        return 1.0
    return math.ldexp(1.0, 14 - math.frexp(peak)[1] + 1)


def encode_flux(flux: np.ndarray, scale: float) -> np.ndarray:
    """(N, 3) watts -> (N, 3) uint16 float16 bit patterns of ``flux * scale``.

    numpy rounds float64 to float16 to nearest, ties to even.
    """
    scaled = np.asarray(flux, dtype=np.float64) * scale
    return scaled.astype(np.float16).view(np.uint16)


def decode_flux(codes: np.ndarray, scale: float) -> np.ndarray:
    """(N, 3) uint16 codes -> (N, 3) float32 watts."""
    return codes.view(np.float16).astype(np.float32) * np.float32(1.0 / scale)


def encode_direction(directions: np.ndarray) -> np.ndarray:
    """(N, 3) non-zero vectors -> (N, 2) uint16 octahedral codes (length is ignored).

    Raises ValueError if a vector is zero or not finite.
    """
    d = np.ascontiguousarray(directions, dtype=np.float64)
    codes = np.empty((d.shape[0], 2), np.uint16)
    bad = _encode_direction_kernel(d, codes)
    if bad:
        raise ValueError(f"directions must be finite non-zero vectors ({bad} are not)")
    return codes


def decode_direction(codes: np.ndarray) -> np.ndarray:
    """(N, 2) uint16 octahedral codes -> (N, 3) float32 unit vectors."""
    u = codes[:, 0].astype(np.float64) * (2.0 / _OCT_MAX) - 1.0
    v = codes[:, 1].astype(np.float64) * (2.0 / _OCT_MAX) - 1.0
    z = 1.0 - np.abs(u) - np.abs(v)
    t = np.maximum(-z, 0.0)
    x = u - np.where(u >= 0.0, t, -t)
    y = v - np.where(v >= 0.0, t, -t)
    d = np.stack([x, y, z], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d.astype(np.float32)


@njit(cache=True, nogil=True, inline="always")
def half_to_float(h):
    """One uint16 float16 bit pattern (non-negative, finite) -> float64, exactly."""
    e = (np.int64(h) >> 10) & 31
    m = np.int64(h) & 1023
    if e == 0:
        return m * 5.9604644775390625e-08  # subnormal: m * 2^-24
    return math.ldexp(np.float64(m + 1024), e - 25)


@njit(cache=True, nogil=True, inline="always")
def oct_decode(cu, cv):
    """Two uint16 octahedral codes -> (x, y, z) float64 unit vector."""
    u = np.float64(cu) * (2.0 / _OCT_MAX) - 1.0
    v = np.float64(cv) * (2.0 / _OCT_MAX) - 1.0
    z = 1.0 - abs(u) - abs(v)
    t = max(-z, 0.0)
    x = u - t if u >= 0.0 else u + t
    y = v - t if v >= 0.0 else v + t
    inv = 1.0 / math.sqrt(x * x + y * y + z * z)
    return x * inv, y * inv, z * inv


@njit(cache=True, nogil=True, inline="always")
def oct_encode(x, y, z):
    """A non-zero vector (float64 x, y, z) -> two uint16 octahedral codes."""
    s = abs(x) + abs(y) + abs(z)
    u = x / s
    v = y / s
    if z < 0.0:
        # The lower hemisphere folds onto the corners of the square; sign(0) is +1 here.
        fu = (1.0 - abs(v)) * (1.0 if u >= 0.0 else -1.0)
        fv = (1.0 - abs(u)) * (1.0 if v >= 0.0 else -1.0)
        u = fu
        v = fv
    return (np.uint16(np.rint((u * 0.5 + 0.5) * _OCT_MAX)),
            np.uint16(np.rint((v * 0.5 + 0.5) * _OCT_MAX)))


@njit(parallel=True, cache=True, nogil=True)
def _encode_direction_kernel(directions, out):
    """out[i] = octahedral code of directions[i]; returns the count of invalid vectors."""
    bad = 0
    for i in prange(directions.shape[0]):
        x = directions[i, 0]
        y = directions[i, 1]
        z = directions[i, 2]
        s = abs(x) + abs(y) + abs(z)
        if s > 0.0 and s < np.inf:
            out[i, 0], out[i, 1] = oct_encode(x, y, z)
        else:
            bad += 1
            out[i, 0] = 0
            out[i, 1] = 0
    return bad

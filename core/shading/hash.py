"""Cycles' hashes (intern/cycles/util/hash.h): Bob Jenkins' lookup3 ``final``/``mix`` on
uint32 keys, and the PCG 2D/3D/4D integer hashes (signed variant) Voronoi uses since
Blender 5.0. Our own numba code, bit-exact with Cycles.

uint32 arithmetic is done in int64 and masked to 32 bits after each step (numba's uint32
promotes to int64/float on mixed operations, which silently breaks the rotations).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (numba's cache per package name)

M32 = 0xFFFFFFFF
_JIT = dict(cache=True, error_model="numpy", inline="always")


@njit(**_JIT)
def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & M32


@njit(**_JIT)
def _final(a, b, c):
    c ^= b
    c = (c - _rot(b, 14)) & M32
    a ^= c
    a = (a - _rot(c, 11)) & M32
    b ^= a
    b = (b - _rot(a, 25)) & M32
    c ^= b
    c = (c - _rot(b, 16)) & M32
    a ^= c
    a = (a - _rot(c, 4)) & M32
    b ^= a
    b = (b - _rot(a, 14)) & M32
    c ^= b
    c = (c - _rot(b, 24)) & M32
    return c


@njit(**_JIT)
def _mix(a, b, c):
    a = (a - c) & M32
    a ^= _rot(c, 4)
    c = (c + b) & M32
    b = (b - a) & M32
    b ^= _rot(a, 6)
    a = (a + c) & M32
    c = (c - b) & M32
    c ^= _rot(b, 8)
    b = (b + a) & M32
    a = (a - c) & M32
    a ^= _rot(c, 16)
    c = (c + b) & M32
    b = (b - a) & M32
    b ^= _rot(a, 19)
    a = (a + c) & M32
    c = (c - b) & M32
    c ^= _rot(b, 4)
    b = (b + a) & M32
    return a, b, c


@njit(**_JIT)
def hash_uint(kx):
    """lookup3 hash of one uint32 key (any int; taken mod 2^32) -> int in [0, 2^32)."""
    a = b = c = (0xDEADBEEF + (1 << 2) + 13) & M32
    a = (a + (kx & M32)) & M32
    return _final(a, b, c)


@njit(**_JIT)
def hash_uint2(kx, ky):
    a = b = c = (0xDEADBEEF + (2 << 2) + 13) & M32
    b = (b + (ky & M32)) & M32
    a = (a + (kx & M32)) & M32
    return _final(a, b, c)


def hash_string(text: str) -> int:
    """Cycles' hash_string (util/hash.h): i = i * 37 + c over the UTF-8 bytes, mod 2^32,
    each byte read as a signed char (x86), as Cycles' ``uint c = *str++`` does."""
    i = 0
    for byte in text.encode("utf-8"):
        c = byte if byte < 128 else (byte - 256) & M32
        i = (i * 37 + c) & M32
    return i


def object_random_id(name: str, instance_id: int, is_instance: bool) -> int:
    """The uint32 random id Cycles gives an object (blender/object.cpp): the depsgraph
    instance's ``random_id`` for an instance, else hash_uint2(hash_string(name), 0)."""
    if is_instance:
        return int(instance_id) & M32
    return int(hash_uint2(hash_string(name), 0))


@njit(**_JIT)
def hash_uint3(kx, ky, kz):
    a = b = c = (0xDEADBEEF + (3 << 2) + 13) & M32
    c = (c + (kz & M32)) & M32
    b = (b + (ky & M32)) & M32
    a = (a + (kx & M32)) & M32
    return _final(a, b, c)


@njit(**_JIT)
def hash_uint4(kx, ky, kz, kw):
    a = b = c = (0xDEADBEEF + (4 << 2) + 13) & M32
    a = (a + (kx & M32)) & M32
    b = (b + (ky & M32)) & M32
    c = (c + (kz & M32)) & M32
    a, b, c = _mix(a, b, c)
    a = (a + (kw & M32)) & M32
    return _final(a, b, c)


@njit(**_JIT)
def uint_to_float_incl(n):
    """[0, 2^32 - 1] -> [0, 1], as Cycles' ``uint_to_float_incl`` (float32 rounding)."""
    return np.float64(np.float32(n) * np.float32(1.0 / 4294967295.0))


@njit(**_JIT)
def float_bits(x):
    """The IEEE bits of ``x`` rounded to float32 (Cycles' ``__float_as_uint``)."""
    return np.int64(np.float32(x).view(np.uint32))


@njit(**_JIT)
def hash_float_to_float(k):
    return uint_to_float_incl(hash_uint(float_bits(k)))


@njit(**_JIT)
def hash_float2_to_float(x, y):
    return uint_to_float_incl(hash_uint2(float_bits(x), float_bits(y)))


@njit(**_JIT)
def hash_float3_to_float(x, y, z):
    return uint_to_float_incl(hash_uint3(float_bits(x), float_bits(y), float_bits(z)))


@njit(**_JIT)
def hash_float4_to_float(x, y, z, w):
    return uint_to_float_incl(hash_uint4(float_bits(x), float_bits(y), float_bits(z),
                                         float_bits(w)))


# --- PCG (signed, masked to 31 bits at the end) -----------------------------------------

@njit(**_JIT)
def mul32(a, b):
    """(a * b) mod 2^32 for a, b in [0, 2^32): one uint64 product (it wraps mod 2^64,
    well defined, where numba's int64 product is ``mul nsw``: overflow undefined), its
    low 32 bits; twice as fast as the two 16-bit halves it replaces (issue 14)."""
    return np.int64((np.uint64(a) * np.uint64(b)) & np.uint64(M32))


@njit(**_JIT)
def _xorshift16(v):
    """v ^ (v >> 16) with v a signed int32 (arithmetic shift), mod 2^32."""
    s = v - (1 << 32) if v >= (1 << 31) else v
    return (v ^ ((s >> 16) & M32)) & M32


@njit(**_JIT)
def hash_pcg2d(x, y):
    x = (mul32(x & M32, 1664525) + 1013904223) & M32
    y = (mul32(y & M32, 1664525) + 1013904223) & M32
    x = (x + mul32(y, 1664525)) & M32
    y = (y + mul32(x, 1664525)) & M32
    x = _xorshift16(x)
    y = _xorshift16(y)
    x = (x + mul32(y, 1664525)) & M32
    y = (y + mul32(x, 1664525)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF


@njit(**_JIT)
def hash_pcg3d(x, y, z):
    x = (mul32(x & M32, 1664525) + 1013904223) & M32
    y = (mul32(y & M32, 1664525) + 1013904223) & M32
    z = (mul32(z & M32, 1664525) + 1013904223) & M32
    x = (x + mul32(y, z)) & M32
    y = (y + mul32(z, x)) & M32
    z = (z + mul32(x, y)) & M32
    x = _xorshift16(x)
    y = _xorshift16(y)
    z = _xorshift16(z)
    x = (x + mul32(y, z)) & M32
    y = (y + mul32(z, x)) & M32
    z = (z + mul32(x, y)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF


@njit(**_JIT)
def _to_unit(h):
    return np.float64(np.float32(h) * np.float32(1.0 / 2147483647.0))


@njit(**_JIT)
def hash_int2_to_float2(x, y):
    hx, hy = hash_pcg2d(x, y)
    return _to_unit(hx), _to_unit(hy)


@njit(**_JIT)
def hash_int3_to_float3(x, y, z):
    hx, hy, hz = hash_pcg3d(x, y, z)
    return _to_unit(hx), _to_unit(hy), _to_unit(hz)


@njit(**_JIT)
def hash_pcg4d(x, y, z, w):
    x = (mul32(x & M32, 1664525) + 1013904223) & M32
    y = (mul32(y & M32, 1664525) + 1013904223) & M32
    z = (mul32(z & M32, 1664525) + 1013904223) & M32
    w = (mul32(w & M32, 1664525) + 1013904223) & M32
    x = (x + mul32(y, w)) & M32
    y = (y + mul32(z, x)) & M32
    z = (z + mul32(x, y)) & M32
    w = (w + mul32(y, z)) & M32
    x = _xorshift16(x)
    y = _xorshift16(y)
    z = _xorshift16(z)
    w = _xorshift16(w)
    x = (x + mul32(y, w)) & M32
    y = (y + mul32(z, x)) & M32
    z = (z + mul32(x, y)) & M32
    w = (w + mul32(y, z)) & M32
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF, w & 0x7FFFFFFF


@njit(**_JIT)
def hash_int4_to_float4(x, y, z, w):
    hx, hy, hz, hw = hash_pcg4d(x, y, z, w)
    return _to_unit(hx), _to_unit(hy), _to_unit(hz), _to_unit(hw)

"""Cycles' hashes: lookup3 against Bob Jenkins' hashword() (lookup3.c, compiled with gcc on
this machine from the reference source; the values below are its output with initval 13,
as Cycles' hash_uint{,2,3,4}), and the PCG hash's properties."""

import numpy as np
import pytest

from core.shading import hash as h

# (k0, k1, k2, k3, number of keys, hashword(k, n, 13)) from the C reference
LOOKUP3 = [
    (0, 0, 0, 0, 1, 2501500005), (0, 0, 0, 0, 2, 3695015161), (0, 0, 0, 0, 3, 2624515579),
    (0, 0, 0, 0, 4, 479202252), (1, 2, 3, 4, 1, 1255655072), (1, 2, 3, 4, 2, 272092061),
    (1, 2, 3, 4, 3, 3100736010), (1, 2, 3, 4, 4, 92593857),
    (4294967295, 7, 2147483648, 12345, 1, 1116397369),
    (4294967295, 7, 2147483648, 12345, 2, 847497518),
    (4294967295, 7, 2147483648, 12345, 3, 2418057687),
    (4294967295, 7, 2147483648, 12345, 4, 3657684233),
    (1065353216, 1073741824, 3212836864, 42, 1, 637203474),
    (1065353216, 1073741824, 3212836864, 42, 2, 2321353991),
    (1065353216, 1073741824, 3212836864, 42, 3, 1956741384),
    (1065353216, 1073741824, 3212836864, 42, 4, 2736478550),
]


@pytest.mark.parametrize("k0, k1, k2, k3, n, expected", LOOKUP3)
def test_lookup3_matches_the_reference_c(k0, k1, k2, k3, n, expected):
    fn = {1: lambda: h.hash_uint(k0), 2: lambda: h.hash_uint2(k0, k1),
          3: lambda: h.hash_uint3(k0, k1, k2), 4: lambda: h.hash_uint4(k0, k1, k2, k3)}[n]
    assert fn() == expected


def test_float_hash_reads_float32_bits():
    """1.0f, 2.0f, -1.0f are the keys 1065353216, 1073741824, 3212836864 above."""
    assert h.float_bits(1.0) == 1065353216 and h.float_bits(-1.0) == 3212836864
    expected = 637203474 / 4294967296.0  # hash_uint(bits(1.0)) * 2^-32 (float32 1/UINT_MAX)
    assert h.hash_float_to_float(1.0) == pytest.approx(expected, rel=1e-7)
    assert h.hash_float3_to_float(1.0, 2.0, -1.0) == pytest.approx(
        1956741384 / 4294967296.0, rel=1e-7)


def test_pcg3d_is_signed_31_bit_and_matches_a_numpy_int32_twin():
    """hash_pcg3d_i on int32 with wrap-around (numpy's int32 arithmetic wraps like C's
    ignore-overflow build), v >> 16 arithmetic."""
    rng = np.random.default_rng(3)
    keys = rng.integers(-2**31, 2**31, size=(200, 3), dtype=np.int64)
    with np.errstate(over="ignore"):
        v = keys.astype(np.int32) * np.int32(1664525) + np.int32(1013904223)
        x, y, z = v[:, 0].copy(), v[:, 1].copy(), v[:, 2].copy()
        x += y * z
        y += z * x
        z += x * y
        x ^= x >> 16
        y ^= y >> 16
        z ^= z >> 16
        x += y * z
        y += z * x
        z += x * y
    want = np.stack([x, y, z], 1) & np.int32(0x7FFFFFFF)
    got = np.array([h.hash_pcg3d(int(a), int(b), int(c)) for a, b, c in keys])
    np.testing.assert_array_equal(got, want)


def test_hash_string_is_cycles_with_signed_chars():
    assert h.hash_string("") == 0
    assert h.hash_string("Ab") == 65 * 37 + 98
    # "é" is C3 A9 in UTF-8; x86's signed char makes each byte 0xFFFFFF..
    assert h.hash_string("é") == (0xFFFFFFC3 * 37 + 0xFFFFFFA9) % 2 ** 32

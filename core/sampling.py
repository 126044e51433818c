"""Reproducible random numbers and the warps that turn them into directions and points.

Random numbers are counter-based: ``u = hash(seed, pixel, sample, dimension)``. A sample's
numbers depend only on those four integers, never on the order in which rays are traced,
so an image is identical whatever the tiling, the batch sizes or the thread count.

Dimensions are 64-bit integers built with ``stream()`` from a purpose and small indices
(bounce, light, shadow sample, component), so two uses never share a number.

Warps take uniform numbers in [0, 1) and return float64 arrays. Local frames are
(tangent, bitangent, normal), built with ``orthonormal_basis``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_K_PIXEL = np.uint64(0x9E3779B97F4A7C15)
_K_SAMPLE = np.uint64(0xC2B2AE3D27D4EB4F)
_K_DIM = np.uint64(0x165667B19E3779F9)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV_2_53 = 1.0 / 9007199254740992.0

# The purposes of random dimensions (the first argument of stream()): the one table of
# them, so that no two uses share a stream. Values are part of every seeded image.
PIXEL_JITTER = 1       # camera rays' position in the pixel
LIGHT_SAMPLE = 2       # the point on a light a shadow ray aims at
WORLD_SAMPLE = 3       # the direction a shadow ray to the world takes
SPECULAR_CHOICE = 4    # mirror vs glass, reflection vs refraction on camera paths
LIGHT_PICK = 5         # which emissive triangle a shadow ray aims at
PHOTON = 6             # photon emission and scattering (per map, source, bounce)
GATHER_DIRECTION = 16  # final-gather ray directions
GATHER_LOBE = 17       # lobe choices of final-gather rays at mirrors and glass
CACHE_SAMPLE = 18      # the radiance cache's surface points
CUTOUT_CHOICE = 19     # camera rays passing a cut-out (opacity < 1)
GATHER_CUTOUT = 20     # final-gather rays passing a cut-out
VOLUME_DISTANCE = 21   # the distance along a camera segment where Volume Direct scatters
VOLUME_LIGHT = 22      # the point on a light a volume shadow ray aims at
MEDIUM_FLIGHT = 23     # photons' free flights and phase-function scattering in media
WAVELENGTH = 24        # the wavelength a photon picks at its first dispersive surface
CAMERA_WAVELENGTH = 25  # the wavelength a camera path picks at its first dispersive surface
MEDIUM_TRANSMITTANCE = 26  # ratio tracking through heterogeneous media (per call)
MEDIUM_TRACKING = 27    # delta tracking of photons and camera sub-stretches in them
MEDIUM_EMISSION = 28    # where and in which direction an emissive medium's photons start

PROGRESSIVE = 7
"""Last stream index of the progressive integrator's camera paths: keeps its visible-point
numbers apart from the photon-mapping camera pass's, which use the same purposes."""


@njit(cache=True, error_model="numpy")
def mix64(x):
    """splitmix64's finaliser: a bijective avalanche on uint64."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@njit(cache=True, error_model="numpy")
def hash_uniform(seed, pixel, sample, dim):
    """One uniform float64 in [0, 1) from four int64 counters (53 random bits)."""
    x = mix64(np.uint64(seed) ^ _K_DIM * np.uint64(dim))
    x = mix64(x ^ _K_PIXEL * np.uint64(pixel))
    x = mix64(x ^ _K_SAMPLE * np.uint64(sample))
    return np.float64(x >> _S11) * _INV_2_53


@njit(cache=True, parallel=True, error_model="numpy")
def _uniform_kernel(seed, pixel, sample, dim, out):
    for i in prange(pixel.shape[0]):
        out[i] = hash_uniform(seed, pixel[i], sample[i], dim)


# --- stratified sets: shuffled, Owen-scrambled Sobol (Burley 2020, "Practical Hash-based
# Owen Scrambling"), the kind of sampler Cycles uses ----------------------------------------
# The n samples of one pixel for one dimension pair are the first n points of the 2D Sobol
# (0, 2)-sequence, Owen-scrambled per dimension and visited in a shuffled order; the
# scrambles and the shuffle are hashes of (seed, pixel, dimension), so a sample's numbers
# still depend only on (seed, pixel, sample, dimension), and different dimension pairs are
# independent. For n a power of two every elementary interval holds one point.

_U32 = np.uint64(0xFFFFFFFF)


@njit(cache=True, error_model="numpy")
def reverse32(x):
    x = ((x >> np.uint64(1)) & np.uint64(0x55555555)) | ((x & np.uint64(0x55555555)) << np.uint64(1))
    x = ((x >> np.uint64(2)) & np.uint64(0x33333333)) | ((x & np.uint64(0x33333333)) << np.uint64(2))
    x = ((x >> np.uint64(4)) & np.uint64(0x0F0F0F0F)) | ((x & np.uint64(0x0F0F0F0F)) << np.uint64(4))
    x = ((x >> np.uint64(8)) & np.uint64(0x00FF00FF)) | ((x & np.uint64(0x00FF00FF)) << np.uint64(8))
    return ((x >> np.uint64(16)) | (x << np.uint64(16))) & _U32


@njit(cache=True, error_model="numpy")
def owen32(x, seed):
    """Nested uniform (Owen) scramble of a 32-bit fraction: reverse, Laine-Karras, reverse."""
    x = reverse32(x)
    x = (x + seed) & _U32
    x ^= (x * np.uint64(0x6C50B47C)) & _U32
    x ^= (x * np.uint64(0xB82F1E52)) & _U32
    x ^= (x * np.uint64(0xC7AFE638)) & _U32
    x ^= (x * np.uint64(0x8D22F6E6)) & _U32
    return reverse32(x)


@njit(cache=True, error_model="numpy")
def sobol1(i):
    """Second Sobol dimension (Pascal matrix) of index i, as a 32-bit fraction."""
    v = np.uint64(1) << np.uint64(31)
    r = np.uint64(0)
    while i != np.uint64(0):
        if i & np.uint64(1):
            r ^= v
        i >>= np.uint64(1)
        v ^= v >> np.uint64(1)
    return r


@njit(cache=True, error_model="numpy")
def pattern(seed, pixel, dim):
    """A 64-bit pattern id per (seed, pixel, dimension pair)."""
    x = mix64(np.uint64(seed) ^ _K_DIM * np.uint64(dim))
    return mix64(x ^ _K_PIXEL * np.uint64(pixel))


def index_bits(n: int) -> int:
    """Bits of a sample index in a set of n: ceil(log2(n)), at least 1."""
    return max(1, int(n - 1).bit_length())


@njit(cache=True, error_model="numpy")
def sobol2(index, bits, p):
    """Sample ``index`` (< 2^bits) of the shuffled, scrambled 2D Sobol set with pattern p.

    The shuffle Owen-scrambles the index and keeps its low ``bits`` bits: a permutation of
    [0, 2^bits); the per-dimension Owen scrambles then randomise every finer digit.
    """
    p32 = p & _U32
    mask = (np.uint64(1) << np.uint64(bits)) - np.uint64(1)
    i = owen32(np.uint64(index) & _U32, p32) & mask
    return sobol2_point(i, p)


@njit(cache=True, error_model="numpy")
def sobol2_point(i, p):
    """Point i (uint64 < 2^32) of the 2D Sobol sequence, Owen-scrambled per dimension by
    the pattern p, in sequence order (no index shuffle): the first n points of any n are
    stratified, what a progressive render needs."""
    x = owen32(reverse32(i), (p >> np.uint64(32)) & _U32)
    y = owen32(sobol1(i), mix64(p) & _U32)
    return np.float64(x) * 2.0 ** -32, np.float64(y) * 2.0 ** -32


@njit(cache=True, parallel=True, error_model="numpy")
def progressive2(seed, k, dim, out):
    """out (P, 2) float64: point k of each pixel's own scrambled 2D Sobol sequence (pixel
    p's pattern from (seed, p, dim)); pass k of a progressive render jitters by it."""
    i = np.uint64(k) & _U32
    for p in prange(out.shape[0]):
        out[p, 0], out[p, 1] = sobol2_point(i, pattern(seed, p, dim))


def pass_seed(seed: int, k: int) -> int:
    """The photon seed of pass k (0-based) of a progressive render, or of any other
    independent photon batch k: a splitmix64 hash of (seed, k), an int < 2^63."""
    x = (int(seed) * 0x9E3779B97F4A7C15 + (int(k) + 1) * 0xD1B54A32D192ED03) & (2**64 - 1)
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & (2**64 - 1)
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & (2**64 - 1)
    return (x ^ (x >> 31)) >> 1


@njit(cache=True, parallel=True, error_model="numpy")
def _stratified_kernel(seed, pixel, index, bits, dim, out_x, out_y):
    for i in prange(pixel.shape[0]):
        out_x[i], out_y[i] = sobol2(index[i], bits, pattern(seed, pixel[i], dim))


def stratified2(seed: int, pixel: np.ndarray, index: np.ndarray, n: int,
                dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Two (N,) float64 uniforms, stratified over the ``n`` indices of each pixel.

    index (N,) int64 in [0, n): the sample's position in its pixel's set (e.g. the camera
    sample, or sample * k + j for k light samples per camera sample). Over the n indices
    of one pixel, (x, y) is a scrambled Sobol set; different ``dim`` give independent sets.
    """
    pixel = np.ascontiguousarray(pixel, np.int64)
    index = np.ascontiguousarray(index, np.int64)
    x = np.empty(pixel.shape[0])
    y = np.empty(pixel.shape[0])
    if pixel.shape[0]:
        if int(index.min()) < 0 or int(index.max()) >= n:
            raise ValueError(f"stratified index must be in [0, {n})")
        _stratified_kernel(np.int64(seed), pixel, index, np.int64(index_bits(n)), np.int64(dim), x, y)
    return x, y


def stream(purpose: int, *indices: int) -> int:
    """A dimension id (int64 >= 0) for a purpose and small indices (bounce, light, k, comp).

    Each index must be in [0, 2^12); the packing is exact, so distinct tuples give
    distinct dimensions.
    """
    d = int(purpose)
    for i in indices:
        if not 0 <= i < 4096:
            raise ValueError(f"random stream index must be in [0, 4096), got {i}")
        d = d * 4096 + int(i)
    if d >= 2**63:
        raise ValueError("too many random stream indices")
    return d


def uniform(seed: int, pixel: np.ndarray, sample: np.ndarray, dim: int) -> np.ndarray:
    """(N,) float64 uniform numbers in [0, 1) for counters pixel (N,) and sample (N,) int64."""
    pixel = np.ascontiguousarray(pixel, np.int64)
    sample = np.ascontiguousarray(sample, np.int64)
    out = np.empty(pixel.shape[0], np.float64)
    if pixel.shape[0]:
        _uniform_kernel(np.int64(seed), pixel, sample, np.int64(dim), out)
    return out


def uniform2(seed, pixel, sample, dim) -> tuple[np.ndarray, np.ndarray]:
    """Two independent (N,) uniform arrays: dimensions 2*dim and 2*dim + 1."""
    return uniform(seed, pixel, sample, 2 * dim), uniform(seed, pixel, sample, 2 * dim + 1)


# --- warps (numba, scalar helpers inlined into the kernels of other modules) -------------

@njit(cache=True, error_model="numpy")
def basis(nx, ny, nz):
    """Tangent and bitangent (tx, ty, tz, bx, by, bz) of a unit normal (Duff et al. 2017)."""
    s = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return 1.0 + s * nx * nx * a, s * b, -s * nx, b, s + ny * ny * a, -ny


@njit(cache=True, error_model="numpy")
def to_world(lx, ly, lz, nx, ny, nz):
    """Local (x, y, z) in the frame of unit normal n -> world direction."""
    tx, ty, tz, bx, by, bz = basis(nx, ny, nz)
    return (lx * tx + ly * bx + lz * nx,
            lx * ty + ly * by + lz * ny,
            lx * tz + ly * bz + lz * nz)


@njit(cache=True, error_model="numpy")
def concentric_disk(u1, u2):
    """Uniform point on the unit disk (Shirley-Chiu concentric map): (x, y)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r = a
        phi = (np.pi / 4.0) * (b / a)
    else:
        r = b
        phi = np.pi / 2.0 - (np.pi / 4.0) * (a / b)
    return r * np.cos(phi), r * np.sin(phi)


@njit(cache=True, error_model="numpy")
def cosine_hemisphere(u1, u2):
    """Cosine-weighted direction about +Z: (x, y, z), pdf = z / pi."""
    x, y = concentric_disk(u1, u2)
    z = np.sqrt(max(0.0, 1.0 - x * x - y * y))
    return x, y, z


@njit(cache=True, error_model="numpy")
def uniform_sphere(u1, u2):
    """Uniform direction on the unit sphere, pdf = 1 / (4 pi)."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return r * np.cos(phi), r * np.sin(phi), z


@njit(cache=True, error_model="numpy")
def uniform_cone(u1, u2, one_minus_cos_max):
    """Uniform direction in the cone about +Z with 1 - cos(half angle) given.

    pdf = 1 / (2 pi one_minus_cos_max). Taking 1 - cos as input keeps tiny cones (the
    sun's 0.5 degree) exact in float64.
    """
    one_minus_cos = u1 * one_minus_cos_max
    z = 1.0 - one_minus_cos
    sin2 = one_minus_cos * (2.0 - one_minus_cos)
    r = np.sqrt(max(0.0, sin2))
    phi = 2.0 * np.pi * u2
    return r * np.cos(phi), r * np.sin(phi), z


@njit(cache=True, error_model="numpy")
def uniform_triangle(u1, u2):
    """Uniform barycentrics (b1, b2) on a triangle (square-root parameterisation)."""
    su = np.sqrt(u1)
    return su * (1.0 - u2), su * u2


@njit(cache=True, error_model="numpy")
def pick(cdf, u):
    """The index (int) a uniform u picks by the (K,) cumulative distribution cdf (float64,
    non-decreasing, K >= 1): the first j with cdf[j] > u, so that j has probability
    cdf[j] - cdf[j - 1] for u uniform in [0, cdf[-1]); the last one, K - 1, when rounding
    puts u at or beyond cdf[-1]. ``pick_many`` is its vectorised form."""
    j = np.searchsorted(cdf, u, side="right")
    if j >= cdf.shape[0]:
        j = cdf.shape[0] - 1
    return j


# --- vectorised wrappers, for tests and Python-level callers ------------------------------

@njit(cache=True, parallel=True, error_model="numpy")
def _pick_kernel(cdf, u, out):
    for i in prange(u.shape[0]):
        out[i] = pick(cdf, u[i])


@njit(cache=True, error_model="numpy")
def _vec_cosine(u1, u2, out):
    for i in range(u1.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = cosine_hemisphere(u1[i], u2[i])


@njit(cache=True, error_model="numpy")
def _vec_sphere(u1, u2, out):
    for i in range(u1.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = uniform_sphere(u1[i], u2[i])


@njit(cache=True, error_model="numpy")
def _vec_cone(u1, u2, omc, out):
    for i in range(u1.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = uniform_cone(u1[i], u2[i], omc)


@njit(cache=True, error_model="numpy")
def _vec_disk(u1, u2, out):
    for i in range(u1.shape[0]):
        out[i, 0], out[i, 1] = concentric_disk(u1[i], u2[i])


@njit(cache=True, error_model="numpy")
def _vec_basis(n, t, b):
    for i in range(n.shape[0]):
        t[i, 0], t[i, 1], t[i, 2], b[i, 0], b[i, 1], b[i, 2] = basis(n[i, 0], n[i, 1], n[i, 2])


def _pair(u1, u2):
    return np.ascontiguousarray(u1, np.float64), np.ascontiguousarray(u2, np.float64)


def sample_cosine_hemisphere(u1, u2) -> np.ndarray:
    """(N, 3) float64 local directions about +Z, pdf = z / pi."""
    u1, u2 = _pair(u1, u2)
    out = np.empty((u1.shape[0], 3))
    _vec_cosine(u1, u2, out)
    return out


def sample_uniform_sphere(u1, u2) -> np.ndarray:
    """(N, 3) float64 unit vectors, pdf = 1 / (4 pi)."""
    u1, u2 = _pair(u1, u2)
    out = np.empty((u1.shape[0], 3))
    _vec_sphere(u1, u2, out)
    return out


def sample_uniform_cone(u1, u2, one_minus_cos_max: float) -> np.ndarray:
    """(N, 3) float64 local directions about +Z within the cone, pdf = 1/(2 pi (1 - cos))."""
    u1, u2 = _pair(u1, u2)
    out = np.empty((u1.shape[0], 3))
    _vec_cone(u1, u2, float(one_minus_cos_max), out)
    return out


def sample_uniform_disk(u1, u2) -> np.ndarray:
    """(N, 2) float64 points on the unit disk, pdf = 1 / pi."""
    u1, u2 = _pair(u1, u2)
    out = np.empty((u1.shape[0], 2))
    _vec_disk(u1, u2, out)
    return out


def pick_many(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``pick`` for each of the uniforms u (N,) float64: (N,) int64 indices into the (K,)
    float64 cdf."""
    out = np.empty(u.shape[0], np.int64)
    _pick_kernel(cdf, u, out)
    return out


def orthonormal_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangents and bitangents (N, 3) float64 completing unit normals (N, 3) to a frame."""
    n = np.ascontiguousarray(normals, np.float64).reshape(-1, 3)
    t = np.empty_like(n)
    b = np.empty_like(n)
    _vec_basis(n, t, b)
    return t, b

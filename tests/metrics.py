"""Image error metrics shared by the tests and the benchmarks (one definition each)."""

import numpy as np


def rel_mse(a, b) -> float:
    """Relative mean squared error of image ``a`` against the reference ``b`` (same shape,
    any float dtype; computed in float64): mean((a - b)^2 / (b^2 + 0.01)) over pixels and
    channels. The 0.01 keeps black reference pixels from dominating (the convention of
    docs/tradeoff.md's tables)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return float(np.mean((a - b) ** 2 / (b * b + 0.01)))

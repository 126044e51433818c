"""The contract's array checks and its error (shared by contract.py and media.py, which
contract.py imports)."""

from __future__ import annotations

import numpy as np


class SceneError(ValueError):
    """A scene that cannot be rendered; the message names the field and the value."""


MAX_MAGNITUDE = 1e30
"""Largest magnitude of any float input: radiance, power, lengths. Beyond it float32 sums
of the passes (and squares of lengths) overflow to infinity."""


def check_array(name, a, shape, *, dtype=None, nonnegative=False, finite=True, labels=None,
                at_most=None):
    """Validate one array: shape (None = any length), dtype kind, finite and within
    +-MAX_MAGNITUDE, >= 0, <= at_most."""
    if not isinstance(a, np.ndarray):
        raise SceneError(f"{name} must be a numpy array, got {type(a).__name__}")
    if a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise SceneError(f"{name} must have shape {want}, got {a.shape}")
    if dtype is not None and a.dtype != dtype:
        raise SceneError(f"{name} must be {np.dtype(dtype).name}, got {a.dtype.name}")
    if finite and a.dtype.kind == "f" and a.size and not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        where = label(labels, bad[0])
        raise SceneError(f"{name}{where} holds a non-finite value {a[tuple(bad)]} at index {tuple(bad)}")
    if finite and a.dtype.kind == "f" and a.size and np.any(np.abs(a) > MAX_MAGNITUDE):
        bad = np.argwhere(np.abs(a) > MAX_MAGNITUDE)[0]
        where = label(labels, bad[0])
        raise SceneError(f"{name}{where} holds {a[tuple(bad)]} at index {tuple(bad)}, beyond "
                         f"the largest magnitude {MAX_MAGNITUDE:g} the renderer accepts")
    if nonnegative and a.size and np.any(a < 0):
        bad = np.argwhere(a < 0)[0]
        where = label(labels, bad[0])
        raise SceneError(f"{name}{where} must be >= 0, got {a[tuple(bad)]} at index {tuple(bad)}")
    if at_most is not None and a.size and np.any(a > at_most):
        bad = np.argwhere(a > at_most)[0]
        where = label(labels, bad[0])
        raise SceneError(f"{name}{where} must be <= {at_most:g}, got {a[tuple(bad)]} at index {tuple(bad)}")



def label(labels, i):
    if labels is not None and 0 <= i < len(labels):
        return f" of '{labels[i]}'"
    return ""

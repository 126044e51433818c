"""Keep numba's on-disk cache apart for each package name the core is imported under.

The same files load as ``core`` (tests/core, benchmarks), ``photon_map.core`` (tests/blender,
the CLI) and ``bl_ext.user_default.photon_map.core`` (installed in Blender). numba's default
in-tree cache is keyed by file, not by module name, and a cached kernel re-imports the
module it was compiled in by name, so a cache written under one name breaks loading
under another ("No module named 'photon_map'"). This locator puts each package's cache
beside each source in ``__pycache__/numba_<package>_<digest>/``, where the digest covers every
core source file, subpackages included (see _sources_digest).

Import this module before any ``@njit(cache=True)`` in the core is decorated
(``core/__init__.py`` does; every kernel module also imports it, which is harmless).
"""

from __future__ import annotations

import hashlib
import os

from numba.core import caching

_CORE_DIR = os.path.dirname(os.path.abspath(__file__))


def core_sources() -> list[str]:
    """Every core source file (core/*.py and the subpackages' files), relative to core/
    with "/" separators, sorted."""
    found = []
    for folder, dirs, files in os.walk(_CORE_DIR):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        rel = os.path.relpath(folder, _CORE_DIR)
        for name in files:
            if name.endswith(".py"):
                found.append(name if rel == "." else f"{rel}/{name}".replace(os.sep, "/"))
    return sorted(found)


def _sources_digest() -> str:
    """A short hash of every core source file (core_sources): kernels inline functions
    from other files (photons/estimate.py inlines photons/kdtree.py's search), and numba's
    own cache only checks the defining file's timestamp, so any change anywhere in core/
    starts a fresh cache."""
    h = hashlib.sha1()
    for name in core_sources():
        with open(os.path.join(_CORE_DIR, *name.split("/")), "rb") as f:
            h.update(name.encode() + b"\0" + f.read())
    return h.hexdigest()[:12]


_DIGEST = _sources_digest()


class PackageCacheLocator(caching.InTreeCacheLocator):
    """In-tree cache under ``__pycache__/numba_<package>`` for functions defined in core/."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        package = (py_func.__module__ or "unknown").rpartition(".")[0] or "top"
        self._cache_path = os.path.join(os.path.dirname(py_file), "__pycache__",
                                        "numba_" + package.replace(".", "_") + "_" + _DIGEST)

    @classmethod
    def from_function(cls, py_func, py_file):
        path = os.path.abspath(py_file)
        if os.path.commonpath([path, _CORE_DIR]) != _CORE_DIR:
            return None
        return super().from_function(py_func, py_file)


def install() -> None:
    """Put the locator first in numba's list (idempotent)."""
    classes = caching.CacheImpl._locator_classes
    if PackageCacheLocator not in classes:
        classes.insert(0, PackageCacheLocator)


install()

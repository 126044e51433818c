"""Keep numba's on-disk cache apart for each package name the core is imported under.

The same files load as ``core`` (tests/core, benchmarks), ``photon_map.core`` (tests/blender,
the CLI) and ``bl_ext.user_default.photon_map.core`` (installed in Blender). numba's default
in-tree cache is keyed by file, not by module name, and a cached kernel re-imports the
module it was compiled in by name, so a cache written under one name breaks loading
under another ("No module named 'photon_map'"). This locator puts each package's cache
beside each source in ``__pycache__/numba_<package>_<digest>/``, where the digest covers every
core source file, subpackages included (see _sources_digest).

When that folder cannot be written (a read-only install, a read-only or unset HOME holding
the extension), kernels would be compiled again in every process (~35 s a render): the
locator then says so once on stderr, naming the folder, and keeps the cache in a writable
fallback instead (``fallback_root``: ``NUMBA_CACHE_DIR`` if set, else the system temporary
folder), keyed by package, digest and source file so that it is found again by the next
process.

Import this module before any ``@njit(cache=True)`` in the core is decorated
(``core/__init__.py`` does; every kernel module also imports it, which is harmless).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile

from numba.core import caching

_CORE_DIR = os.path.dirname(os.path.abspath(__file__))


def core_sources() -> list[str]:
    """Every core source file (core/*.py and the subpackages' files) and every data file
    kernels freeze into their code as constants (*.npz: materials/albedo_tables.npz),
    relative to core/ with "/" separators, sorted."""
    found = []
    for folder, dirs, files in os.walk(_CORE_DIR):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        rel = os.path.relpath(folder, _CORE_DIR)
        for name in files:
            if name.endswith((".py", ".npz")):
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


def _cache_name(py_func) -> str:
    """``numba_<package>_<digest>``: the package the core was imported under, and the
    digest of its sources."""
    package = (py_func.__module__ or "unknown").rpartition(".")[0] or "top"
    return "numba_" + package.replace(".", "_") + "_" + _DIGEST


def fallback_root() -> str:
    """The folder the cache goes to when the in-tree one cannot be written:
    ``NUMBA_CACHE_DIR`` when set, else the system temporary folder."""
    return os.environ.get("NUMBA_CACHE_DIR") or tempfile.gettempdir()


_reported: list[str] = []
"""The unwritable in-tree folder already reported (the message is said once a process)."""


def _report_unwritable(folder: str, fallback: str) -> None:
    if _reported:
        return
    _reported.append(folder)
    print(f"Photon Map: the numba cache folder {folder} is not writable; compiled kernels "
          f"are kept in {fallback} instead", file=sys.stderr, flush=True)


class PackageCacheLocator(caching.InTreeCacheLocator):
    """In-tree cache under ``__pycache__/numba_<package>`` for functions defined in core/;
    ``FallbackCacheLocator`` when that folder cannot be written."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(os.path.dirname(py_file), "__pycache__",
                                        _cache_name(py_func))

    @classmethod
    def from_function(cls, py_func, py_file):
        path = os.path.abspath(py_file)
        if os.path.commonpath([path, _CORE_DIR]) != _CORE_DIR:
            return None
        found = super().from_function(py_func, py_file)
        if found is not None or not os.path.exists(py_file):
            return found
        fallback = FallbackCacheLocator.from_function(py_func, py_file)
        if fallback is not None:
            _report_unwritable(os.path.join(os.path.dirname(path), "__pycache__"),
                               fallback.root)
        return fallback


class FallbackCacheLocator(caching.InTreeCacheLocator):
    """``<fallback_root()>/photon_map_numba/numba_<package>_<digest>``: the same folder for
    every copy of the same sources (the digest), so a read-only install compiles once, not
    once a process (numba's index files are named by source file, so the modules of one
    package share the folder)."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self.root = os.path.join(fallback_root(), "photon_map_numba")
        self._cache_path = os.path.join(self.root, _cache_name(py_func))


def install() -> None:
    """Put the locator first in numba's list (idempotent)."""
    classes = caching.CacheImpl._locator_classes
    if PackageCacheLocator not in classes:
        classes.insert(0, PackageCacheLocator)


install()

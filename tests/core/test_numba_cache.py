"""numba's on-disk cache (core/_numba_cache.py) covers every core package: its digest reads
the sources of the subpackages too, and its locator takes kernels defined in them."""

import io
import pathlib

from core import _numba_cache
from core.photons import kdtree
from core.scene import geometry

CORE = pathlib.Path(_numba_cache.__file__).resolve().parent


def test_the_digest_reads_every_core_source_file():
    on_disk = sorted(p.relative_to(CORE).as_posix() for p in CORE.rglob("*.py")
                     if "__pycache__" not in p.parts)
    assert _numba_cache.core_sources() == on_disk
    assert "photons/kdtree.py" in on_disk and "integrators/sppm.py" in on_disk


def test_the_digest_changes_with_a_subpackage_file(monkeypatch):
    before = _numba_cache._sources_digest()
    path = CORE / "photons" / "kdtree.py"
    real_open = open

    def edited_open(name, mode="r", *a, **kw):
        f = real_open(name, mode, *a, **kw)
        if pathlib.Path(name).resolve() == path and "b" in mode:
            data = f.read() + b"\n# edited\n"
            f.close()
            return io.BytesIO(data)
        return f

    monkeypatch.setattr("builtins.open", edited_open)
    assert _numba_cache._sources_digest() != before


def test_the_locator_takes_subpackage_kernels_and_keeps_packages_apart():
    for fn in (kdtree.nearest_kernel.py_func, geometry.offset_eps.py_func):
        loc = _numba_cache.PackageCacheLocator.from_function(fn, fn.__code__.co_filename)
        assert loc is not None
        path = pathlib.Path(loc.get_cache_path())
        assert path.parent == pathlib.Path(fn.__code__.co_filename).parent / "__pycache__"
        assert path.name == f"numba_{fn.__module__.rpartition('.')[0].replace('.', '_')}_" \
                            f"{_numba_cache._DIGEST}"
    # A function outside core/ is not this locator's.
    assert _numba_cache.PackageCacheLocator.from_function(
        test_the_digest_reads_every_core_source_file, __file__) is None

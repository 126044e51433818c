"""numba's on-disk cache (core/_numba_cache.py) covers every core package: its digest reads
the sources of the subpackages too, and its locator takes kernels defined in them."""

import io
import pathlib

import pytest

from core import _numba_cache
from core.photons import kdtree
from core.scene import geometry

CORE = pathlib.Path(_numba_cache.__file__).resolve().parent


def test_the_digest_reads_every_core_source_file():
    on_disk = sorted(p.relative_to(CORE).as_posix()
                     for pattern in ("*.py", "*.npz") for p in CORE.rglob(pattern)
                     if "__pycache__" not in p.parts)
    assert _numba_cache.core_sources() == on_disk
    assert "photons/kdtree.py" in on_disk and "integrators/sppm.py" in on_disk
    # the albedo tables are frozen into the kernels as constants
    assert "materials/albedo_tables.npz" in on_disk


@pytest.mark.parametrize("edited", ["photons/kdtree.py", "materials/albedo_tables.npz"])
def test_the_digest_changes_with_a_subpackage_file(monkeypatch, edited):
    before = _numba_cache._sources_digest()
    path = CORE / edited
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


# --- a cache folder that cannot be written (issue 11 part 6) ----------------------------------

def test_the_fallback_is_numba_cache_dir_then_the_temporary_folder(monkeypatch, tmp_path):
    import tempfile
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert _numba_cache.fallback_root() == str(tmp_path)
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert _numba_cache.fallback_root() == tempfile.gettempdir()


def test_an_unwritable_in_tree_folder_falls_back_and_is_said_once(monkeypatch, tmp_path, capsys):
    from numba.core import caching
    real = caching._CacheLocator.ensure_cache_path

    def in_tree_read_only(self):
        if str(tmp_path) not in self.get_cache_path():
            raise PermissionError(self.get_cache_path())
        return real(self)

    monkeypatch.setattr(caching._CacheLocator, "ensure_cache_path", in_tree_read_only)
    monkeypatch.setattr(_numba_cache, "_reported", [])
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    paths = []
    for fn in (kdtree.nearest_kernel.py_func, geometry.offset_eps.py_func):
        loc = _numba_cache.PackageCacheLocator.from_function(fn, fn.__code__.co_filename)
        assert isinstance(loc, _numba_cache.FallbackCacheLocator)
        paths.append(pathlib.Path(loc.get_cache_path()))
    assert paths == [tmp_path / "photon_map_numba" / f"numba_core_{sub}_{_numba_cache._DIGEST}"
                     for sub in ("photons", "scene")]
    err = capsys.readouterr().err
    folder = pathlib.Path(kdtree.__file__).parent / "__pycache__"
    assert err == (f"Photon Map: the numba cache folder {folder} is not writable; compiled "
                   f"kernels are kept in {tmp_path / 'photon_map_numba'} instead\n")


RENDER_FROM_A_READ_ONLY_COPY = r"""
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from core import render
from core.scene import shapes
from core.scene.contract import LIGHT_POINT, Lights, Materials, Scene
from core.settings import RenderSettings
floor = shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0])
scene = Scene(shapes.assemble([(floor, 0)]), Materials.from_list([{"diffuse": [0.8, 0.8, 0.8]}]),
              Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 1], "power": 100.0}]),
              shapes.pinhole([0, -3, 2], [0, 0, 0], 8, 8, 0.6))
out = render(scene, RenderSettings(samples=1, global_photons=500, caustic_photons=0,
                                   final_gather_rays=4))
print("mean", float(out.passes["combined"].mean()))
"""


def test_a_read_only_install_renders_says_so_once_and_caches_in_the_fallback(tmp_path):
    """The package copied to a folder nobody may write (mode 0555; when the tests run as
    root, who writes anywhere, the child runs without CAP_DAC_OVERRIDE through setpriv):
    the render works, the message comes once, the kernels land in the fallback.
    NUMBA_CACHE_DIR points at a folder kept between runs of the suite, seeded from this
    process's own in-tree cache."""
    import os
    import shutil
    import subprocess
    import sys
    import tempfile

    install = tmp_path / "install"
    shutil.copytree(CORE, install / "core", ignore=shutil.ignore_patterns("__pycache__"))
    for folder, dirs, files in os.walk(install):
        for name in files:
            os.chmod(os.path.join(folder, name), 0o444)
    for folder, dirs, files in os.walk(install, topdown=False):
        os.chmod(folder, 0o555)
    os.chmod(tmp_path, 0o755)
    fallback = pathlib.Path(tempfile.gettempdir()) / "photon_map_test_fallback"
    fallback.mkdir(exist_ok=True)
    os.chmod(fallback, 0o1777)
    # Seed the fallback with this process's in-tree caches of the same sources (the copy
    # keeps the files' timestamps, which numba's index checks), so the child need not
    # compile everything cold (~70 s); scatter's entries are removed, so the child must
    # compile and write those to the fallback, which the last assertion checks.
    kept = fallback / "photon_map_numba" / f"numba_core_photons_{_numba_cache._DIGEST}"
    for cache in CORE.rglob(f"__pycache__/numba_core_*_{_numba_cache._DIGEST}"):
        shutil.copytree(cache, fallback / "photon_map_numba" / cache.name, dirs_exist_ok=True)
    for stale in kept.glob("scatter.*"):
        stale.unlink()
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "NUMBA_CACHE_DIR")}
    env["NUMBA_CACHE_DIR"] = str(fallback)
    command = [sys.executable, "-c", RENDER_FROM_A_READ_ONLY_COPY, str(install)]
    if os.geteuid() == 0:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            pytest.skip("running as root without setpriv: every folder is writable")
        command = [setpriv, "--bounding-set=-dac_override,-fowner", "--"] + command
    try:
        done = subprocess.run(command, capture_output=True, text=True, env=env,
                              cwd=str(install), timeout=600)
    finally:
        for folder, dirs, files in os.walk(install):
            os.chmod(folder, 0o755)
    assert done.returncode == 0, done.stderr
    message = (f"Photon Map: the numba cache folder {install / 'core'}/")
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("Photon Map:")]
    assert len(lines) == 1 and lines[0].startswith(message), done.stderr
    assert lines[0].endswith(f"is not writable; compiled kernels are kept in "
                             f"{fallback / 'photon_map_numba'} instead"), lines
    assert float(done.stdout.split()[-1]) > 0
    assert any(kept.glob("scatter.*.nbi"))
    assert not any((install / "core").rglob("*.nbi"))

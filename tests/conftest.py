"""Test bootstrap.

- ``tests/core`` imports the renderer as the top-level package ``core`` (no Blender).
- ``tests/blender`` imports the extension as ``photon_map`` (the repo root loaded as a
  package, as Blender does), so ``photon_map.photon_engine`` and ``photon_map.core`` are
  one consistent package. Do not mix ``core.*`` and ``photon_map.core.*`` objects.
"""

import importlib.util
import os
import pathlib
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def load_extension_package():
    """Import the repo root as the package ``photon_map`` (what Blender's installer does)."""
    if "photon_map" in sys.modules:
        return sys.modules["photon_map"]
    spec = importlib.util.spec_from_file_location(
        "photon_map", ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules["photon_map"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def rng():
    """A fixed-seed generator: tests are reproducible."""
    return np.random.default_rng(12345)


def pytest_collection_modifyitems(config, items):
    """Mark every test under tests/core ``core`` (CI selects them by marker, pytest.ini)."""
    core = ROOT / "tests" / "core"
    for item in items:
        if core in pathlib.Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.core)


_EXIT = {}


def pytest_sessionfinish(session, exitstatus):
    _EXIT["status"] = int(exitstatus)


def pytest_unconfigure(config):
    """Leave without the interpreter's teardown: bpy 4.2 (CPython 3.11) can crash in its
    own shutdown after every test has run and the summary is printed (seen once in CI:
    1008 passed, then a segmentation fault at exit), which would turn a green run red.
    The exit status is pytest's own, so a failing run still fails."""
    if "status" in _EXIT:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT["status"])

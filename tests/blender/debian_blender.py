"""Run a real Blender executable (Debian's ``blender`` package, 3.4) with Photon Map.

Blender 3.4 predates extensions: it loads Photon Map as a legacy add-on from
``$BLENDER_USER_SCRIPTS/addons/photon_map`` (``bl_info`` in the root ``__init__.py``) and
imports third-party modules from ``$BLENDER_USER_SCRIPTS/addons/modules``, which is on
its ``sys.path``. ``user_scripts()`` builds such a folder from symlinks: the repository
as the add-on, and numpy, numba, llvmlite, embreex and OpenEXR from a CPython 3.11
environment: Debian's Blender runs the system CPython 3.11 (its own Python has no numpy),
so the modules come from the Python running the tests when that is 3.11, else from
``.venv-4.2`` (tools/setup.sh; the main ``.venv`` is CPython 3.13). Nothing is installed
into the user's Blender folders.

Not a test module: imported by tests/blender/test_blender_exe.py and test_animation.py.
"""

from __future__ import annotations

import functools
import json
import importlib.util
import os
import pathlib
import shutil
import signal
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DEPENDENCIES = ("numpy", "numba", "llvmlite", "embreex", "OpenEXR")
SCENES = ROOT / "tests" / "blender" / "scenes.py"
VIEWPORT_SCRIPT = ROOT / "tests" / "blender" / "viewport_window.py"


@functools.lru_cache(maxsize=None)
def executable() -> str:
    """Path of ``blender``; installs Debian's package when apt and root are available,
    otherwise skips the calling test with the reason."""
    found = shutil.which("blender")
    if found is None and shutil.which("apt-get") and hasattr(os, "geteuid") and os.geteuid() == 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        for command in (["apt-get", "install", "-y", "-qq", "blender"],
                        ["sh", "-c", "apt-get update -qq && apt-get install -y -qq blender"]):
            if subprocess.run(command, env=env, capture_output=True, timeout=900).returncode == 0:
                break
        found = shutil.which("blender")
    if found is None:
        pytest.skip("no `blender` executable and no apt-get as root to install Debian's "
                    "`blender` package (tools/setup.sh installs it)")
    return found


def user_scripts(folder: pathlib.Path) -> pathlib.Path:
    """A BLENDER_USER_SCRIPTS folder in ``folder``: addons/photon_map -> the repository,
    addons/modules/<dependency> -> this interpreter's copy (with its ``*.libs``)."""
    scripts = folder / "scripts"
    modules = scripts / "addons" / "modules"
    modules.mkdir(parents=True, exist_ok=True)
    link = scripts / "addons" / "photon_map"
    if not link.exists():
        link.symlink_to(ROOT, target_is_directory=True)
    site = _cpython311_site()
    for name in DEPENDENCIES:
        if site is None:
            spec = importlib.util.find_spec(name)
            if spec is None or spec.origin is None:
                raise RuntimeError(f"{name} is not installed in this Python; run tools/setup.sh")
            origin = pathlib.Path(spec.origin)
            source = origin.parent if spec.submodule_search_locations else origin
        else:
            found = [p for p in (site / name, *site.glob(f"{name}.cpython-311-*.so")) if p.exists()]
            if not found:
                raise RuntimeError(f"{name} is not installed in {site}; run tools/setup.sh")
            source = found[0]
        # auditwheel puts a wheel's shared libraries in <name>.libs beside the package.
        for path in [source, *source.parent.glob(f"{name}.libs")]:
            target = modules / path.name
            if not target.exists():
                target.symlink_to(path)
    return scripts


def _cpython311_site() -> pathlib.Path | None:
    """None when this Python is 3.11 (use its modules), else .venv-4.2's site-packages;
    skips the calling test when there is none."""
    if sys.version_info[:2] == (3, 11):
        return None
    found = sorted(ROOT.glob(".venv-4.2/lib/python3.11/site-packages"))
    if not found:
        pytest.skip("Debian's Blender 3.4 runs CPython 3.11 and needs CPython 3.11 builds of "
                    "numpy/numba/embreex/OpenEXR: no .venv-4.2 (tools/setup.sh makes it)")
    return found[0]


def _environment(folder: pathlib.Path) -> dict:
    env = dict(os.environ,
               BLENDER_USER_SCRIPTS=str(user_scripts(folder)),
               BLENDER_USER_CONFIG=str(folder / "config"))
    env.pop("PYTHONPATH", None)
    return env


def run(args, folder: pathlib.Path, timeout=300) -> subprocess.CompletedProcess:
    """``blender <args>`` with Photon Map available as a legacy add-on and user folders
    (scripts, config) isolated in ``folder``; ``cwd`` is ``folder``."""
    return subprocess.run([executable(), *map(str, args)], cwd=folder, env=_environment(folder),
                          capture_output=True, text=True, timeout=timeout)


def run_with_window(args, folder: pathlib.Path, screen=(640, 480), timeout=180) -> str:
    """``blender <args>`` as ``run`` does, but with a window on a virtual X server
    (``xvfb-run``; there the gpu module works, on Mesa's software OpenGL); returns what
    Blender printed. Skips the calling test without xvfb-run. The script must end Blender
    itself (``os._exit``): a hang is killed after ``timeout`` seconds, Xvfb with it."""
    if shutil.which("xvfb-run") is None:
        pytest.skip("needs xvfb-run (apt-get install xvfb) to give Blender a window and a "
                    "GPU context")
    # Its own process group, so that a hang takes Xvfb and Blender down with it.
    process = subprocess.Popen(
        ["xvfb-run", "-a", "-s", f"-screen 0 {screen[0]}x{screen[1]}x24", executable(),
         *map(str, args)], cwd=folder, env=_environment(folder), stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        log, _ = process.communicate(timeout=timeout)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    return log


def check(done: subprocess.CompletedProcess) -> str:
    """The output of a finished Blender run; fails the test with it if Blender failed.

    Blender 3.4 exits 0 even when a ``--python`` script raises, so its output is
    searched for Python errors and crashes too.
    """
    output = done.stdout + done.stderr
    failed = (done.returncode != 0 or "Traceback" in output or "Error:" in output
              or "Segmentation fault" in output or "crash" in output.lower())
    assert not failed, f"blender exited with {done.returncode}:\n{output[-4000:]}"
    return output


def render_in_viewport(folder: pathlib.Path, scene: str, png: pathlib.Path, passes: int,
                       photons: int, window=(800, 600), timeout=180) -> dict:
    """Rendered shading of ``scene`` (a name in viewport_window.SCENES) in a real 3D viewport
    of a ``window``-sized Blender window, ``passes`` passes of ``photons`` photons; saves a
    screenshot of the view as ``png`` and returns viewport_window's record (passes, more,
    error, draws, seconds, area, region). Raises RuntimeError with Blender's output when
    it printed none."""
    blend = folder / f"{scene}.blend"
    args = ["--addons", "photon_map", "--python", VIEWPORT_SCRIPT, "--", scene, blend, png,
            passes, photons, max(1, timeout - 30), ROOT]
    check(run(["-b", "--factory-startup", *args], folder))
    log = run_with_window(["--factory-startup", blend, "-p", "0", "0", window[0], window[1],
                           *args], folder, screen=window, timeout=timeout)
    line = next((l for l in log.splitlines() if l.startswith("VIEWPORT ")), None)
    if line is None:
        raise RuntimeError(f"no viewport record from Blender:\n{log[-3000:]}")
    return json.loads(line.split(" ", 1)[1])

#!/usr/bin/env bash
# Set up Photon Map's development environments from nothing:
#   - Debian packages bpy needs at run time (X/GL client libraries; no display is used),
#   - Debian's `blender` (3.4), a real `blender -b` executable for tests/blender/test_blender_exe.py
#     and test_animation.py (they run it with .venv-4.2's CPython 3.11 modules, docs/blender.md),
#   - xvfb, a virtual X server for the viewport draw tests (tests/blender/test_overlay.py),
#   - .venv: CPython 3.13 + bpy 5.2.3 (Blender 5.2 LTS, numpy 2) + requirements.txt; the whole
#     test suite runs here,
#   - .venv-4.2: CPython 3.11 + bpy 4.2.23 (Blender 4.2 LTS, numpy 1.x) + requirements-4.2.txt,
#     the other end of the supported range (core tests and `pytest -m api`, see .ci/run).
# CPython 3.11 comes from Debian (bookworm's python3). CPython 3.13 is taken from PATH,
# pyenv or a previous run; otherwise uv (pip-installed into .uv/) downloads a standalone
# build into .python/ (about 30 MB from GitHub; nothing system-wide; untested here: this
# sandbox reaches package registries only). SETUP_PYTHON313=/path/to/python3.13
# picks one by hand.
# Idempotent: a second run only checks. Safe without root (skips apt with a note).
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(libxrender1 libxxf86vm1 libxfixes3 libxi6 libxkbcommon0 libsm6 libgl1 libegl1 blender xvfb xauth)

usable() { [ -n "$1" ] && "$1" -c 'import venv, ensurepip' >/dev/null 2>&1; }

# find_python X.Y: the first CPython X.Y that can make a venv, or nothing.
find_python() {
  local v=$1 cand
  for cand in "python$v" "/usr/bin/python$v" "$HOME"/.pyenv/versions/"$v".*/bin/"python$v" \
              .python/cpython-"$v".*/bin/"python$v"; do
    cand=$(command -v "$cand" 2>/dev/null || true)
    if usable "$cand"; then echo "$cand"; return; fi
  done
}

missing=()
if command -v dpkg >/dev/null 2>&1; then
  for p in "${APT_PACKAGES[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
fi
PY311=$(find_python 3.11)
[ -n "$PY311" ] || missing+=(python3.11 python3.11-venv)

if [ ${#missing[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "setup: installing Debian packages: ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  elif command -v apt-get >/dev/null 2>&1 && command -v sudo >/dev/null 2>&1; then
    sudo apt-get update -qq
    sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "setup: please install: ${missing[*]} (no apt-get/root here)" >&2
  fi
fi
[ -n "$PY311" ] || PY311=$(find_python 3.11)
if [ -z "$PY311" ]; then
  echo "setup: error: no CPython 3.11 with venv (apt-get install python3.11 python3.11-venv)" >&2
  exit 1
fi

PY313=${SETUP_PYTHON313:-$(find_python 3.13)}
if ! usable "$PY313"; then
  echo "setup: no CPython 3.13 here; fetching a standalone build with uv into .python/"
  [ -x .uv/bin/uv ] || { "$PY311" -m venv .uv && .uv/bin/python -m pip install -q uv; }
  UV_PYTHON_INSTALL_DIR="$PWD/.python" .uv/bin/uv python install -q 3.13
  PY313=$(UV_PYTHON_INSTALL_DIR="$PWD/.python" .uv/bin/uv python find --no-project --managed-python 3.13 || true)
fi
if ! usable "$PY313"; then
  echo "setup: error: could not get CPython 3.13 (needed by bpy 5.2, Blender 5.2 LTS); install" \
       "it (pyenv, uv, or Debian 13's python3.13) or set SETUP_PYTHON313=/path/to/python3.13" >&2
  exit 1
fi

# make_venv DIR PYTHON X.Y REQUIREMENTS
make_venv() {
  local dir=$1 py=$2 v=$3 req=$4
  if [ ! -x "$dir/bin/python" ] || ! "$dir/bin/python" -c "import sys; assert sys.version_info[:2] == tuple(map(int, '$v'.split('.')))" 2>/dev/null; then
    echo "setup: creating $dir with $py"
    rm -rf "$dir"
    "$py" -m venv "$dir"
  fi
  "$dir/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$dir/bin/python" -m pip install -q --disable-pip-version-check -r "$req"
  "$dir/bin/python" -c 'import sys, bpy, numba, numpy, embreex, OpenEXR; print(f"setup: ok, '"$dir"': Python {sys.version.split()[0]}, bpy {bpy.app.version_string}, numpy {numpy.__version__}, numba {numba.__version__}")'
}
make_venv .venv "$PY313" 3.13 requirements.txt
make_venv .venv-4.2 "$PY311" 3.11 requirements-4.2.txt

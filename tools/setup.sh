#!/usr/bin/env bash
# Set up Photon Map's development environment from nothing:
#   - Debian packages bpy needs at run time (X/GL client libraries; no display is used),
#   - Debian's `blender` (3.4), a real `blender -b` executable for tests/blender/test_blender_exe.py
#     and test_animation.py (they run it with this .venv's numba/embreex, see docs/blender.md),
#   - xvfb, a virtual X server for the viewport-overlay draw test (tests/blender/test_overlay.py),
#   - Python 3.11 (bpy 5.0.1 is built for CPython 3.11 only),
#   - a virtual environment at .venv in the repo root with requirements.txt.
# Idempotent: a second run only checks. Safe without root (skips apt with a note).
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(libxrender1 libxxf86vm1 libxfixes3 libxi6 libxkbcommon0 libsm6 libgl1 libegl1 blender xvfb xauth)

missing=()
if command -v dpkg >/dev/null 2>&1; then
  for p in "${APT_PACKAGES[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
fi

PY=""
for cand in python3.11 /usr/bin/python3.11; do
  if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import venv, ensurepip' >/dev/null 2>&1; then
    PY=$(command -v "$cand"); break
  fi
done
[ -n "$PY" ] || missing+=(python3.11 python3.11-venv)

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
[ -n "$PY" ] || PY=$(command -v python3.11)

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null; then
  echo "setup: creating .venv with $PY"
  rm -rf .venv
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -r requirements.txt
.venv/bin/python -c 'import bpy, numba, embreex, OpenEXR; print("setup: ok, bpy", bpy.app.version_string, "numba", numba.__version__)'

#!/usr/bin/env bash
# Create .venv-blender (Python 3.11) with Blender 4.5 LTS as the Python module `bpy`, for
# tests/test_blender.py. Idempotent; safe to re-run. Kept apart from .venv on purpose:
# bpy 4.5 needs numpy<2, usdmotion needs numpy 2. Nothing here is needed by the main suite.
#
#   scripts/setup_blender.sh            # then: scripts/test.sh tests/test_blender.py
#   BPY_VERSION=4.5.15 scripts/setup_blender.sh
set -euo pipefail
cd "$(dirname "$0")/.."

BPY_SPEC=${BPY_VERSION:+"bpy==$BPY_VERSION"}
BPY_SPEC=${BPY_SPEC:-"bpy>=4.5,<4.6"}   # 4.5 LTS; bpy 5.x needs Python 3.13
VENV=.venv-blender

# Shared libraries the bpy wheel links against (X11 client libs, GL, xkbcommon) even
# when running headless (from `ldd bpy/__init__.so`; their own dependencies come along).
source scripts/_lib.sh
ensure_apt "libraries bpy links against" libx11-6 libxext6 libxfixes3 libxi6 libxrender1 libxkbcommon0 libsm6 libice6 libgl1
[ -x "$VENV/bin/python" ] || { PY=$(python311 "bpy 4.5 LTS"); "$PY" -m venv "$VENV"; }
stamp="$VENV/.bpy-installed"
if [ ! -f "$stamp" ] || [ "$0" -nt "$stamp" ]; then
  "$VENV/bin/python" -m pip install -q --upgrade pip
  "$VENV/bin/python" -m pip install -q "$BPY_SPEC" "numpy<2"
  touch "$stamp"
fi
"$VENV/bin/python" -c 'import bpy, numpy; print(f"setup_blender: ready (Blender {bpy.app.version_string}, numpy {numpy.__version__})")'

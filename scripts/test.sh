#!/usr/bin/env bash
# Set up (if needed) and run the whole test suite. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# Blender (bpy 4.5 LTS, own venv: it needs numpy<2) for the DCC import tests; they skip if this fails.
scripts/setup_blender.sh || echo "test: Blender venv not available; tests/test_blender.py will skip"
export PYOPENGL_PLATFORM=egl
exec .venv/bin/python -m pytest -q "$@"

#!/usr/bin/env bash
# Create .venv (Python 3.11) with usdmotion and its test tools. Idempotent; safe to re-run.
# Installs the Debian libraries for headless EGL rendering (Mesa) when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/_lib.sh
ensure_apt "headless OpenGL via EGL" libegl1 libegl-mesa0 libgl1-mesa-dri libgles2
if [ ! -x .venv/bin/python ]; then
  ensure_free_disk 3000 "the virtual environment (1.7 GiB installed, with pip's build space)"
  PY=$(python311 "usdmotion (jax 0.10.2 and Blender's bpy pin it)")
  "$PY" -m venv .venv
fi
stamp=.venv/.usdmotion-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[test]"
  touch "$stamp"
fi
# The studio's web packages (three.js, uPlot), pinned by package-lock.json, served locally; Chromium for its
# browser tests (Debian's package: Playwright drives it, no browser is downloaded from anywhere else).
ensure_apt "studio browser tests" chromium
web=usdmotion/studio/web
if [ ! -f "$web/node_modules/.package-lock.json" ] || [ "$web/package-lock.json" -nt "$web/node_modules/.package-lock.json" ]; then
  command -v npm >/dev/null 2>&1 || ensure_apt "studio web packages" npm
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
fi
if command -v npm >/dev/null 2>&1; then
  if [ ! -d tests/gltf_validator/node_modules/gltf-validator ] \
     || [ tests/gltf_validator/package-lock.json -nt tests/gltf_validator/node_modules/.package-lock.json ]; then
    (cd tests/gltf_validator && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
  fi
else
  echo "setup: npm not found: skipping the Khronos glTF-Validator (tests/gltf_validator); its tests will skip"
fi
echo "setup: ready ($(.venv/bin/python --version), usdmotion $(.venv/bin/python -c 'import importlib.metadata as m; print(m.version("usdmotion"))'))"

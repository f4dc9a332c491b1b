#!/usr/bin/env bash
# Create .venv (Python 3.11) with usdmotion and its test tools. Idempotent; safe to re-run.
# Installs the Debian libraries for headless EGL rendering (Mesa) when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
for pkg in libegl1 libegl-mesa0 libgl1-mesa-dri libgles2; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing ${need_apt[*]} (headless OpenGL via EGL)"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq && $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
"$PY" - <<'PYEOF'
import sys
if sys.version_info[:2] != (3, 11):
    sys.exit(f"setup: usdmotion needs Python 3.11 (jax 0.10.2 and Blender's bpy pin it), found {sys.version.split()[0]}")
PYEOF

if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.usdmotion-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[test]"
  touch "$stamp"
fi
echo "setup: ready ($(.venv/bin/python --version), usdmotion $(.venv/bin/python -c 'import importlib.metadata as m; print(m.version("usdmotion"))'))"

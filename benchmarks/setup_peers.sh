#!/usr/bin/env bash
# Create benchmarks' own venv (.venv-bench) with the peer BVH libraries pybvh and bvhio.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
[ -x .venv-bench/bin/python ] || "$PY" -m venv .venv-bench
.venv-bench/bin/python -m pip install -q "pybvh==0.9.0" "bvhio==1.5.4"

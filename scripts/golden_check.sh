#!/usr/bin/env bash
# Golden outputs that a behaviour-preserving refactor must keep byte-identical.
#   scripts/golden_check.sh record DIR   # write them into DIR (run once on the commit before)
#   scripts/golden_check.sh check DIR    # recompute into a temp dir and compare bytes with DIR
# What is compared: the demo's files (scripts/demo.sh -> out/demo/; the .usdz zips and the
# .mp4/.png renders are compared too and reported separately, since their bytes may
# embed encoder details), the skeleton-names record (tests/skeleton_names_record.py; on
# main at 5bc0ae8 it already differs from tests/data/skeleton_names_golden.json in the
# variant:namespace_pipe maps, so the record of the commit before is compared) and the kinematics CSVs of
# `usdmotion analyze` on the bundled walk and two shared takes.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:?record|check}; dir=${2:?directory}
U=.venv/bin/usdmotion
SHARED=${USDMOTION_SHARED_DATA:-../shared/data}
export PYOPENGL_PLATFORM=egl
out=$dir; [ "$mode" = check ] && out=$(mktemp -d /tmp/golden-check.XXXXXX)
mkdir -p "$out/analyze"
rm -rf out/demo && scripts/demo.sh > "$out/demo.log" 2>&1
cp -r out/demo "$out/demo"
USDMOTION_SHARED_DATA=$(realpath "$SHARED") .venv/bin/python tests/skeleton_names_record.py "$out/skeleton_names.json" > /dev/null
$U analyze usdmotion/data/cmu_12_01_walk.bvh --units asf --frames 1: --mass 70 --out "$out/analyze/walk.csv" > /dev/null
$U analyze "$SHARED/cmu/max_131_01_start_walk_stop.bvh" --mass 70 --out "$out/analyze/start_walk_stop.csv" > /dev/null
$U analyze "$SHARED/cmu14/max_14_14_exercise_routine.bvh" --mass 70 --out "$out/analyze/exercise_routine.csv" > /dev/null
if [ "$mode" = check ]; then
  status=0
  (cd "$dir" && find . -type f ! -name demo.log | sort) | while read -r f; do
    if cmp -s "$dir/$f" "$out/$f"; then echo "same      $f"; else echo "DIFFERENT $f"; fi
  done | tee "$out/compare.txt"
  grep -q DIFFERENT "$out/compare.txt" && status=1
  echo "recomputed in $out"; exit $status
fi
echo "recorded in $dir"

#!/usr/bin/env bash
# Golden outputs that a behaviour-preserving refactor must keep byte-identical.
#   scripts/golden_check.sh record DIR   # write them into DIR (run once on the commit before)
#   scripts/golden_check.sh check DIR    # recompute into a temp dir and compare bytes with DIR
# What is compared: the demo's files (scripts/demo.sh -> out/demo/, renders included), the
# skeleton-names record (tests/skeleton_names_record.py; on main at 5bc0ae8 it already
# differs from tests/data/skeleton_names_golden.json in the variant:namespace_pipe maps, so
# the record of the commit before is compared) and the kinematics CSVs of `usdmotion
# analyze` on the bundled walk and two shared takes.
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
  # Bytes, except what is not deterministic: a .usdz zip stamps each member with the time
  # it was written (its members' bytes are compared instead) and the retarget report holds
  # timings (time_s, frames_per_second_solve; every other field is compared).
  .venv/bin/python - "$dir" "$out" <<'PY' | tee "$out/compare.txt"
import json, sys, zipfile
from pathlib import Path
before, after = Path(sys.argv[1]), Path(sys.argv[2])
def content(path):
    if path.suffix == ".usdz":
        with zipfile.ZipFile(path) as z:
            return [(i.filename, z.read(i)) for i in z.infolist()]
    if path.name == "retarget_report.json":
        doc = json.loads(path.read_text())
        doc.pop("time_s", None), doc.pop("frames_per_second_solve", None)
        return doc
    return path.read_bytes()
for f in sorted(p.relative_to(before) for p in before.rglob("*") if p.is_file() and p.name != "demo.log"):
    same = (after / f).is_file() and content(before / f) == content(after / f)
    print(f"{'same     ' if same else 'DIFFERENT'} {f}")
PY
  echo "recomputed in $out"
  ! grep -q DIFFERENT "$out/compare.txt"; exit
fi
echo "recorded in $dir"

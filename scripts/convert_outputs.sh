#!/usr/bin/env bash
# Write a set of `usdmotion convert` outputs with the code of TREE (a checkout or a `git archive`)
# into OUT and list their MD5s in OUT.md5 (.usdz packages by their unpacked files: the zip holds
# timestamps), to show that a change leaves the files byte-identical:
#
#   scripts/convert_outputs.sh /tmp/before /tmp/out-before   # e.g. git archive main | tar -x -C /tmp/before
#   scripts/convert_outputs.sh .           /tmp/out-after
#   diff /tmp/out-before.md5 /tmp/out-after.md5
#
# Inputs: the benchmark's 5,000-frame take (benchmarks/startup.py), the bundled CMU walk as
# .usda/.usdc/.usd/.usdz, with --mesh, --to-up-axis/--fps, edge-case and other-rig BVHs from
# ../shared/data (skipped when absent), tests/data/rigs, and USD → USD.
set -euo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
TREE=$(cd "$1" && pwd); OUT=$2
PY="$REPO/.venv/bin/python"
DATA=${USDMOTION_SHARED_DATA:-$REPO/../shared/data}
WALK="$REPO/usdmotion/data/cmu_12_01_walk.bvh"
rm -rf "$OUT"; mkdir -p "$OUT"; cd "$OUT"
"$PY" -c "import sys; sys.path.insert(0, '$REPO/benchmarks'); from _common import tiled_bvh; from pathlib import Path
tiled_bvh(Path('$WALK'), 5000, Path('walk_5000.input.bvh'))"
c() { PYTHONPATH="$TREE" "$PY" -c "import sys; sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]
from usdmotion.cli import main; sys.exit(main(sys.argv[1:]))" convert "$@" >/dev/null 2>>log.txt || echo "FAILED: convert $*" | tee -a log.txt; }
c walk_5000.input.bvh out.usdc
for e in usda usdc usd usdz; do c "$WALK" "w.$e" --units asf; done
c "$WALK" m.usdc --units asf --mesh; c "$WALK" m.usda --units asf --mesh; c "$WALK" m.usdz --units asf --mesh --to-up-axis Y
c "$WALK" y.usda --units asf --to-up-axis Y --fps 30
for f in edge_cases/pybvh_bvh_example_mixed_orders_zup edge_cases/fairmotion_sinusoidal_no_end_site \
         edge_cases/pybvh_bvh_test3_60joints_mixed_orders edge_cases/pybvh_rotation_first_root \
         other_rigs/ad_rokoko_jesse_dance other_rigs/wspr_louise_optitrack_arena other_rigs/20tab_test_freebvh_mixamorig; do
  if [ -f "$DATA/$f.bvh" ]; then n=$(basename "$f"); c "$DATA/$f.bvh" "$n.usda"; c "$DATA/$f.bvh" "$n.usdc"; fi
done
c w.usdc back.usda; c m.usdc mback.usda
for r in "$REPO"/tests/data/rigs/*.bvh; do c "$r" "$(basename "$r" .bvh).usdc"; done
rm walk_5000.input.bvh
for z in *.usdz; do mkdir -p "$z.d"; (cd "$z.d" && unzip -q "../$z"); done
find . -type f ! -name '*.usdz' ! -name log.txt | sort | xargs md5sum > "$OUT.md5"
echo "$(wc -l < "$OUT.md5") files listed in $OUT.md5"

"""Automatic joint maps from the CMU (cgspeed) walk and the Bandai walk onto every rig
profile's test skeleton (tests/data/rigs/) and the corpus rigs: how many joints are mapped,
and every unmapped target joint with its reason (issue 17, "automatic maps for every rig
profile"). No timing: a table to read.

    PYTHONPATH=. python benchmarks/rig_maps.py

Prints one block per (source, target) and writes ``benchmarks/results/rig_maps.json``.
"""

from __future__ import annotations

import json
import sys
import warnings
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks._common import RESULTS, SHARED_DATA  # noqa: E402

SOURCES = {"cmu": ("cmu/cgspeed_12_01_walk.bvh", "asf"), "bandai": ("bandai1/dataset-1_walk_normal_001.bvh", None)}
CORPUS_TARGETS = ("cmu/daz_10_01_soccer_kick.bvh", "bandai1/dataset-1_walk_normal_001.bvh",
                  "other_rigs/ad_mixamo_Boxing.bvh", "other_rigs/ad_rokoko_jesse_dance.bvh")


def automatic_maps(source, targets: dict) -> dict:
    """``label → {"how", "mapped", "pairs", "unmapped": {reason: [joints]}}`` for each target Motion."""
    from usdmotion.ops.retarget.jointmap import auto_map, unmapped_reasons

    out = {}
    for label, target in targets.items():
        jmap = auto_map(source.joint_names, target.joint_names, target.end_sites)
        by_reason = defaultdict(list)
        for joint, why in unmapped_reasons(source.joint_names, target.joint_names, jmap.pairs,
                                           target.end_sites).items():
            by_reason[why].append(joint)
        pairs = {t: s for t, s in jmap.pairs.items() if s is not None}
        out[label] = {"how": jmap.how, "mapped": len(pairs), "pairs": pairs, "unmapped": dict(by_reason)}
    return out


def main() -> None:
    from usdmotion.io import read_motion

    targets = {p.stem: read_motion(p) for p in sorted((REPO / "tests" / "data" / "rigs").glob("*.bvh"))}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        targets.update({rel: read_motion(SHARED_DATA / rel) for rel in CORPUS_TARGETS if (SHARED_DATA / rel).exists()})
        sources = {k: read_motion(SHARED_DATA / rel, units=u) for k, (rel, u) in SOURCES.items()
                   if (SHARED_DATA / rel).exists()}
    result = {}
    for name, source in sources.items():
        result[name] = automatic_maps(source, {k: v for k, v in targets.items() if k != SOURCES[name][0]})
        for label, m in result[name].items():
            print(f"{name} -> {label}: {m['how']}; {m['mapped']} mapped")
            for why, joints in sorted(m["unmapped"].items()):
                print(f"    {why:<28} {len(joints):>3}  {', '.join(joints[:6])}{' …' if len(joints) > 6 else ''}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "rig_maps.json").write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {RESULTS / 'rig_maps.json'}")


if __name__ == "__main__":
    main()

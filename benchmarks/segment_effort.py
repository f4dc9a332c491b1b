"""The segmentation editor's effort: edits a person makes in the Studio to turn the detector's
cuts into the labelled ones (issue 14, Must-show 2), on CMU 86_01 and 14_14.

Each detected cut is paired with the nearest labelled boundary not taken by a nearer one
(:func:`usdmotion.ops.segment.evaluate.edits_to_labels`, the pairing the editor's browser test
follows); paired cuts off their labelled frame are *moved* (and *needed* a move when they were not
already a hit within the labelled band or ±0.5 s), labelled cuts left unpaired are *added*,
detections left unpaired *deleted*. Default detector (kcpd, as the Studio runs it) and the paper's
heuristic for comparison. No timing: the figures do not depend on the machine.

    python benchmarks/segment_effort.py      # prints the table, writes benchmarks/results/segment_effort.json
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, write_results  # noqa: E402

from usdmotion.io import read_motion  # noqa: E402
from usdmotion.ops.segment.detect import segment  # noqa: E402
from usdmotion.ops.segment.evaluate import DEFAULT_TOLERANCE_S, edits_to_labels, load_labels, score_cuts  # noqa: E402

TAKES = {"86_01": ("cmu86/86_01_from_amc_cgspeed_layout.bvh", "cmu86/86_01_segments.csv"),
         "14_14": ("cmu14/max_14_14_exercise_routine.bvh", "cmu14/14_14_segments.csv")}


def main() -> None:
    rows, results = [], {}
    for take, (motion_file, label_file) in TAKES.items():
        if not (SHARED_DATA / motion_file).is_file():
            print(f"skipped {take}: {SHARED_DATA / motion_file} not found")
            continue
        motion = read_motion(SHARED_DATA / motion_file, units="asf")
        labels = load_labels(SHARED_DATA / label_file)
        tol = int(round(DEFAULT_TOLERANCE_S * motion.fps))
        for method in ("kcpd", "heuristic"):
            cuts = segment(motion, method=method).cuts
            plan = edits_to_labels(cuts, labels, tol)
            score = score_cuts(cuts, labels, tol)
            results[f"{take}/{method}"] = {"detected": cuts.tolist(), "labelled": labels.cuts.tolist(),
                                           "precision": score.precision, "recall": score.recall, **plan.to_dict()}
            rows.append([take, method, cuts.size, labels.cuts.size, f"{score.precision:.0%}/{score.recall:.0%}",
                         plan.kept, len(plan.moved), plan.needed, len(plan.added), len(plan.deleted),
                         plan.needed + len(plan.added) + len(plan.deleted),
                         max((abs(a - b) for a, b in plan.moved), default=0)])
    print_table("Edits from the detector's cuts to the labelled boundaries (tolerance: labelled band or ±0.5 s)",
                ["take", "detector", "detected", "labelled", "P/R before", "exact", "moved", "of which needed",
                 "added", "deleted", "edits needed for 100 %", "largest move (frames)"], rows)
    print(f"wrote {write_results('segment_effort', {'takes': results})}")


if __name__ == "__main__":
    main()

"""``usdmotion segment-eval IN LABELS``: precision and recall of detected cuts against labels."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, Json, Lenient, RootOffset, RootOffsetChoice, UpAxis, Units, read_input
from usdmotion.cli._segment_options import Cutoff, MinLength, Param, Penalty, Preset, Refine, Roles
from usdmotion.cli.app import app


@app.command("segment-eval")
def segment_eval(
    source: InputPath,
    labels: Annotated[Path, typer.Argument(help="Labels: groundtruth86-style .json, *_segments.csv, or a "
                                                "segments.json.", show_default=False)],
    trial: Annotated[int, typer.Option(help="Trial (row of 'gt') in a groundtruth86-style file.")] = 0,
    first_frame: Annotated[int, typer.Option(help="Label number of the motion's frame 0 (CMU AMC: 1).")] = 1,
    tolerance: Annotated[float, typer.Option(help="A cut matches within its labelled transition band or "
                                                  "this many seconds of the labelled cut.")] = 0.5,
    param: Param = 0.5,
    cutoff: Cutoff = 2.0,
    penalty: Penalty = None,
    min_length: MinLength = 1.0,
    refine: Refine = True,
    role: Roles = None,
    preset: Preset = None,
    units: Units = None,
    up_axis: UpAxis = None,
    root_offset: RootOffset = RootOffsetChoice.auto,
    lenient: Lenient = False,
    as_json: Json = False,
) -> None:
    """Score both detectors (kcpd and the paper's heuristic) against labelled cuts."""
    from usdmotion.cli._segment_options import MethodChoice, run_segmentation
    from usdmotion.ops.segment_eval import load_labels, score_cuts

    truth = load_labels(labels, trial, 0 if labels.suffix.lower() == ".json" and _is_ours(labels) else first_frame)
    motion = read_input(source, units, up_axis, root_offset, lenient)
    tol = int(round(tolerance * motion.fps))
    results = {}
    for method in MethodChoice:
        seg = run_segmentation(motion, source, method, param, cutoff, penalty, min_length, role, preset, refine)
        results[method.value] = {"params": seg.params, **score_cuts(seg.cuts, truth, tol).to_dict()}
    if as_json:
        typer.echo(json.dumps({"file": str(source), "labels": str(labels), "tolerance_frames": tol,
                               "labelled_cuts": truth.cuts.tolist(), "methods": results}, indent=2))
        return
    typer.echo(f"{source.name} vs {labels.name}: {truth.cuts.size} labelled cuts, match within the labelled band "
               f"or ±{tolerance:g} s (±{tol} frames), one-to-one")
    typer.echo(f"{'method':<10} {'detected':>8} {'hits':>5} {'precision':>9} {'recall':>7} {'F1':>6} "
               f"{'in-region P':>11}")
    for name, r in results.items():
        typer.echo(f"{name:<10} {r['detected']:>8} {r['true_positives']:>5} {r['precision']:>9.1%} "
                   f"{r['recall']:>7.1%} {r['f1']:>6.3f} {r['in_region_precision']:>11.1%}")


def _is_ours(path: Path) -> bool:
    try:
        return "cuts" in json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False

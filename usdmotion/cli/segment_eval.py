"""``usdmotion segment-eval IN LABELS``: precision and recall of detected cuts against labels."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, Json, ReadOptions, reads_motion
from usdmotion.cli._segment_options import DetectorOptions, MethodChoice, detects_segments
from usdmotion.cli.app import app


@app.command("segment-eval")
@reads_motion
@detects_segments
def segment_eval(
    source: InputPath,
    labels: Annotated[Path, typer.Argument(help="Labels: groundtruth86-style .json, *_segments.csv, or a "
                                                "segments.json.", show_default=False)],
    trial: Annotated[int, typer.Option(help="Trial (row of 'gt') in a groundtruth86-style file.")] = 0,
    first_frame: Annotated[int, typer.Option(help="Label number of the motion's frame 0 (CMU AMC: 1).")] = 1,
    tolerance: Annotated[float, typer.Option(help="A cut matches within its labelled transition band or "
                                                  "this many seconds of the labelled cut.")] = 0.5,
    cuts: Annotated[Path | None, typer.Option(
        help="Score the cuts of this segments JSON (`segment --out`, or saved by the Studio's editor) instead "
             "of running the detectors.", show_default=False)] = None,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
    detector: DetectorOptions = DetectorOptions(),
) -> None:
    """Score both detectors (kcpd and the paper's heuristic), or a segments file, against labelled cuts."""
    from usdmotion.ops.segment.evaluate import load_labels, score_cuts

    truth = load_labels(labels, trial, 0 if labels.suffix.lower() == ".json" and _is_ours(labels) else first_frame)
    motion = read.read(source)
    tol = int(round(tolerance * motion.fps))
    results = {}
    if cuts is not None:
        results[cuts.name] = {"params": {}, **score_cuts(_saved_cuts(cuts, motion.n_frames), truth, tol).to_dict()}
    for method in MethodChoice if cuts is None else ():
        seg = detector.run(motion, source, method)
        results[method.value] = {"params": seg.params, **score_cuts(seg.cuts, truth, tol).to_dict()}
    if as_json:
        typer.echo(json.dumps({"file": str(source), "labels": str(labels), "tolerance_frames": tol,
                               "labelled_cuts": truth.cuts.tolist(), "methods": results}, indent=2))
        return
    typer.echo(f"{source.name} vs {labels.name}: {truth.cuts.size} labelled cuts, match within the labelled band "
               f"or ±{tolerance:g} s (±{tol} frames), one-to-one")
    width = max(10, *(len(name) for name in results))
    typer.echo(f"{'method':<{width}} {'detected':>8} {'hits':>5} {'precision':>9} {'recall':>7} {'F1':>6} "
               f"{'in-region P':>11}")
    for name, r in results.items():
        typer.echo(f"{name:<{width}} {r['detected']:>8} {r['true_positives']:>5} {r['precision']:>9.1%} "
                   f"{r['recall']:>7.1%} {r['f1']:>6.3f} {r['in_region_precision']:>11.1%}")


def _saved_cuts(path: Path, n_frames: int) -> list[int]:
    """The cuts of a segments JSON, checked against the schema and the motion's length."""
    from usdmotion.errors import InputError
    from usdmotion.schemas import load_document

    doc = load_document(path, "segments")
    if doc["frames"] != n_frames:
        raise InputError(path, f"segments of a {doc['frames']}-frame take, the motion has {n_frames} frames")
    return doc["cuts"]


def _is_ours(path: Path) -> bool:
    """Whether ``path`` is a saved segments JSON (an object with ``cuts``); any other file is
    left to :func:`~usdmotion.ops.segment.evaluate.load_labels`, which says what is wrong with it."""
    from usdmotion.schemas import json_or_none

    try:
        document = json_or_none(path.read_bytes())  # absurd nesting refused, not recursed
    except OSError:
        return False
    return isinstance(document, dict) and "cuts" in document

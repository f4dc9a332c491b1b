"""``usdmotion check IN --limits limits.json``: report every range-of-motion or speed violation."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._analysis import Cutoff, FileUnits, Filter, FilterChoice, Frames, MotionInput, prepare
from usdmotion.cli._analysis_report import print_violations
from usdmotion.cli._options import Json, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def check(
    source: MotionInput,
    limits: Annotated[Path, typer.Option("--limits", "-l", help="Limits document (JSON/YAML, "
                                         "schemas/limits.schema.json).", show_default=False)],
    frames: Frames = None,
    filter: Filter = FilterChoice.butter,
    cutoff: Cutoff = 6.0,
    file_units: FileUnits = False,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Check joint ranges of motion and speeds against limits; exit code 1 if any is violated."""
    from usdmotion.check import check_motion, load_limits
    from usdmotion.ops.analyse.smoothing import FilterSpec

    rules = load_limits(limits)
    motion, first = prepare(source, read, frames)
    found = check_motion(motion, rules, str(limits), filter=FilterSpec(filter.value, cutoff), si=not file_units,
                         first_frame=first)
    if as_json:
        typer.echo(json.dumps({"file": str(source), "limits": str(limits), "violations": [v.as_dict() for v in found]},
                              indent=1))
    else:
        print_violations(found, source.name)
    if found:
        raise typer.Exit(1)

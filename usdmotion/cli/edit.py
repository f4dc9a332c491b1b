"""``usdmotion edit IN OUT --pipeline edits.json``: a list of editing operations."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._edit import Output, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def edit(
    source: InputPath,
    output: Output,
    pipeline: Annotated[Path, typer.Option(help="JSON list of operations (schemas/edit-pipeline.schema.json).",
                                           show_default=False)],
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Print a line per operation.")] = False,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Apply an edit pipeline (equalize, reorient, displace, layer, blend, speed, resample, cycle, trim)."""
    from usdmotion.ops.edit.pipeline import load_pipeline, run_pipeline

    operations = load_pipeline(pipeline)  # validate before reading the motion

    def report(i, op, motion):
        if verbose:
            typer.echo(f"  {i}: {op['op']}: {motion.n_frames} frames at {motion.fps:.6g} fps", err=True)

    def apply(motion):
        return run_pipeline(motion, operations, pipeline.resolve().parent, pipeline,
                            read=read.read, on_step=report)

    run_edit(source, output, apply, f"{len(operations)} operations from {pipeline.name}", read)

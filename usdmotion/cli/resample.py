"""``usdmotion resample IN OUT --fps N``: the same motion at another frame rate."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Interp, Output, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def resample(
    source: InputPath,
    output: Output,
    fps: Annotated[float, typer.Option(help="New frame rate (frames per second).", show_default=False)],
    interp: Interp = "cubic",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Resample to another frame rate (same duration; rotations interpolated as rotations)."""
    from usdmotion.ops.edit import resample as op

    run_edit(source, output, lambda m: op(m, fps, interp=interp), f"resampled to {fps:g} fps", read)

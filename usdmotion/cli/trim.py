"""``usdmotion trim IN OUT --frames START:STOP``: keep a range of frames."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Output, parse_range, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def trim(
    source: InputPath,
    output: Output,
    frames: Annotated[str, typer.Option(help="START:STOP, stop exclusive, frames or seconds (1.5s); negative "
                                             "counts from the end; either may be empty.", show_default=False)],
    read: ReadOptions = ReadOptions(),
) -> None:
    """Cut a motion down to frames START..STOP-1 (BVH Euler values kept as read)."""
    from usdmotion.ops.edit import trim as op

    def apply(motion):
        return op(motion, *parse_range(frames, motion.fps))

    run_edit(source, output, apply, f"trimmed to {frames}", read)

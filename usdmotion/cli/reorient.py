"""``usdmotion reorient IN OUT``: new heading and start position (rigid, about the up axis)."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Output, parse_floats, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def reorient(
    source: InputPath,
    output: Output,
    rotate: Annotated[float | None, typer.Option(help="Turn by DEG about the up axis (right-handed), around the "
                                                      "start position.", show_default=False)] = None,
    heading: Annotated[float | None, typer.Option(help="New travel direction in degrees: 0 = +Z (Y-up) or +X "
                                                       "(Z-up), 90 = +X (Y-up) or +Y (Z-up).",
                                                  show_default=False)] = None,
    position: Annotated[str | None, typer.Option(help="New start position: 'X,Z' (Y-up) / 'X,Y' (Z-up) on the "
                                                      "ground, or 'X,Y,Z'.", show_default=False)] = None,
    translate: Annotated[str | None, typer.Option(help="Move by 'X,Y,Z' file units.", show_default=False)] = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Re-orient and re-position a whole motion (walk south-west instead of north)."""
    from usdmotion.ops.edit import reorient as op

    def apply(motion):
        return op(motion, rotate=rotate, heading_deg=heading, position=parse_floats(position, "--position", (2, 3)),
                  translate=parse_floats(translate, "--translate", (3,)))

    run_edit(source, output, apply, "re-oriented", read)

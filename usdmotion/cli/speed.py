"""``usdmotion speed IN OUT``: time-warp by a constant factor or a keyed speed curve."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Interp, Joint, Keys, Output, Subtree, parse_keys, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def speed(
    source: InputPath,
    output: Output,
    factor: Annotated[float | None, typer.Option(help="Constant speed: 2 plays twice as fast (half the frames).",
                                                 show_default=False)] = None,
    key: Keys = None,
    joint: Joint = None,
    subtree: Subtree = False,
    interp: Interp = "cubic",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Change the playing speed; --key SOURCE_FRAME=SPEED (repeatable) gives a smooth speed curve."""
    from usdmotion.ops.edit import speed as op

    def apply(motion):
        return op(motion, factor=factor, keys=parse_keys(key, motion.fps), joint=joint, subtree=subtree,
                  interp=interp)

    run_edit(source, output, apply, f"speed {factor if factor is not None else 'curve'}", read)

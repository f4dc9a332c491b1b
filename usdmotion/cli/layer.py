"""``usdmotion layer IN OUT``: an additive curve on one channel."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Keys, Output, parse_keys, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def layer(
    source: InputPath,
    output: Output,
    joint: Annotated[str, typer.Option(help="The joint to edit.", show_default=False)],
    channel: Annotated[str, typer.Option(help="rx, ry, rz (degrees about the joint's axis) or tx, ty, tz (units).",
                                         show_default=False)],
    key: Keys = None,
    falloff: Annotated[str | None, typer.Option(help="Ease in/out over this many frames (or seconds) around the "
                                                     "keys.", show_default=False)] = None,
    frame: Annotated[str, typer.Option(help="Rotation axis of the joint's own frame (local) or its "
                                            "parent's.")] = "local",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Add a keyed curve (--key FRAME=VALUE, repeatable) to one channel of one joint."""
    from usdmotion.ops.edit import EditError, layer as op
    from usdmotion.ops.edit._common import frames_of

    def apply(motion):
        if not key:
            raise EditError("layer needs at least one --key FRAME=VALUE")
        return op(motion, joint, channel, parse_keys(key, motion.fps),
                  falloff=frames_of(falloff, motion.fps, "--falloff"), frame=frame)

    run_edit(source, output, apply, f"layer on {joint} {channel}", read)

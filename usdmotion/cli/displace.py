"""``usdmotion displace IN OUT``: displacement mapping from keyed pose changes."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Output, parse_floats, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app

KeyList = list[str] | None


@app.command()
@reads_motion
def displace(
    source: InputPath,
    output: Output,
    rotate: Annotated[KeyList, typer.Option(help="JOINT@FRAME=A,B,C: change the joint's rotation by Euler degrees "
                                                 "(its BVH order) at FRAME (repeatable).", show_default=False)] = None,
    pose: Annotated[KeyList, typer.Option(help="JOINT@FRAME=A,B,C: the joint's rotation at FRAME, Euler degrees.",
                                          show_default=False)] = None,
    move: Annotated[KeyList, typer.Option(help="JOINT@FRAME=X,Y,Z: add to the joint's translation at FRAME.",
                                          show_default=False)] = None,
    falloff: Annotated[str | None, typer.Option(help="Ease in/out over this many frames (or 0.5s) around the keys; "
                                                     "default: the change holds before/after.",
                                                show_default=False)] = None,
    frame: Annotated[str, typer.Option(help="Rotation changes in the joint's own frame (local) or its "
                                            "parent's.")] = "local",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Change a few poses; a smooth spline through the changes edits everything in between."""
    from usdmotion.ops.edit import EditError, displace as op
    from usdmotion.ops.edit._common import frames_of

    def apply(motion):
        keys = []
        for field, specs in (("rotate", rotate), ("rotation", pose), ("translate", move)):
            for spec in specs or []:
                where, sep, values = spec.partition("=")
                joint, at, when = where.rpartition("@")
                if not (sep and at and joint):
                    raise EditError(f"key {spec!r}: expected JOINT@FRAME=A,B,C")
                keys.append({"joint": joint, "frame": frames_of(when, motion.fps, f"key {spec!r}"),
                             field: parse_floats(values, f"key {spec!r}", (3,))})
        return op(motion, keys, falloff=frames_of(falloff, motion.fps, "--falloff"), frame=frame)

    run_edit(source, output, apply, "displaced", read)

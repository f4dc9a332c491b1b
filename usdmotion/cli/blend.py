"""``usdmotion blend FIRST SECOND OUT``: blend one motion into another."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._edit import Interp, Joint, Keys, Output, Subtree, parse_keys, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app



def _time(text: str):
    return Annotated[str | None, typer.Option(help=text + " Frames, or seconds like 0.5s.", show_default=False)]


@app.command()
@reads_motion
def blend(
    source: InputPath,
    other: Annotated[Path, typer.Argument(help="The motion to blend into.", show_default=False)],
    output: Output,
    transition: _time("Length of the blend ramp (default 0.5 s).") = None,
    at: _time("Output frame where the ramp starts (default: it ends with FIRST).") = None,
    offset: _time("Output frame where SECOND's frame 0 plays (default: at, or found by --align).") = None,
    speed0: Annotated[float, typer.Option(help="Speed of the first motion.")] = 1.0,
    speed1: Annotated[float, typer.Option(help="Speed of the second motion.")] = 1.0,
    align: Annotated[str, typer.Option(help="Timing: none, peaks (needs --align-joint) or dtw.")] = "none",
    align_joint: Annotated[str | None, typer.Option(help="Joint whose channel is aligned (e.g. a thigh).",
                                                    show_default=False)] = None,
    align_channel: Annotated[str, typer.Option(help="auto (principal axis), rx, ry or rz.")] = "auto",
    curve: Annotated[str, typer.Option(help="Blend ramp: smooth or linear.")] = "smooth",
    key: Keys = None,
    method: Annotated[str, typer.Option(help="slerp or nlerp.")] = "slerp",
    joint: Joint = None, subtree: Subtree = False,
    map_joint: Annotated[list[str] | None, typer.Option("--map", help="FIRST=SECOND joint names (repeatable).",
                                                        show_default=False)] = None,
    interp: Interp = "cubic",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Blend FIRST into SECOND over a transition (default: the last 0.5 s of FIRST)."""
    from usdmotion.ops.edit import blend as op
    from usdmotion.ops.edit._common import frames_of

    second = read.read(other)
    mapping = dict(m.split("=", 1) for m in map_joint or [] if "=" in m)

    def apply(m):
        t = {k: frames_of(v, m.fps, f"--{k}") for k, v in (("transition", transition), ("at", at), ("offset", offset))}
        return op(m, second, **t, speed0=speed0, speed1=speed1, align=align, align_joint=align_joint,
                  align_channel=align_channel, curve=curve, keys=parse_keys(key, m.fps), method=method, joint=joint,
                  subtree=subtree, joint_map=mapping, interp=interp)

    run_edit(source, output, apply, f"blended into {other.name}", read)

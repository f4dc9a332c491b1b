"""``usdmotion cycle IN OUT``: loop a range with a cross-fade; the character keeps travelling."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Output, parse_range, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def cycle(
    source: InputPath,
    output: Output,
    frames: Annotated[str | None, typer.Option(help="Range START:STOP to loop (stop exclusive; frames or 1.5s); "
                                                    "STOP 'auto' finds the best loop end. Default: all.",
                                               show_default=False)] = None,
    loops: Annotated[int, typer.Option(help="How many times the loop plays.")] = 2,
    transition: Annotated[str | None, typer.Option(help="Cross-fade length, frames or seconds (default 0.25s, at "
                                                        "most a third of the range).", show_default=False)] = None,
    offset: Annotated[str, typer.Option(help="Path per loop: rigid (heading and position continue), translation "
                                             "(position only) or none (in place).")] = "rigid",
    method: Annotated[str, typer.Option(help="Rotation cross-fade: slerp or nlerp.")] = "slerp",
    read: ReadOptions = ReadOptions(),
) -> None:
    """Make a looping motion (cycle with offset)."""
    from usdmotion.ops.edit import cycle as op
    from usdmotion.ops.edit._common import frames_of

    def apply(motion):
        start, stop = parse_range(frames, motion.fps, allow_auto=True)
        n = frames_of(transition, motion.fps, "--transition", allow_zero=False)
        return op(motion, start, stop, transition=n, loops=loops, offset=offset, method=method)

    run_edit(source, output, apply, f"cycled {loops}x", read)

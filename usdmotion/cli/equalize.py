"""``usdmotion equalize IN OUT``: the motion equaliser (band gains, presets)."""

from __future__ import annotations

from typing import Annotated

import typer

from usdmotion.cli._edit import Joint, Output, Subtree, parse_floats, run_edit
from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def equalize(
    source: InputPath,
    output: Output,
    gains: Annotated[str | None, typer.Option(help="Gain per band, highest frequencies first, e.g. 0,0,0.5 "
                                                   "(bands past the list keep 1).", show_default=False)] = None,
    preset: Annotated[str | None, typer.Option(help="denoise, exaggerate, damp or jitter (gains set by the fps).",
                                               show_default=False)] = None,
    joint: Joint = None,
    subtree: Subtree = False,
    translations: Annotated[bool, typer.Option(help="Also filter the root path and joint translations.")] = True,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Equalise a motion: scale the frequency bands of every channel (Bruderlin & Williams)."""
    from usdmotion.ops.edit import equalize as op

    def apply(motion):
        return op(motion, gains=parse_floats(gains, "--gains"), preset=preset, joint=joint, subtree=subtree,
                  translations=translations)

    run_edit(source, output, apply, f"equalised ({preset or 'gains ' + str(gains)})", read)

"""``usdmotion synth SPEC OUT...``: build a motion from a table of angles, write BVH/USD, plot it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._analysis import read_any
from usdmotion.cli.app import app
from usdmotion.errors import UsdMotionError


@app.command()
def synth(
    spec: Annotated[Path, typer.Argument(help="Synthesis document (.json .yaml, schemas/synthesis.schema.json) or "
                                              "a shipped example name: giant_swing.", show_default=False)],
    outputs: Annotated[list[Path] | None, typer.Argument(help="Motion files to write: .bvh .usda .usdc .usdz .usd.",
                                                         show_default=False)] = None,
    plot: Annotated[Path | None, typer.Option(help="Stick-figure strip of every frame (.png .pdf .svg).",
                                              show_default=False)] = None,
    show_spec: Annotated[bool, typer.Option("--print-spec", help="Print the (example) document and exit.")] = False,
) -> None:
    """Synthesise a motion from joint-angle tables (e.g. the 3-segment giant swing)."""
    from usdmotion.io import write_motion
    from usdmotion.synthesis import EXAMPLES, example_path

    source = example_path(str(spec)) if not spec.exists() and str(spec) in EXAMPLES else spec
    if show_spec:
        typer.echo(source.read_text(encoding="utf-8"))
        return
    if not outputs and plot is None:
        raise UsdMotionError("nothing to do: name output files (.bvh, .usdz ...) and/or --plot FILE.png")
    motion = read_any(source)
    for output in outputs or []:
        write_motion(motion, output)
        typer.echo(f"wrote {output}: {motion.n_joints} joints, {motion.n_frames} frames at {motion.fps:g} fps")
    if plot is not None:
        from usdmotion.kinplot import plot_strip

        plot_strip(motion, plot, title=f"{source.stem}: {motion.n_frames} frames at {motion.fps:g} fps",
                   mark_origin=True)
        typer.echo(f"wrote {plot}")

"""``usdmotion analyze IN``: joint kinematics, angles, angular rates, centre of mass."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._analysis import (Cutoff, EulerOrder, FileUnits, Filter, FilterChoice, Frames, MotionInput,
                                     SexChoice, body_for, prepare)
from usdmotion.cli._analysis_report import print_summary
from usdmotion.cli._options import Json, ReadOptions, reads_motion
from usdmotion.cli.app import app



def _opt(name: str, text: str):
    return Annotated[Path | None, typer.Option(name, help=text, show_default=False)]


@app.command()
@reads_motion
def analyze(
    source: MotionInput,
    joints: Annotated[str | None, typer.Option(help="Comma-separated joints to report (default: all).",
                                               show_default=False)] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Per-frame table: .csv, .parquet, or .json "
                                             "(summary + table).", show_default=False)] = None,
    summary: _opt("--summary", "Write the summary statistics as JSON.") = None,
    plot: _opt("--plot", "Figure (.png .pdf .svg): joint angles, speeds, top and side views of trajectories.") = None,
    frames: Frames = None,
    filter: Filter = FilterChoice.butter,
    cutoff: Cutoff = 6.0,
    euler_order: EulerOrder = None,
    mass: Annotated[float | None, typer.Option(help="Body mass in kg, 1 to 1000 (for the linear momentum).",
                                               show_default=False)] = None,
    sex: Annotated[SexChoice, typer.Option(help="de Leva (1996) table column.")] = SexChoice.male,
    segments: _opt("--segments", "Segment map (JSON/YAML): landmark overrides or a custom segment table.") = None,
    com: Annotated[bool, typer.Option(help="Compute the centre of mass.")] = True,
    file_units: FileUnits = False,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Kinematics per joint and frame, centre of mass, summary statistics, tables and plots."""
    from usdmotion.ops.analyse.measures import analyse, select_joints
    from usdmotion.ops.analyse.report import summary as summarise
    from usdmotion.ops.analyse.report import write_kinematics, write_summary
    from usdmotion.ops.analyse.smoothing import FilterSpec

    from usdmotion.kinplot import image_path
    from usdmotion.ops.analyse.report import table_path

    for path, check in ((out, table_path), (plot, image_path)):  # fail before the work, not after
        if path is not None:
            check(path)
    motion, first = prepare(source, read, frames)
    body = body_for(motion, source, com, sex, segments)
    kin = analyse(motion, FilterSpec(filter.value, cutoff), euler_order, body, mass, not file_units, first, str(source))
    chosen = select_joints(kin, [j.strip() for j in joints.split(",")] if joints else None, str(source))
    data = summarise(kin, chosen, str(source))
    for path, write in ((out, lambda p: write_kinematics(kin, p, chosen, str(source))),
                        (summary, lambda p: write_summary(data, p)), (plot, lambda p: _plot(kin, p, joints, chosen))):
        if path is not None:
            write(path)
            typer.echo(f"wrote {path}", err=True)
    typer.echo(json.dumps(data, indent=1)) if as_json else print_summary(data, source.name)


def _plot(kin, path: Path, joints: str | None, chosen: list[int]) -> None:
    from usdmotion.kinplot import plot_kinematics

    plot_kinematics(kin, path, chosen if joints else None, title=path.stem)

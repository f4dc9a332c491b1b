"""Options shared by several commands (typer ``Annotated`` aliases)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer


class RootOffsetChoice(str, Enum):
    auto = "auto"
    add = "add"
    replace = "replace"


class UpAxisChoice(str, Enum):
    Y = "Y"
    Z = "Z"
    auto = "auto"


InputPath = Annotated[Path, typer.Argument(help="Input motion: .bvh, .usd, .usda, .usdc or .usdz.",
                                           show_default=False)]
Units = Annotated[str | None, typer.Option(
    "--units", help="Length unit of a BVH file: cm, m, mm, in, ft, asf (CMU, 1/0.45 in), or metres per "
                    "unit as a number, or auto (guessed from the body, reason given; see docs/units_guess.md). "
                    "Default: cm for BVH; the stage's for USD.", show_default=False)]
UpAxis = Annotated[UpAxisChoice | None, typer.Option(
    "--up-axis", help="Vertical axis of a BVH file (default Y), or auto (guessed from the body); overrides a "
                      "USD stage's.", show_default=False,
    case_sensitive=False)]
RootOffset = Annotated[RootOffsetChoice, typer.Option(
    "--root-offset", help="BVH root OFFSET: 'add' to the root position channels (BVH spec), 'replace' by "
                          "them (Blender), or 'auto' (replace only when the channels already contain it).",
    case_sensitive=False)]
Lenient = Annotated[bool, typer.Option(
    "--lenient", help="Keep the complete motion rows when 'Frames:' disagrees or rows are malformed "
                      "(warns instead of failing).")]
IgnoreJointPositions = Annotated[bool, typer.Option(
    "--ignore-joint-positions", help="Use the OFFSETs of non-root joints even where they have position channels "
                                     "(for files whose such channels hold world positions).")]
Json = Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")]


def parse_start_stop(text: str | None) -> tuple[int | None, int | None]:
    """``(start, stop)`` of a ``--frames START:STOP`` option; either side may be empty."""
    if text is None:
        return None, None
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start, stop = (int(p) if p.strip() else None for p in parts)
    except ValueError:
        raise ValueError(f"--frames: {text!r} is not START:STOP (e.g. 1: or 100:400)") from None
    return start, stop


def read_input(path: Path, units: str | None, up_axis: UpAxisChoice | None,
               root_offset: RootOffsetChoice = RootOffsetChoice.auto, lenient: bool = False,
               ignore_joint_positions: bool = False):
    """Read a motion with the shared CLI options (progress shown for slow files)."""
    from usdmotion.cli._progress import progress
    from usdmotion.io import read_motion

    with progress(f"reading {path.name}"):
        return read_motion(path, root_offset=root_offset.value, units=units,
                           up_axis=None if up_axis is None else up_axis.value, lenient=lenient,
                           ignore_joint_positions=ignore_joint_positions)

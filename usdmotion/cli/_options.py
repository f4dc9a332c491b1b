"""Options shared by several commands (typer ``Annotated`` aliases)."""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._progress import progress


class RootOffsetChoice(str, Enum):
    auto = "auto"
    add = "add"
    replace = "replace"


class UpAxisChoice(str, Enum):
    Y = "Y"
    Z = "Z"
    auto = "auto"


InputPath = Annotated[Path, typer.Argument(help="Input motion: .bvh, .usd, .usda, .usdc, .usdz, .glb or .gltf.",
                                           show_default=False)]
Units = Annotated[str | None, typer.Option(
    "--units", help="Length unit of a BVH file: cm, m, mm, in, ft, asf (CMU, 1/0.45 in), or metres per "
                    "unit as a number, or auto (guessed from the body, reason given; see docs/units_guess.md). "
                    "Default for BVH: guessed from the body (a warning when not cm; cm when the skeleton is not "
                    "recognisably human); the file's for USD and glTF.", show_default=False)]
UpAxis = Annotated[UpAxisChoice | None, typer.Option(
    "--up-axis", help="Vertical axis of a BVH file, or auto (guessed from the body, reason given). Default for "
                      "BVH: guessed (a warning when not Y; Y when not guessed); overrides a USD or glTF file's.",
    show_default=False,
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


Skeleton = Annotated[str | None, typer.Option(
    "--skeleton", help="The ASF skeleton file for .amc input, the Skeleton prim path for a USD stage with "
                       "several skeletons, or the skin (index or name) of a glTF file with several.",
    show_default=False)]

Resample = Annotated[bool, typer.Option(
    "--resample", help="Read a USD animation whose time samples are unevenly spaced at even steps (the usual "
                       "step; USD interpolates) instead of refusing it.")]


@dataclass(frozen=True)
class ReadOptions:
    """How to read a motion file: the CLI's reading options, declared once (:func:`reads_motion`).

    ``units`` and ``up_axis`` state what a BVH file does not (and override a USD stage's);
    ``root_offset`` is ``"auto"``/``"add"``/``"replace"``; see :func:`usdmotion.io.read_motion`.
    """

    units: str | None = None
    up_axis: str | None = None
    root_offset: str = "auto"
    lenient: bool = False
    ignore_joint_positions: bool = False
    skeleton: str | None = None
    resample: bool = False

    def __post_init__(self) -> None:
        if self.units is not None:  # checked before any work, not after reading a long take
            from usdmotion.channels import resolve_units

            resolve_units(self.units)

    def read(self, path: Path):
        """The motion in ``path`` (progress shown for slow files)."""
        # Deferred so that loading the CLI (``--version``, ``--help``) does not import NumPy.
        from usdmotion.io import read_motion

        with progress(f"reading {path.name}"):
            return read_motion(path, **dataclasses.asdict(self))


#: The parameters :func:`reads_motion` adds to a command: (name, annotation, default).
READ_PARAMETERS = (("units", Units, None), ("up_axis", UpAxis, None), ("root_offset", RootOffset, RootOffsetChoice.auto),
                   ("lenient", Lenient, False), ("ignore_joint_positions", IgnoreJointPositions, False),
                   ("skeleton", Skeleton, None), ("resample", Resample, False))


def option_group(parameters: tuple, into: str, group: type) -> Callable[[Callable], Callable]:
    """A decorator that gives a typer command a group of options declared once.

    ``parameters`` are ``(name, Annotated type, default)``; the command declares a keyword
    parameter ``into`` and receives ``group(**values)`` there (enum values as their
    ``.value``). The group's options appear after the command's own in ``--help``.
    """
    def decorate(command: Callable) -> Callable:
        signature = inspect.signature(command, eval_str=True)
        own = [p for name, p in signature.parameters.items() if name != into]
        added = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=annotation)
                 for name, annotation, default in parameters]

        @functools.wraps(command)
        def wrapper(*args, **kwargs):
            values = {name: kwargs.pop(name) for name, _, _ in parameters}
            values = {name: v.value if isinstance(v, Enum) else v for name, v in values.items()}
            return command(*args, **{into: group(**values)}, **kwargs)

        wrapper.__signature__ = signature.replace(parameters=own + added)
        wrapper.__annotations__ = {p.name: p.annotation for p in own + added}
        return wrapper

    return decorate


#: Gives a command the shared reading options (``--units``, ``--up-axis``, ``--root-offset``,
#: ``--lenient``, ``--ignore-joint-positions``, ``--skeleton``, ``--resample``) as ``read: ReadOptions``; it
#: reads with ``read.read(path)``.
reads_motion = option_group(READ_PARAMETERS, "read", ReadOptions)

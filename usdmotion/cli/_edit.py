"""Shared plumbing of the editing commands (equalize, reorient, blend, speed, ...).

Every editing command reads IN, applies one library operation, writes OUT atomically
and prints one line. Library :class:`~usdmotion.ops.edit.EditError` become
``IN: message`` (exit 2, nothing written).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import ReadOptions
from usdmotion.cli._progress import progress
from usdmotion.errors import InputError, OutputError

Output = Annotated[Path, typer.Argument(help="Output motion: .bvh, .usd, .usda, .usdc or .usdz.", show_default=False)]
Joint = Annotated[str | None, typer.Option("--joint", help="Act on this joint only (default: the whole body).",
                                           show_default=False)]
Subtree = Annotated[bool, typer.Option("--subtree", help="With --joint: the joint and everything below it.")]
Interp = Annotated[str, typer.Option("--interp", help="Interpolation between frames: cubic (C², default) or linear "
                                                      "(slerp).")]
Keys = Annotated[list[str] | None, typer.Option("--key", help="A key FRAME=VALUE (repeatable); FRAME in frames or "
                                                              "seconds like 1.5s.", show_default=False)]


@contextlib.contextmanager
def naming(path: Path) -> Iterator[None]:
    """Turn library editing errors into one-line input errors naming ``path``."""
    from usdmotion.ops.edit import EditError

    try:
        yield
    except EditError as exc:
        raise InputError(path, str(exc)) from None


def run_edit(source: Path, output: Path, operation: Callable, what: str, read: ReadOptions = ReadOptions()) -> None:
    """Read ``source`` with ``read``, apply ``operation(motion)``, write ``output``, report."""
    from usdmotion.io import write_motion

    if source.resolve() == output.resolve():
        raise OutputError(f"{output}: output would overwrite the input")
    start = time.perf_counter()
    motion = read.read(source)
    with naming(source), progress(what):
        edited = operation(motion)
    with progress(f"writing {output.name}"):
        write_motion(edited, output)
    typer.echo(f"wrote {output}: {what}; {edited.n_frames} frames at {edited.fps:.6g} fps ({edited.duration:.2f} s), "
               f"from {motion.n_frames} frames [{time.perf_counter() - start:.2f} s]")


def parse_floats(text: str | None, what: str, count: tuple[int, ...] | None = None) -> list[float] | None:
    """``"1,2,3"`` → ``[1.0, 2.0, 3.0]`` (``None`` stays ``None``)."""
    from usdmotion.ops.edit import EditError

    if text is None:
        return None
    try:
        values = [float(v) for v in text.replace(" ", ",").split(",") if v]
    except ValueError:
        raise EditError(f"{what}: {text!r} is not a comma-separated list of numbers") from None
    if count and len(values) not in count:
        raise EditError(f"{what}: needs {' or '.join(map(str, count))} numbers, got {len(values)}")
    return values


def parse_keys(keys: list[str] | None, fps: float, what: str = "--key") -> list[tuple[float, float]] | None:
    """``["0=1", "1.5s=0.5"]`` → ``[(0.0, 1.0), (180.0, 0.5)]`` (frames, value)."""
    from usdmotion.ops.edit import EditError
    from usdmotion.ops.edit._common import frames_of

    if not keys:
        return None
    pairs = []
    for key in keys:
        frame, sep, value = key.partition("=")
        if not sep:
            raise EditError(f"{what} {key!r}: expected FRAME=VALUE")
        try:
            pairs.append((frames_of(frame, fps, f"{what} {key!r}"), float(value)))
        except ValueError:
            raise EditError(f"{what} {key!r}: {value!r} is not a number") from None
    return pairs


def parse_range(text: str | None, fps: float, allow_auto: bool = False):
    """``"START:STOP"`` (frames or seconds, either side may be empty; STOP may be ``auto``)."""
    from usdmotion.ops.edit import EditError
    from usdmotion.ops.edit._common import frames_of

    if text is None:
        return None, None
    start, sep, stop = text.partition(":")
    if not sep:
        raise EditError(f"--frames {text!r}: expected START:STOP")

    def one(part: str):
        part = part.strip()
        if not part:
            return None
        if allow_auto and part == "auto":
            return "auto"
        sign = -1 if part.startswith("-") else 1
        return sign * int(round(frames_of(part.lstrip("-"), fps, f"--frames {text!r}")))

    return one(start), one(stop)

"""Options and input handling shared by ``analyze``, ``check`` and ``synth``."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import ReadOptions, parse_start_stop
from usdmotion.errors import InputError, UsdMotionWarning

SPEC_SUFFIXES = (".json", ".yaml", ".yml")


class FilterChoice(str, Enum):
    butter = "butter"
    savgol = "savgol"
    none = "none"


class SexChoice(str, Enum):
    male = "male"
    female = "female"


MotionInput = Annotated[Path, typer.Argument(
    help="Motion (.bvh .usd .usda .usdc .usdz), a synthesis document (.json .yaml) or a shipped example name "
         "(giant_swing).", show_default=False)]
Frames = Annotated[str | None, typer.Option(
    "--frames", help="Frames to analyse, START:STOP (Python slice, STOP exclusive), e.g. 1: to skip the T-pose "
                     "frame of cgspeed CMU files.", show_default=False)]
Filter = Annotated[FilterChoice, typer.Option(
    "--filter", help="Smoothing before differentiation: zero-lag Butterworth, Savitzky-Golay, or none (five-point "
                     "derivative of the raw samples).", case_sensitive=False)]
Cutoff = Annotated[float, typer.Option(
    "--cutoff", help="Low-pass cutoff in Hz (-3 dB of the whole zero-lag filter; for savgol it sets the window). "
                     "6 Hz suits walking; use 10-15 Hz for sprints, strikes, jumps (0.1 Hz at least).")]
EulerOrder = Annotated[str | None, typer.Option(
    "--euler-order", help="Decompose every joint angle in this intrinsic order (XYZ, ZXY, ...); default: each "
                          "joint's BVH channel order.", show_default=False)]
FileUnits = Annotated[bool, typer.Option(
    "--file-units", help="Report lengths in file units instead of metres.")]


def read_any(path: Path, read: ReadOptions = ReadOptions()):
    """A motion from a motion file, a synthesis document, or a shipped example name."""
    from usdmotion.synthesis import EXAMPLES, example_path, load_synthesis

    if not path.exists() and str(path) in EXAMPLES:
        path = example_path(str(path))
    if path.suffix.lower() in SPEC_SUFFIXES:
        from usdmotion.channels import override_units_axis

        return override_units_axis(load_synthesis(path), read.units, read.up_axis)
    return read.read(path)


def frame_slice(spec: str | None, n_frames: int) -> tuple[int, int]:
    """``(start, stop)`` from ``"START:STOP"`` (either may be empty or negative)."""
    if spec is None:
        return 0, n_frames
    start, stop, _ = slice(*parse_start_stop(spec)).indices(n_frames)
    if stop - start < 2:
        raise ValueError(f"--frames {spec} leaves {max(stop - start, 0)} of {n_frames} frames; analysis needs 2")
    return start, stop


def prepare(path: Path, read: ReadOptions, frames: str | None):
    """``(motion sliced to --frames, first frame)``; warns about a leading rest-pose frame."""
    import warnings

    from usdmotion.kinematics import first_frame_jumps
    from usdmotion.ops.analyse.measures import slice_frames

    motion = read_any(path, read)
    start, stop = frame_slice(frames, motion.n_frames)
    if frames is None and first_frame_jumps(motion):
        warnings.warn(f"{path}: the motion jumps between frames 0 and 1 (a T-pose frame, as in cgspeed CMU files?); "
                      "--frames 1: skips it", UsdMotionWarning, stacklevel=2)
    if (start, stop) != (0, motion.n_frames):
        motion = slice_frames(motion, start, stop)
    return motion, start


def body_for(motion, path: Path, com: bool, sex: SexChoice, segments: Path | None):
    """The body model for the COM (``None`` when switched off or not found without ``--segments``)."""
    import warnings

    from usdmotion.anthropometry import body_model, load_segment_map

    if not com:
        return None
    segment_map = load_segment_map(segments) if segments is not None else None
    try:
        return body_model(motion, sex.value, segment_map, source=str(segments) if segments else str(path))
    except InputError as exc:
        if segments is not None:
            raise
        warnings.warn(f"no centre of mass: {exc}", UsdMotionWarning, stacklevel=2)
        return None

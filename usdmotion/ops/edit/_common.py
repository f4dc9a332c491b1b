"""Shared pieces of the editing operations: errors, joint selection, ranges, time specs."""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.motion import POSITION_CHANNELS, ROTATION_CHANNELS, Motion


class EditError(UsdMotionError, ValueError):
    """An editing operation got options it cannot honour (unknown joint, bad range...)."""


def check_result_frames(count: int, n_joints: int, what: str) -> None:
    """Refuse an edit whose result would have ``count`` frames that cannot be held: more than
    :data:`usdmotion.constants.MAX_FRAMES`, or ``(count, n_joints, 4)`` float64 rotations
    above half of this machine's memory (the result's other arrays and the writer need the
    rest). Checked before anything of that size is allocated (numpy's ``Unable to allocate
    3.81 TiB`` for ``speed --factor 1e-9`` was the error line before)."""
    from usdmotion.constants import MAX_FRAMES

    need = float(count) * max(int(n_joints), 1) * 4 * 8
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # not POSIX: the frame cap alone
        memory = float("inf")
    if count > MAX_FRAMES or need > memory / 2:
        shown = f"{count:,}" if count < 10**12 else f"{float(count):.3g}"  # 1e-300: 300 digits otherwise
        gib = need / 2**30
        raise EditError(f"{what}: the result would have {shown} frames "
                        f"({f'{gib:,.1f}' if gib < 1e9 else f'{gib:.3g}'} GiB of rotations); at most "
                        f"{MAX_FRAMES:,} frames whose rotations fit in half of this machine's "
                        f"{memory / 2**30:,.0f} GiB are supported")


def joint_index(motion: Motion, name: str) -> int:
    """Index of joint ``name``; :class:`EditError` with close names when absent."""
    try:
        return motion.joint_index(name)
    except KeyError as exc:
        raise EditError(exc.args[0]) from None


def select_joints(motion: Motion, joint: str | None = None, subtree: bool = False) -> np.ndarray:
    """Boolean mask ``(J,)`` of the joints an operation acts on.

    ``joint=None``: every joint. Otherwise the named joint alone, or with ``subtree``
    the joint and all its descendants.
    """
    mask = np.zeros(motion.n_joints, bool)
    if joint is None:
        mask[:] = True
        return mask
    j = joint_index(motion, joint)
    mask[motion.subtree(j) if subtree else j] = True
    return mask


def frame_range(motion: Motion, start: int | None, stop: int | None, what: str = "range",
                min_frames: int = 1) -> tuple[int, int]:
    """Validate ``[start, stop)`` (Python-style, negatives count from the end) → ints."""
    n = motion.n_frames
    lo = 0 if start is None else int(start)
    hi = n if stop is None else int(stop)
    lo = lo + n if lo < 0 else lo
    hi = hi + n if hi < 0 else hi
    if not (0 <= lo < n) or not (lo < hi <= n):
        raise EditError(f"{what} {_fmt_range(start, stop)} is outside the motion's frames 0..{n - 1} "
                        f"(start inclusive, stop exclusive)")
    if hi - lo < min_frames:
        raise EditError(f"{what} {lo}:{hi} has {hi - lo} frames, needs at least {min_frames}")
    return lo, hi


def _fmt_range(start, stop) -> str:
    return f"{'' if start is None else start}:{'' if stop is None else stop}"


def frames_of(value: float | int | str | None, fps: float, what: str, allow_zero: bool = True) -> float | None:
    """A duration or instant given in frames (number) or seconds (``"0.5s"``) → frames."""
    if value is None:
        return None
    if isinstance(value, str):
        text = value.strip().lower()
        try:
            frames = float(text[:-1]) * fps if text.endswith("s") else float(text)
        except ValueError:
            raise EditError(f"{what}: {value!r} is not a number of frames or seconds like '0.5s'") from None
    else:
        frames = float(value)
    if not math.isfinite(frames) or frames < 0 or (frames == 0 and not allow_zero):
        raise EditError(f"{what} must be {'≥' if allow_zero else '>'} 0, got {value!r}")
    return frames


def smoothstep(x: np.ndarray) -> np.ndarray:
    """``3x² − 2x³`` clipped to [0, 1]: a C¹ ramp with zero slope at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def translations_or_none(motion: Motion) -> np.ndarray | None:
    """``motion.joint_translations`` as a writable copy (``None`` stays ``None``)."""
    return None if motion.joint_translations is None else np.array(motion.joint_translations)


def animated_translation_joints(motion: Motion) -> np.ndarray:
    """Mask ``(J,)`` of non-root joints whose per-frame translation differs from the OFFSET."""
    moving = np.zeros(motion.n_joints, bool)
    if motion.joint_translations is not None:
        deviation = np.abs(motion.joint_translations - motion.offsets[None]).max(axis=(0, 2))
        moving = deviation > 1e-9
        moving[0] = False
    return moving


def rebuild(motion: Motion, rotations: np.ndarray, root_translation: np.ndarray,
            joint_translations: np.ndarray | None, fps: float | None = None,
            frame_times: np.ndarray | None = None) -> Motion:
    """A new motion with new per-frame data; BVH channels gain what the data now needs.

    Drops the Euler hint (``source_channels``); gives the root rotation channels and
    non-root joints position channels when the new data moves them. ``frame_times``: the
    source frames of the new frames, for per-frame data carried along (:meth:`Motion.with_frames`).
    """
    out = motion.with_frames(rotations, root_translation, joint_translations, fps=fps, frame_times=frame_times)
    channels = motion.channels
    if channels is None:
        return out
    fixed = list(channels)
    if not any(c in ROTATION_CHANNELS for c in fixed[0]):
        q = out.rotations[:, 0]
        if np.any(np.abs(q[:, 1:]) > 1e-12):
            fixed[0] = tuple(fixed[0]) + ("Zrotation", "Xrotation", "Yrotation")
    if joint_translations is not None:
        moving = animated_translation_joints(out)
        for j in np.flatnonzero(moving):
            if not any(c in POSITION_CHANNELS for c in fixed[j]):
                fixed[j] = POSITION_CHANNELS + (tuple(fixed[j]) or ("Zrotation", "Xrotation", "Yrotation"))
    if tuple(fixed) == channels:
        return out
    return dataclasses.replace(out, channels=tuple(fixed))


def ground_axes(motion: Motion) -> tuple[int, int, int]:
    """``(up, a, b)`` axis indices: heading 0° points along ``a``, 90° along ``b``.

    Y-up: up=Y, a=Z, b=X; Z-up: up=Z, a=X, b=Y (right-handed turns about the up axis).
    """
    return (1, 2, 0) if motion.up_axis == "Y" else (2, 0, 1)

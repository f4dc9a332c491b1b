"""Two takes on one picture (``render --compare OTHER --align …``): which frame of the
other take goes with each output frame, and where to put it.

* **Time** (``--align``):
  ``start``: both clocks run from each take's frame 0 (same seconds);
  ``frame:N,M``: the main take's frame ``N`` shows with the other's frame ``M``, both at
  their own rate from there;
  ``time``: dynamic time warping on the 8-D bone-angle feature
  (:func:`usdmotion.ops.segment.detect.bone_angles`, joints by role) with the blend code's DTW
  (:func:`usdmotion.ops.edit.align.subsequence_dtw` and ``warp_from_path``), each frame
  then snapped to the best match within ±2 frames of that smoothed warp: each frame of
  the main take gets the other take's best-matching frame, monotone in time.
* **Space**: the other take is turned about the vertical and moved on the floor so that
  its root position and heading (the line between its hips, by role) at the paired frame
  equal the main take's at the first output frame.

All in render space (metres, Y up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.motion import Motion
from usdmotion.ops.edit.align import subsequence_dtw, warp_from_path
from usdmotion.ops.segment.detect import bone_angles
from usdmotion.ops.segment.roles import find_roles

ALIGN_HELP = "start, time (DTW on bone angles) or frame:N,M"


@dataclass(frozen=True)
class Alignment:
    """How the other take maps onto the output frames.

    ``frames (N,)`` its source frames; ``turn (3, 3)`` and ``shift (3,)`` move its render-space
    points (``p @ turn.T + shift``); ``rate (N,)`` its local playback rate relative to the
    main take (1 = same speed); ``mode`` the ``--align`` value; ``moved`` whether the
    spatial alignment could be made (both takes have hips by role).
    """

    frames: np.ndarray
    turn: np.ndarray
    shift: np.ndarray
    rate: np.ndarray
    mode: str
    moved: bool = True  # False: no hips found by role in one of the takes, so it was left in place


def parse_align(text: str) -> tuple[str, int | None, int | None]:
    """``"time"`` → ``("time", None, None)``; ``"frame:10,42"`` → ``("frame", 10, 42)``."""
    text = (text or "").strip().lower()
    if text in ("start", "time"):
        return text, None, None
    if text.startswith("frame:"):
        try:
            n, m = (int(v) for v in text[6:].split(","))
        except ValueError:
            pass
        else:
            if n >= 0 and m >= 0:
                return "frame", n, m
    raise UsdMotionError(f"--align {text!r}: use {ALIGN_HELP} (frames are non-negative integers)")


def dtw_frames(motion: Motion, other: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Other take's frame ``(F,)`` matched to every frame of ``motion`` by DTW on the
    bone-angle feature (both at the main take's rate), and the smooth warp ``(F,)`` it was
    snapped from (for the local playback rate)."""
    try:
        a, b = bone_angles(motion), bone_angles(other)
    except UsdMotionError as exc:
        detail = str(exc).split(": ", 1)[-1].split("; name them")[0]
        raise UsdMotionError(f"--align time compares the limbs' bone angles: {detail} "
                             "(use --align start or frame:N,M)") from None
    step = other.fps / motion.fps  # other frames per main frame
    grid = np.arange(0.0, other.n_frames - 1 + 1e-9, step) if other.n_frames > 1 else np.zeros(1)
    b = np.stack([np.interp(grid, np.arange(other.n_frames), b[:, k]) for k in range(b.shape[1])], axis=1)
    cost = (a * a).sum(1)[:, None] + (b * b).sum(1)[None] - 2.0 * a @ b.T
    cost = np.maximum(cost, 0.0)
    warp = warp_from_path(subsequence_dtw(cost), len(a))
    # the blend's warp is smoothed over 5 frames; snap each frame to the best match within ±2
    near = np.clip(np.rint(warp).astype(np.int64)[:, None] + np.arange(-2, 3)[None], 0, cost.shape[1] - 1)
    best = near[np.arange(len(a)), np.argmin(np.take_along_axis(cost, near, axis=1), axis=1)]
    return np.maximum.accumulate(best.astype(np.float64)) * step, warp * step


def align_takes(motion: Motion, other: Motion, frames: np.ndarray, times: np.ndarray, mode: str,
                joints_of) -> Alignment:
    """The :class:`Alignment` of ``other`` for output ``frames (N,)`` at ``times (N,)`` s.

    ``joints_of(motion, frames) -> (n, J, 3)`` gives render-space joint positions.
    """
    kind, n, m = parse_align(mode)
    last = other.n_frames - 1
    if kind == "frame":
        if n >= motion.n_frames or m > last:
            raise UsdMotionError(f"--align {mode}: frame {n if n >= motion.n_frames else m} is outside the "
                                 f"{'main' if n >= motion.n_frames else 'compared'} take "
                                 f"({motion.n_frames if n >= motion.n_frames else other.n_frames} frames)")
        position = (times - n / motion.fps) * other.fps + m
        rate = np.ones(len(frames))
    elif kind == "time":
        matched, smooth = dtw_frames(motion, other)
        position = np.interp(times * motion.fps, np.arange(motion.n_frames), matched)
        rate = np.gradient(smooth)[frames] * motion.fps / other.fps if motion.n_frames > 1 else np.ones(len(frames))
    else:
        position = times * other.fps
        rate = np.ones(len(frames))
    other_frames = np.clip(np.rint(position), 0, last).astype(np.int64)
    try:
        turn, shift = _match_pose(motion, other, int(frames[0]), int(other_frames[0]), joints_of)
    except UsdMotionError:  # a rig without hips by role: compare in place, and say so
        return Alignment(other_frames, np.eye(3), np.zeros(3), rate, kind, moved=False)
    return Alignment(other_frames, turn, shift, rate, kind)


def _match_pose(motion: Motion, other: Motion, f: int, g: int, joints_of) -> tuple[np.ndarray, np.ndarray]:
    """Turn about Y and floor shift putting ``other``'s root and heading at frame ``g``
    onto ``motion``'s at frame ``f``."""
    def root_and_heading(take: Motion, frame: int):
        roles = find_roles(take)
        p = joints_of(take, np.array([frame]))[0]
        left = p[roles["left_hip"]] - p[roles["right_hip"]]
        forward = np.cross(left, [0.0, 1.0, 0.0])
        return p[0], np.arctan2(forward[0], forward[2])

    root_a, yaw_a = root_and_heading(motion, f)
    root_b, yaw_b = root_and_heading(other, g)
    angle = yaw_a - yaw_b
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about +Y: z→x by +angle
    shift = root_a - turn @ root_b
    shift[1] = 0.0  # on the floor: heights stay the takes' own
    return turn, shift


def clock_text(alignment: Alignment, i: int, other_fps: float, name: str) -> str:
    """One overlay line saying how the clocks map at output frame ``i``."""
    g = int(alignment.frames[i])
    how = {"time": f"DTW, {alignment.rate[i]:.2f}x", "start": "same clock", "frame": "from the paired frame"}
    where = "" if alignment.moved else ", not moved: no hips found"
    return f"{name or 'compare'}: frame {g}  {g / other_fps:6.3f} s  ({how[alignment.mode]}{where})"

"""Cycling: loop a range of frames with a cross-fade, the character keeps travelling.

The range ``S[0..L-1]`` becomes a loop of period ``P = L − n`` (``n`` = transition):
loop frame ``φ`` is ``S[φ]`` for ``φ ≥ n`` and, for ``φ < n``, a cross-fade from
``S[P+φ]`` (the end of the range, weight ``1 − w``) into ``S[φ]`` (weight ``w``), with
``w = smoothstep((φ+1)/(n+1))``. After loop frame ``P−1 = S[P−1]`` comes loop frame 0,
which starts as ``S[P]``: the loop is continuous in pose and velocity everywhere. The
output starts at loop frame ``n`` (``S[n]``, an original frame) and repeats ``loops``
times.

The ground path is not cross-faded: its per-frame steps (taken in the character's frame)
are looped and integrated, so every loop carries on from where the previous one ended
("cycle with offset"). ``offset="rigid"`` (default) continues heading and position (a
curved walk keeps curving); ``"translation"`` continues the position only (MotionLab's
rule: the heading is cross-faded like the pose); ``"none"`` cross-fades the position too
(an in-place loop).
"""

from __future__ import annotations

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.kinematics import joint_positions
from usdmotion.motion import Motion
from usdmotion.ops.edit import trajectory as T
from usdmotion.ops.edit._common import EditError, check_result_frames, frame_range, smoothstep
from usdmotion.ops.edit.timewarp import trim

OFFSETS = ("rigid", "translation", "none")


def cycle(motion: Motion, start: int | None = None, stop: int | str | None = None, transition: int | None = None,
          loops: int = 2, offset: str = "rigid", method: str = "slerp") -> Motion:
    """Loop frames ``[start, stop)`` ``loops`` times with a cross-fade of ``transition`` frames.

    Default transition: a quarter second, at most a third of the range. ``stop="auto"``
    picks the end whose last ``transition`` frames best match the first ones (see
    :func:`loop_end`). The output has ``loops × (stop − start − transition)`` frames.
    """
    if offset not in OFFSETS:
        raise EditError(f"cycle offset must be one of {', '.join(OFFSETS)}, got {offset!r}")
    if method not in ("slerp", "nlerp"):
        raise EditError(f"cycle method must be slerp or nlerp, got {method!r}")
    if isinstance(loops, bool) or not isinstance(loops, int | np.integer) or loops < 1:
        raise EditError(f"loops must be a whole number ≥ 1, got {loops!r}")
    if isinstance(stop, str):
        if stop != "auto":
            raise EditError(f"cycle stop must be a frame number or 'auto', got {stop!r}")
        lo, _ = frame_range(motion, start, None, "cycle range", min_frames=3)
        n = int(round(0.25 * motion.fps)) if transition is None else int(round(transition))
        hi = loop_end(motion, lo, max(n, 1))
    else:
        lo, hi = frame_range(motion, start, stop, "cycle range", min_frames=3)
        n = None if transition is None else int(round(transition))
    length = hi - lo
    n = int(round(min(0.25 * motion.fps, length / 3.0))) if n is None else n
    if n < 1 or 2 * n + 1 > length:
        raise EditError(f"cycle transition must be 1..{(length - 1) // 2} frames for a {length}-frame range, got {n}")
    period = length - n
    check_result_frames(int(loops) * period, motion.n_joints, f"{loops} loops of {period} frames")
    # one frame past the range, where there is one, gives the path step out of its last frame
    segment = trim(motion, lo, min(hi + 1, motion.n_frames))
    carried, undo = T.to_root_carried(segment)
    if offset == "none":
        local = carried
    else:
        # the raw heading (no smoothing): a periodic motion gives exactly periodic path steps
        local, yaw, ground = T.split_path(carried, translation_only=offset == "translation", smooth_s=0.0)
    w = smoothstep((np.arange(n) + 1.0) / (n + 1.0))
    rotations, root, jt = _loop_frames(local, period, n, w, method)
    phase = (np.arange(loops * period) + n) % period
    rotations, root = rotations[phase], root[phase]
    jt = None if jt is None else jt[phase]
    looped = local.with_frames(rotations, root, jt)
    if offset != "none":
        d_yaw, d_ground = _loop_steps(yaw, ground, period, n, w)
        path_yaw, path_ground = T.integrate(d_yaw[phase[:-1]], d_ground[phase[:-1]], yaw[n], ground[n])
        root_rot, root_pos = T.join_path(looped, path_yaw, path_ground)
        rotations = np.array(looped.rotations)
        rotations[:, 0] = root_rot
        looped = looped.with_frames(rotations, root_pos, jt)
    return T.from_root_carried(looped, undo, motion)


def loop_end(motion: Motion, start: int, transition: int, min_period: float = 0.4) -> int:
    """The stop frame that makes ``[start, stop)`` loop best with a ``transition``-frame fade.

    Compares the pose windows ``S[φ]`` and ``S[P+φ]``, ``φ < transition`` (joint positions
    relative to the root in the character's heading frame, and their velocities) for every
    period ``P`` of at least ``min_period`` seconds, and returns ``start + P + transition``
    for the best ``P``.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    n = transition
    segment = trim(motion, start, None)
    carried, _ = T.to_root_carried(segment)
    local, _, _ = T.split_path(carried)
    p = joint_positions(local)
    p = (p - p[:, :1]).reshape(len(p), -1)
    features = np.concatenate([p[1:], np.diff(p, axis=0) * (0.1 * motion.fps)], axis=1)  # velocity per 0.1 s
    first_period = max(n + 1, int(round(min_period * motion.fps)))
    windows = sliding_window_view(features, n, axis=0)  # (count, D, n)
    count = len(windows) - n  # period P uses window P, and needs P + n ≤ len(features)
    if count <= first_period:
        raise EditError(f"cycle: from frame {start}, the motion is too short to find a loop of at least "
                        f"{min_period:g} s with a {n}-frame transition")
    head = windows[0]
    cost = ((windows[first_period:count + 1] - head[None]) ** 2).sum(axis=(1, 2))
    period = first_period + int(np.argmin(cost))
    return start + period + n + 1


def _loop_frames(local: Motion, period: int, n: int, w: np.ndarray, method: str):
    """One period of loop frames: rotations ``(P, J, 4)``, root ``(P, 3)``, joint translations."""
    joints = np.flatnonzero(~local.end_sites)
    rotations = np.array(local.rotations[:period])
    head = Q.to_c(local.rotations[:n, joints])
    tail = Q.to_c(local.rotations[period:period + n, joints])
    mix = Q.slerp if method == "slerp" else Q.nlerp
    rotations[:n, joints] = Q.from_c(mix(tail, head, np.broadcast_to(w[:, None], head.shape[1:])))
    root = np.array(local.root_translation[:period])
    root[:n] = (1.0 - w)[:, None] * local.root_translation[period:period + n] + w[:, None] * root[:n]
    jt = None
    if local.joint_translations is not None:
        jt = np.array(local.joint_translations[:period])
        wj = w[:, None, None]
        jt[:n] = (1.0 - wj) * local.joint_translations[period:period + n] + wj * jt[:n]
    return rotations, root, jt


def _loop_steps(yaw: np.ndarray, ground: np.ndarray, period: int, n: int, w: np.ndarray):
    """Path step from loop frame ``φ`` to the next, for every ``φ`` (``(P,)``, ``(P, 2)``)."""
    d_yaw, d_ground = T.steps(yaw, ground)  # L − 1 original steps
    last = len(d_yaw) - 1
    d_yaw_loop = np.array(d_yaw[:period])
    d_ground_loop = np.array(d_ground[:period])
    w_next = np.append(w[1:], 1.0)
    wm = 0.5 * (w + w_next)  # weight of the step between two cross-faded frames
    tail = np.minimum(np.arange(n) + period, last)  # at the motion's very end the last step stands in
    d_yaw_loop[:n] = (1.0 - wm) * d_yaw[tail] + wm * d_yaw[:n]
    d_ground_loop[:n] = (1.0 - wm)[:, None] * d_ground[tail] + wm[:, None] * d_ground[:n]
    return d_yaw_loop, d_ground_loop

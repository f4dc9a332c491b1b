"""Displacement mapping and additive layers (MotionLab "edit", after Bruderlin & Williams).

A user changes a few poses; a smooth spline through those *changes* is added to the
motion, so everything between the keys follows the original movement. Rotation changes
are rotation vectors ``δ(t)`` composed as rotations: ``q'(t) = q(t) · exp(δ(t))`` (the
change expressed in the joint's own frame, ``frame="local"``) or ``exp(δ(t)) · q(t)``
(in the parent's frame, ``frame="parent"``). Translation changes are added.

The spline through the keyed changes is a clamped cubic (zero slope at the first and
last key, C² between), constant outside the keys. ``falloff`` adds zero keys that many
frames before the first and after the last key, so the change eases in and out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.motion import Motion
from usdmotion.ops.edit._common import EditError, joint_index, rebuild
from usdmotion.rotations import euler_to_quat, quat_conjugate, quat_log, quat_mul

FRAMES = ("local", "parent")
CHANNELS = ("rx", "ry", "rz", "tx", "ty", "tz")


def key_curve(frames: np.ndarray, values: np.ndarray, n_frames: int) -> np.ndarray:
    """Clamped cubic spline ``(F, D)`` through ``values (K, D)`` at ``frames (K,)``.

    Constant before the first and after the last key; one key gives a constant.
    """
    t = np.arange(n_frames, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if len(frames) == 1:
        return np.broadcast_to(values[0], (n_frames,) + values.shape[1:]).copy()
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(frames, values, axis=0, bc_type="clamped")
    return spline(np.clip(t, frames[0], frames[-1]))


def _check_frames(frames: list[float], n_frames: int, what: str) -> np.ndarray:
    f = np.asarray(frames, dtype=np.float64)
    if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f > n_frames - 1):
        bad = f[~np.isfinite(f) | (f < 0) | (f > n_frames - 1)][0]
        raise EditError(f"{what}: key frame {bad:g} is outside the motion's frames 0..{n_frames - 1}")
    if np.any(np.diff(f) <= 0):
        raise EditError(f"{what}: key frames must be distinct and increasing, got {f.tolist()}")
    return f


def _with_falloff(frames: np.ndarray, values: np.ndarray, falloff: float | None,
                  n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    if not falloff:
        return frames, values
    if not (math.isfinite(falloff) and falloff > 0):
        raise EditError(f"falloff must be a positive number of frames, got {falloff}")
    zero = np.zeros((1,) + values.shape[1:])
    if frames[0] > 0:
        frames = np.concatenate([[max(0.0, frames[0] - falloff)], frames])
        values = np.concatenate([zero, values])
    if frames[-1] < n_frames - 1:
        frames = np.concatenate([frames, [min(n_frames - 1.0, frames[-1] + falloff)]])
        values = np.concatenate([values, zero])
    return frames, values


def _apply_rotation_offsets(rotations: np.ndarray, j: int, delta: np.ndarray, frame: str) -> None:
    """In place: ``rotations[:, j] ∘ exp(delta (F, 3))`` on the side given by ``frame``."""
    q = Q.to_c(rotations[:, j])
    d = Q.exp(np.ascontiguousarray(delta.T))
    rotations[:, j] = Q.from_c(Q.mul(q, d) if frame == "local" else Q.mul(d, q))


def _euler_quat(motion: Motion, j: int, degrees, order: str | None) -> np.ndarray:
    angles = np.radians(np.asarray(degrees, dtype=np.float64))
    if angles.shape != (3,):
        raise EditError(f"a rotation needs 3 Euler angles in degrees, got {degrees!r}")
    order = order or _joint_order(motion, j)
    try:
        return euler_to_quat(angles, order)
    except ValueError as exc:
        raise EditError(str(exc)) from None


def _joint_order(motion: Motion, j: int) -> str:
    """The Euler order of a joint's BVH rotation channels (``ZXY`` when unknown)."""
    if motion.channels is not None:
        axes = "".join(c[0] for c in motion.channels[j] if c.endswith("rotation"))
        if len(axes) == 3:
            return axes
    return "ZXY"


def displace(motion: Motion, keys: Iterable[Mapping], falloff: float | None = None,
             frame: str = "local") -> Motion:
    """Displacement mapping from keyed pose changes.

    Each key is a mapping with ``joint`` and ``frame`` and any of:
    ``rotate`` (3 Euler degrees: a change of rotation), ``rotation`` (3 Euler degrees: the
    pose the joint must have at that frame), ``order`` (Euler order of those angles;
    default the joint's BVH channel order), ``translate`` (3 numbers added to the joint's
    translation; the root's is its world position). Keys of one joint are splined
    together; a joint keyed for rotation at some frames and not others gets a zero change
    at those others only if keyed so explicitly.
    """
    if frame not in FRAMES:
        raise EditError(f"displacement frame must be one of {', '.join(FRAMES)}, got {frame!r}")
    by_joint: dict[int, dict[str, list]] = {}
    for n, key in enumerate(keys):
        if not isinstance(key, Mapping) or "joint" not in key or "frame" not in key:
            raise EditError(f"displacement key {n}: needs 'joint' and 'frame'")
        j = joint_index(motion, str(key["joint"]))
        slot = by_joint.setdefault(j, {"rot": [], "trans": []})
        f = key["frame"]
        if isinstance(f, bool) or not isinstance(f, int | float) or not 0 <= f <= motion.n_frames - 1:
            raise EditError(f"displacement key {n}: frame {f!r} is outside the motion's frames "
                            f"0..{motion.n_frames - 1}")
        f = int(round(f))
        if "rotate" in key or "rotation" in key:
            if "rotate" in key and "rotation" in key:
                raise EditError(f"displacement key {n}: give 'rotate' (a change) or 'rotation' (a pose), not both")
            slot["rot"].append((f, _rotation_change(motion, j, f, key, frame)))
        if "translate" in key:
            t = np.asarray(key["translate"], dtype=np.float64)
            if t.shape != (3,) or not np.all(np.isfinite(t)):
                raise EditError(f"displacement key {n}: 'translate' needs 3 finite numbers, got {key['translate']!r}")
            slot["trans"].append((f, t))
        if not any(k in key for k in ("rotate", "rotation", "translate")):
            raise EditError(f"displacement key {n}: needs 'rotate', 'rotation' or 'translate'")
    if not by_joint:
        raise EditError("displacement needs at least one key")
    rotations = np.array(motion.rotations)
    root = np.array(motion.root_translation)
    jt = None if motion.joint_translations is None else np.array(motion.joint_translations)
    for j, slot in by_joint.items():  # loop over keyed joints (a handful), never frames
        name = motion.joint_names[j]
        if slot["rot"]:
            frames, values = _sorted_keys(slot["rot"], motion.n_frames, f"joint {name}")
            frames, values = _with_falloff(frames, values, falloff, motion.n_frames)
            _apply_rotation_offsets(rotations, j, key_curve(frames, values, motion.n_frames), frame)
        if slot["trans"]:
            frames, values = _sorted_keys(slot["trans"], motion.n_frames, f"joint {name}")
            frames, values = _with_falloff(frames, values, falloff, motion.n_frames)
            offset = key_curve(frames, values, motion.n_frames)
            if j == 0:
                root += offset
            else:
                if jt is None:
                    jt = np.broadcast_to(motion.offsets, (motion.n_frames,) + motion.offsets.shape).copy()
                jt[:, j] += offset
    return rebuild(motion, rotations, root, jt)


def _sorted_keys(pairs, n_frames: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    pairs = sorted(pairs, key=lambda p: p[0])
    frames = _check_frames([p[0] for p in pairs], n_frames, what)
    return frames, np.stack([p[1] for p in pairs])


def _rotation_change(motion: Motion, j: int, f: int, key: Mapping, frame: str) -> np.ndarray:
    """Rotation vector of the change a key asks for at frame ``f`` (continuous branch)."""
    if "rotate" in key:
        return quat_log(_euler_quat(motion, j, key["rotate"], key.get("order")))
    target = _euler_quat(motion, j, key["rotation"], key.get("order"))
    q = motion.rotations[f, j]
    change = quat_mul(quat_conjugate(q), target) if frame == "local" else quat_mul(target, quat_conjugate(q))
    return quat_log(change)


def layer(motion: Motion, joint: str, channel: str, keys, falloff: float | None = None,
          frame: str = "local") -> Motion:
    """An additive layer on one channel, edited as a curve.

    ``channel``: ``rx``/``ry``/``rz`` (degrees about the joint's own X/Y/Z axis, or the
    parent's with ``frame="parent"``) or ``tx``/``ty``/``tz`` (file units added to the
    joint's translation). ``keys``: ``[(frame, value), ...]`` joined by the same clamped
    cubic as :func:`displace`.
    """
    if channel not in CHANNELS:
        raise EditError(f"layer channel must be one of {', '.join(CHANNELS)}, got {channel!r}")
    if frame not in FRAMES:
        raise EditError(f"layer frame must be one of {', '.join(FRAMES)}, got {frame!r}")
    j = joint_index(motion, joint)
    try:
        pairs = sorted((float(f), float(v)) for f, v in keys)
    except (TypeError, ValueError):
        raise EditError(f"layer keys must be (frame, value) pairs, got {keys!r}") from None
    if not pairs or not all(math.isfinite(v) for _, v in pairs):
        raise EditError(f"layer keys must be a non-empty list of (frame, finite value) pairs, got {keys!r}")
    frames = _check_frames([p[0] for p in pairs], motion.n_frames, f"layer on {joint} {channel}")
    values = np.array([p[1] for p in pairs])[:, None]
    frames, values = _with_falloff(frames, values, falloff, motion.n_frames)
    curve = key_curve(frames, values, motion.n_frames)[:, 0]
    axis = "xyz".index(channel[1])
    rotations = np.array(motion.rotations)
    root = np.array(motion.root_translation)
    jt = None if motion.joint_translations is None else np.array(motion.joint_translations)
    if channel[0] == "r":
        delta = np.zeros((motion.n_frames, 3))
        delta[:, axis] = np.radians(curve)
        _apply_rotation_offsets(rotations, j, delta, frame)
    elif j == 0:
        root[:, axis] += curve
    else:
        if jt is None:
            jt = np.broadcast_to(motion.offsets, (motion.n_frames,) + motion.offsets.shape).copy()
        jt[:, j, axis] += curve
    return rebuild(motion, rotations, root, jt)

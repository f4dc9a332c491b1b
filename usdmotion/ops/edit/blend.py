"""Blending two motions: ``(1 − b(t))·m0 + b(t)·m1`` with a blend curve ``b``.

* Skeletons: the same joint names, or a ``joint_map`` from the first motion's names to
  the second's (parents must correspond); the output has the first motion's skeleton.
* Timing: each motion may play faster or slower (``speed0``/``speed1``); the second
  starts at output frame ``offset``, chosen by hand, by MotionLab's peak matching on a
  joint channel, or by dynamic time warping of the poses during the transition.
* Rotations: slerp (default) or nlerp of the local joint rotations.
* Path: the character's ground path (heading and position) is not blended as positions
  (two diverging paths would pull the body sideways); the per-frame steps of both paths,
  taken in the character's own frame, are blended and integrated from the first
  motion's path, so there is no jump and the second motion carries on from where the
  first one is.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.kinematics import joint_positions
from usdmotion.motion import Motion
from usdmotion.ops.edit import align as A
from usdmotion.ops.edit import trajectory as T
from usdmotion.ops.edit._common import (EditError, animated_translation_joints, joint_index, rebuild, select_joints,
                                        smoothstep)
from usdmotion.ops.edit.timewarp import resample, sample_motion, sample_values, speed

CURVES = ("smooth", "linear")
METHODS = ("slerp", "nlerp")
ALIGNMENTS = ("none", "peaks", "dtw")


def map_joints(m0: Motion, m1: Motion, joint_map: Mapping[str, str] | None, needed: np.ndarray) -> np.ndarray:
    """Index in ``m1`` of every joint of ``m0`` (``-1`` where unmapped) → ``(J0,)``.

    Raises :class:`EditError` if a ``needed`` non-end-site joint has no counterpart or the
    hierarchies disagree (a mapped joint's parent must map to the counterpart's parent).
    """
    joint_map = dict(joint_map or {})
    unknown = [k for k in joint_map if k not in m0.joint_names]
    if unknown:
        raise EditError(f"joint map names {unknown[0]!r}, which is not a joint of the first motion")
    lookup = {n: i for i, n in enumerate(m1.joint_names)}
    index = np.array([lookup.get(joint_map.get(n, n), -1) for n in m0.joint_names])
    missing = [m0.joint_names[j] for j in np.flatnonzero(needed & ~m0.end_sites & (index < 0))]
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        raise EditError(f"incompatible skeletons: the second motion has no joint for {', '.join(missing[:3])}{more} "
                        "(give a joint map)")
    if needed[0] and index[0] != 0:
        raise EditError(f"incompatible skeletons: the first motion's root {m0.joint_names[0]} must map to the "
                        f"second motion's root {m1.joint_names[0]}")
    for j in np.flatnonzero(needed & (index >= 0)):
        p = m0.parents[j]
        if p >= 0 and index[p] >= 0 and m1.parents[index[j]] != index[p]:
            raise EditError(f"incompatible skeletons: {m0.joint_names[j]}'s parent is {m0.joint_names[p]} in the first "
                            f"motion but {m1.joint_names[m1.parents[index[j]]]} in the second")
    return index


def blend_curve(n: int, at: float, transition: float, curve: str = "smooth", keys=None) -> np.ndarray:
    """Blend weights ``b (n,)``: 0 before ``at``, 1 from ``at + transition`` on.

    Frames ``at .. at + transition − 1`` are strictly between 0 and 1. ``keys``
    (``[(frame, b), ...]``) replace the ramp by a monotone cubic through them, clipped to
    [0, 1] and constant outside.
    """
    t = np.arange(n, dtype=np.float64)
    if keys is not None:
        try:
            pairs = sorted((float(f), float(b)) for f, b in keys)
        except (TypeError, ValueError):
            raise EditError(f"blend keys must be (frame, weight) pairs, got {keys!r}") from None
        frames = np.array([p[0] for p in pairs])
        values = np.array([p[1] for p in pairs])
        if not pairs or np.any(~np.isfinite(values)) or np.any((values < 0) | (values > 1)):
            raise EditError(f"blend key weights must lie in [0, 1], got {keys!r}")
        if np.any(np.diff(frames) <= 0):
            raise EditError(f"blend key frames must be distinct, got {frames.tolist()}")
        if len(pairs) == 1:
            return np.full(n, values[0])
        from scipy.interpolate import PchipInterpolator

        return np.clip(PchipInterpolator(frames, values)(np.clip(t, frames[0], frames[-1])), 0.0, 1.0)
    if curve not in CURVES:
        raise EditError(f"blend curve must be one of {', '.join(CURVES)}, got {curve!r}")
    x = (t - at + 1.0) / (transition + 1.0)
    return smoothstep(x) if curve == "smooth" else np.clip(x, 0.0, 1.0)


def _prepare(m0: Motion, m1: Motion, speed0: float, speed1: float, interp: str) -> tuple[Motion, Motion]:
    if m0.up_axis != m1.up_axis:
        raise EditError(f"cannot blend a {m0.up_axis}-up motion with a {m1.up_axis}-up one")
    if m1.meters_per_unit != m0.meters_per_unit:
        scale = m1.meters_per_unit / m0.meters_per_unit
        jt = None if m1.joint_translations is None else m1.joint_translations * scale
        m1 = dataclasses.replace(m1, offsets=m1.offsets * scale, root_translation=m1.root_translation * scale,
                                 joint_translations=jt, meters_per_unit=m0.meters_per_unit, source_channels=None)
    if abs(m1.fps - m0.fps) > 1e-9 * m0.fps:
        m1 = resample(m1, m0.fps, interp)
    if speed0 != 1.0:
        m0 = speed(m0, speed0, interp=interp)
    if speed1 != 1.0:
        m1 = speed(m1, speed1, interp=interp)
    return m0, m1


def blend(m0: Motion, m1: Motion, transition: float | None = None, at: float | None = None,
          offset: float | None = None, speed0: float = 1.0, speed1: float = 1.0, align: str = "none",
          align_joint: str | None = None, align_channel: str = "auto", curve: str = "smooth", keys=None,
          method: str = "slerp", joint: str | None = None, subtree: bool = False,
          joint_map: Mapping[str, str] | None = None, interp: str = "cubic") -> Motion:
    """Blend ``m0`` into ``m1`` (see the module docstring).

    Args:
        transition: frames over which ``b`` ramps 0 → 1 (default 0.5 s, at most the
            shorter motion).
        at: output frame where the ramp starts (default: so that it ends with ``m0``).
        offset: output frame at which ``m1``'s frame 0 plays (default: ``at``, or from
            ``align``). Frames are at ``m0``'s rate after ``speed0``.
        speed0, speed1: playback speed of each motion (2 = twice as fast).
        align: ``"none"``, ``"peaks"`` (last peak of ``m0``'s channel before the middle of
            the transition onto the first usable peak of ``m1``'s; needs ``align_joint``)
            or ``"dtw"`` (time-warp ``m1`` during the transition to match ``m0``'s poses,
            or ``align_joint``'s channel).
        align_channel: ``auto`` (principal rotation axis), ``rx``, ``ry`` or ``rz``.
        curve: ``"smooth"`` (C¹ smoothstep) or ``"linear"`` ramp; ``keys`` ``[(frame, b)]``
            instead give an editable curve.
        method: ``"slerp"`` or ``"nlerp"``.
        joint, subtree: blend only that joint (or subtree); the rest follows ``m0``.
        joint_map: first-motion joint name → second-motion joint name.
        interp: ``"cubic"`` or ``"linear"`` for time scaling and fractional frames.
    """
    for value, allowed, what in ((method, METHODS, "blend method"), (align, ALIGNMENTS, "alignment")):
        if value not in allowed:
            raise EditError(f"{what} must be one of {', '.join(allowed)}, got {value!r}")
    for value, what in ((speed0, "speed0"), (speed1, "speed1")):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise EditError(f"{what} must be a positive number, got {value!r}")
    selected = select_joints(m0, joint, subtree)
    index = map_joints(m0, m1, joint_map, selected)
    m0, m1 = _prepare(m0, m1, float(speed0), float(speed1), interp)
    n0, n1 = m0.n_frames, m1.n_frames
    if keys is not None and (transition is not None or at is not None or align == "dtw"):
        raise EditError("blend keys replace transition/at and cannot be used with dtw alignment")
    if transition is None:
        transition = float(min(round(0.5 * m0.fps), n0 - 1, n1 - 1))
    transition = int(round(transition))
    if transition < 1:
        raise EditError(f"blend transition must be at least 1 frame, got {transition}")
    at = float(n0 - transition) if at is None else float(at)
    if keys is None and (at < 0 or at + transition > n0):
        raise EditError(f"the transition {at:g}..{at + transition:g} does not fit in the first motion "
                        f"({n0} frames after speed0)")
    at = int(round(at))
    tau1_transition = None
    if align == "peaks" and offset is None:
        if align_joint is None:
            raise EditError("peak alignment needs align_joint (e.g. a thigh)")
        ja = _joint(m0, align_joint)
        s0, s1 = A.rotation_channels(m0.rotations[:, ja], m1.rotations[:, index[ja]], align_channel)
        offset = A.peak_offset(s0, s1, at, transition)
    elif align == "dtw":
        tau1_transition = _dtw_warp(m0, m1, index, at, transition, align_joint, align_channel)
    total = n0 + n1 + transition + 1 + max(0, 0 if offset is None else int(math.ceil(offset)))  # then cut
    b_full = blend_curve(total, at, transition, curve, keys)
    if offset is None:
        offset = float(np.argmax(b_full > 0)) if np.any(b_full > 0) else 0.0
    tau0, tau1 = _timelines(total, float(offset), tau1_transition, at, transition, b_full)
    n_out = _valid_length(b_full, tau0, tau1, n0, n1, partial=not selected.all())
    if keys is None and n_out < at + transition:
        raise EditError(f"the second motion ends at output frame {n_out - 1}, before the transition "
                        f"{at}..{at + transition} is over; start it earlier or shorten the transition")
    b = b_full[:n_out]
    return _blend_frames(m0, m1, index, selected, tau0[:n_out], tau1[:n_out], b, method, interp)


def _joint(motion: Motion, name: str) -> int:
    return joint_index(motion, name)


def _timelines(total: int, offset: float, tau1_transition, at: int, transition: int, b: np.ndarray):
    t = np.arange(total, dtype=np.float64)
    tau0 = t.copy()
    if tau1_transition is None:
        return tau0, t - offset
    # DTW: m1 follows the warp at the start of the transition and its own rate at the end
    warp = tau1_transition
    rate = np.diff(warp, append=warp[-1] + 1.0)
    rate = (1.0 - b[at:at + transition]) * rate + b[at:at + transition] * 1.0
    inside = warp[0] + np.concatenate([[0.0], np.cumsum(rate[:-1])])
    tau1 = np.empty(total)
    tau1[:at] = inside[0] - (at - t[:at])
    tau1[at:at + transition] = inside
    tau1[at + transition:] = inside[-1] + rate[-1] + (t[at + transition:] - at - transition)
    return tau0, tau1


def _valid_length(b, tau0, tau1, n0, n1, partial: bool) -> int:
    """Frames from 0 on where every motion the blend needs is playing."""
    eps = 1e-9
    has0 = tau0 <= n0 - 1 + eps
    has1 = (tau1 >= -eps) & (tau1 <= n1 - 1 + eps)
    ok = (~((b < 1.0) | partial) | has0) & (~(b > 0.0) | has1)
    n_out = len(ok) if ok.all() else int(np.argmin(ok))
    mixing = np.flatnonzero(b > 0)
    if n_out == 0 or (mixing.size and mixing[0] >= n_out):
        bad = n_out
        which = "first" if not has0[bad] else "second"
        raise EditError(f"the motions do not cover the blend: at output frame {bad} the {which} motion is not "
                        f"playing (the first has frames 0..{n0 - 1}; the second's frame 0 is at output frame "
                        f"{-tau1[0]:g}); change at, offset or transition")
    return n_out


def _dtw_warp(m0, m1, index, at, transition, align_joint, align_channel) -> np.ndarray:
    if align_joint is not None:
        ja = _joint(m0, align_joint)
        s0, s1 = A.rotation_channels(m0.rotations[:, ja], m1.rotations[:, index[ja]], align_channel)
        f0, f1 = s0[at:at + transition, None], s1[:, None]
    else:
        f0, f1 = _pose_features(m0, m1, index, at, transition)
    cost = (f0 * f0).sum(1)[:, None] + (f1 * f1).sum(1)[None] - 2.0 * f0 @ f1.T
    path = A.subsequence_dtw(np.maximum(cost, 0.0))
    return A.warp_from_path(path, transition)


def _pose_features(m0, m1, index, at, transition):
    """Joint positions in the root's heading frame (the whole body), both skeletons."""
    common = np.flatnonzero(index >= 0)
    feats = []
    for motion, joints, frames in ((m0, common, slice(at, at + transition)), (m1, index[common], slice(None))):
        carried, _ = T.to_root_carried(motion)
        local, _, _ = T.split_path(carried)
        p = joint_positions(local)[frames][:, joints]
        feats.append((p - p[:, :1]).reshape(len(p), -1))
    return feats[0], feats[1]


def _blend_frames(m0, m1, index, selected, tau0, tau1, b, method, interp) -> Motion:
    """Sample both motions where they are needed, blend, and put the result on the blended path."""
    whole_path = bool(selected[0])
    undo = None
    c0, c1 = m0, m1
    if whole_path:
        carrier = max(T.carrier_joint(m0), T.carrier_joint(m1))  # one root frame for both
        c0, undo = T.to_root_carried(m0, carrier)
        c1, _ = T.to_root_carried(m1, index[carrier] if carrier else 0)
        body = T.heading_vector(c0)  # one body-fixed vector: the same root frame for both
        path0 = (T.heading(c0, body), T.ground_position(c0))
        path1 = (T.heading(c1, body), T.ground_position(c1))
    tau1 = np.clip(tau1, 0, m1.n_frames - 1)
    n = len(b)
    i0 = np.flatnonzero((b < 1.0) | ~selected.all())  # frames that need the first motion
    i1 = np.flatnonzero(b > 0.0)
    r0, root0, jt0 = sample_motion(c0, tau0[i0], interp)
    r1, root1, jt1 = sample_motion(c1, tau1[i1], interp)
    if whole_path:  # root relative to each motion's own path
        r0[:, 0], root0 = _to_local(m0.up_axis, r0[:, 0], root0, path0, tau0[i0])
        r1[:, 0], root1 = _to_local(m0.up_axis, r1[:, 0], root1, path1, tau1[i1])
    rotations = np.empty((n, m0.n_joints, 4))
    rotations[:] = (1.0, 0.0, 0.0, 0.0)
    rotations[i0] = r0
    root = np.zeros((n, 3))
    root[i0] = root0
    jt = None
    if c0.joint_translations is not None:
        jt = np.broadcast_to(c0.joint_translations[:1], (n,) + c0.joint_translations.shape[1:]).copy()
        jt[i0] = jt0
    joints = np.flatnonzero(selected & ~m0.end_sites & (index >= 0))
    w = b[i1]
    full, part = w >= 1.0, w < 1.0  # only the transition needs interpolating
    if selected.all():  # whole body: the second motion's frames as they are, in the first's joint order
        mapped = r1[np.flatnonzero(full)][:, np.maximum(index, 0)]
        mapped[:, index < 0] = (1.0, 0.0, 0.0, 0.0)
        rotations[i1[full]] = mapped
    else:
        rotations[np.ix_(i1[full], joints)] = r1[np.ix_(np.flatnonzero(full), index[joints])]
    mixed = Q.slerp if method == "slerp" else Q.nlerp
    rows0, rows1, weight = i1[part], np.flatnonzero(part), w[part][:, None]

    def mix(chunk: np.ndarray) -> None:
        q0 = Q.gather_c(rotations[rows0], chunk)
        q1 = Q.gather_c(r1[rows1], index[chunk])
        rotations[np.ix_(rows0, chunk)] = Q.from_c(mixed(q0, q1, np.broadcast_to(weight, q0.shape[1:])))

    Q.over_chunks(mix, joints, len(rows0))
    if whole_path:
        root[i1] = (1.0 - w)[:, None] * root[i1] + w[:, None] * root1
    if jt is not None and jt1 is not None:
        moving = np.flatnonzero(selected & (index >= 0) & (animated_translation_joints(c0)
                                                           | animated_translation_joints(c1)[np.maximum(index, 0)]))
        moving = moving[moving > 0]
        rows = np.ix_(i1, moving)
        jt[rows] = (1.0 - w)[:, None, None] * jt[rows] + w[:, None, None] * jt1[:, index[moving]]
    if not whole_path:
        return rebuild(m0, rotations, root, jt)
    path_yaw, path_ground = _blend_path(*path0, *path1, tau0, tau1, b)
    rotations[:, 0], root = T.transform_root(m0.up_axis, rotations[:, 0], root, path_yaw, None, path_ground)
    return T.from_root_carried(c0.with_frames(rotations, root, jt), undo, m0)


def _to_local(up_axis, rot, pos, path, tau):
    """Root rotation/position relative to the path (heading, ground) sampled at ``tau``."""
    yaw = sample_values(path[0], tau, "linear")
    ground = sample_values(path[1], tau, "linear")
    return T.transform_root(up_axis, rot, pos, -yaw, None, -ground, before=True)


def _blend_path(yaw0, g0, yaw1, g1, tau0, tau1, b):
    """Blend the per-frame path steps and integrate them from the first motion's path."""
    y0 = sample_values(yaw0, tau0, "linear")
    p0 = sample_values(g0, tau0, "linear")
    y1 = sample_values(yaw1, tau1, "linear")
    p1 = sample_values(g1, tau1, "linear")
    d_yaw0, d_ground0 = T.steps(y0, p0)
    d_yaw1, d_ground1 = T.steps(y1, p1)
    w = 0.5 * (b[1:] + b[:-1])
    d_yaw = (1.0 - w) * d_yaw0 + w * d_yaw1
    d_ground = (1.0 - w)[:, None] * d_ground0 + w[:, None] * d_ground1
    return T.integrate(d_yaw, d_ground, y0[0], p0[0])

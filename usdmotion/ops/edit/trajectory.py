"""The character's path on the ground: heading, root-carried form, re-orientation.

Blending and cycling treat the horizontal path (position on the ground plane and heading
about the up axis) apart from the pose. Everything is expressed through the **root
joint** (joint 0), whose world transform moves the whole character rigidly:

* :func:`to_root_carried` handles rigs whose joint 0 stays still while its only child
  carries the world motion in its translation channels (Bandai Namco: ``joint_Root`` at
  the origin, ``Hips`` with the trajectory); the child's motion moves onto joint 0 and
  :func:`from_root_carried` puts it back.
* :func:`split_path` removes the per-frame ground transform (heading ``ψ(t)``, ground
  position) from the root; :func:`join_path` applies one.

Heading ``ψ`` is a right-handed angle about the up axis; ``ψ = 0`` points along Z for
Y-up files and along X for Z-up files, ``ψ = 90°`` along X (Y-up) or Y (Z-up).
"""

from __future__ import annotations

import math

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.motion import Motion
from usdmotion.ops.edit._common import EditError, ground_axes, rebuild, translations_or_none

_STILL = 1e-9


def carrier_joint(motion: Motion) -> int:
    """Joint that carries the world motion: 0, or the only child of a motionless root
    when that child has animated translation channels."""
    if motion.n_frames < 2 or motion.joint_translations is None:
        return 0
    root_moves = (np.ptp(motion.root_translation, axis=0).max() > _STILL
                  or np.ptp(motion.rotations[:, 0], axis=0).max() > _STILL)
    children = motion.children(0)
    if root_moves or len(children) != 1:
        return 0
    c = int(children[0])
    moves = np.ptp(motion.joint_translations[:, c], axis=0).max() > _STILL
    return c if moves else 0


def to_root_carried(motion: Motion, carrier: int | None = None) -> tuple[Motion, tuple | None]:
    """Move a carrier child's motion onto joint 0; returns the motion and what undoes it.

    ``carrier``: the joint to move (default :func:`carrier_joint`); blending passes the
    same one for both motions so that their root frames mean the same.
    """
    c = carrier_joint(motion) if carrier is None else int(carrier)
    if c == 0:
        return motion, None
    if motion.parents[c] != 0 or len(motion.children(0)) != 1 or motion.joint_translations is None:
        raise EditError(f"{motion.joint_names[c]} cannot carry the motion: it must be the root's only child "
                        "and have translation channels")
    q0 = Q.to_c(motion.rotations[:, 0])
    qc = Q.to_c(motion.rotations[:, c])
    tc = motion.joint_translations[:, c]
    rotations = np.array(motion.rotations)
    jt = np.array(motion.joint_translations)
    rotations[:, 0] = Q.from_c(Q.mul(q0, qc))
    root = motion.root_translation + Q.rotate(q0, tc.T).T
    rotations[:, c] = (1.0, 0.0, 0.0, 0.0)
    jt[:, c] = 0.0
    carried = motion.with_frames(rotations, root, jt)
    return carried, (c, motion.rotations[0, 0].copy(), motion.root_translation[0].copy())


def from_root_carried(motion: Motion, undo: tuple | None, template: Motion) -> Motion:
    """Inverse of :func:`to_root_carried` (``template``: the motion it was made from).

    Joint 0 gets the first frame's transform of the original for good (a still root, as
    the rig had), its child the rest of the motion.
    """
    if undo is None:
        return rebuild(template, motion.rotations, motion.root_translation, motion.joint_translations,
                       fps=motion.fps)
    c, q0, p0 = undo
    q0c = Q.to_c(q0)[:, None]
    inv = Q.conj(q0c)
    qr = Q.to_c(motion.rotations[:, 0])
    rotations = np.array(motion.rotations)
    jt = np.array(motion.joint_translations)
    rotations[:, c] = Q.from_c(Q.mul(inv, Q.mul(qr, Q.to_c(motion.rotations[:, c]))))
    world_c = motion.root_translation + Q.rotate(qr, motion.joint_translations[:, c].T).T
    jt[:, c] = Q.rotate(inv, (world_c - p0[None]).T).T
    rotations[:, 0] = q0
    root = np.broadcast_to(p0, motion.root_translation.shape)
    return rebuild(template, rotations, root, jt, fps=motion.fps)


def up_rotation(motion: Motion, angle: np.ndarray) -> np.ndarray:
    """Component-first quaternions ``(4, ...)`` turning by ``angle`` radians about the up axis."""
    up = ground_axes(motion)[0]
    angle = np.asarray(angle, dtype=np.float64)
    out = np.zeros((4,) + angle.shape)
    out[0] = np.cos(0.5 * angle)
    out[1 + up] = np.sin(0.5 * angle)
    return out


def heading_vector(motion: Motion) -> np.ndarray:
    """A vector ``(3,)`` fixed in joint 0's frame that is horizontal at frame 0.

    Of the two candidates (the ground axes seen from the root at frame 0), the one that
    stays farther from vertical over the motion is returned.
    """
    _, a, b = ground_axes(motion)
    q = Q.to_c(motion.rotations[:, 0])
    inv0 = Q.conj(q[:, :1])
    best, best_norm = None, -1.0
    for axis in (a, b):
        world = np.zeros((3, 1))
        world[axis] = 1.0
        body = Q.rotate(inv0, world)[:, 0]
        v = Q.rotate(q, np.broadcast_to(body[:, None], (3, q.shape[1])))
        norm = float(np.hypot(v[a], v[b]).min())
        if norm > best_norm:
            best, best_norm = body, norm
    return best


#: Heading is smoothed with a Gaussian of this many seconds: the pelvis turns back and
#: forth with every stride (±10-15° when running), which is pose, not path.
HEADING_SMOOTHING_S = 0.5


def heading(motion: Motion, body: np.ndarray | None = None, smooth_s: float = HEADING_SMOOTHING_S) -> np.ndarray:
    """Heading ``ψ(t)`` (radians, ``(F,)``, unwrapped) of joint 0 about the up axis.

    Measured from the body-fixed vector ``body`` (default :func:`heading_vector`; its
    choice only adds a constant; motions that are blended share one), then smoothed over
    ``smooth_s`` seconds (Gaussian σ) so the stride's pelvis swing stays in the pose.
    """
    _, a, b = ground_axes(motion)
    body = heading_vector(motion) if body is None else np.asarray(body, dtype=np.float64)
    q = Q.to_c(motion.rotations[:, 0])
    v = Q.rotate(q, np.broadcast_to(body[:, None], (3, q.shape[1])))
    yaw = np.unwrap(np.arctan2(v[b], v[a]))
    if smooth_s > 0 and len(yaw) > 1:
        from scipy.ndimage import gaussian_filter1d

        yaw = gaussian_filter1d(yaw, smooth_s * motion.fps, mode="nearest")
    return yaw


def ground_position(motion: Motion) -> np.ndarray:
    """Root position on the ground plane ``(F, 2)`` as ``(a, b)`` coordinates."""
    _, a, b = ground_axes(motion)
    return motion.root_translation[:, [a, b]]


def rotate2(v: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate ground vectors ``(..., 2)`` (``(a, b)`` coordinates) by ``angle`` about the up axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def split_path(motion: Motion, translation_only: bool = False, body: np.ndarray | None = None,
               smooth_s: float = HEADING_SMOOTHING_S) -> tuple[Motion, np.ndarray, np.ndarray]:
    """Remove the ground transform from joint 0: ``(local_motion, heading (F,), ground (F, 2))``.

    The local motion's root stands over the origin facing ``ψ = 0`` (or keeps its heading
    with ``translation_only``, where the returned heading is all zeros).
    """
    yaw = np.zeros(motion.n_frames) if translation_only else heading(motion, body, smooth_s)
    ground = ground_position(motion)
    local = apply_ground_transform(motion, -yaw, None, -ground, before=True)
    return local, yaw, ground


def join_path(local: Motion, yaw: np.ndarray, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root rotations ``(F, 4)`` and translations ``(F, 3)`` of ``local`` moved onto a path."""
    moved = apply_ground_transform(local, yaw, None, ground, before=False)
    return moved.rotations[:, 0], moved.root_translation


def apply_ground_transform(motion: Motion, angle: np.ndarray, pivot, shift: np.ndarray,
                           before: bool = False) -> Motion:
    """Move the whole motion by per-frame ground transforms on joint 0 (see :func:`transform_root`)."""
    rot, pos = transform_root(motion.up_axis, motion.rotations[:, 0], motion.root_translation, angle, pivot,
                              shift, before)
    rotations = np.array(motion.rotations)
    rotations[:, 0] = rot
    return motion.with_frames(rotations, pos, translations_or_none(motion))


def transform_root(up_axis: str, rot: np.ndarray, pos: np.ndarray, angle, pivot=None, shift=0.0,
                   before: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Root rotations ``(F, 4)`` and positions ``(F, 3)`` moved by per-frame ground transforms.

    ``before=False``: ``x' = R(angle)·(x − pivot) + pivot + shift``;
    ``before=True``: ``x' = R(angle)·(x + shift)`` (used to remove a path). ``angle``
    ``(F,)`` or scalar radians about the up axis, ``shift (F, 2)`` or ``(2,)`` ground
    coordinates, ``pivot`` ``(2,)`` or ``None``.
    """
    up, a, b = (1, 2, 0) if up_axis == "Y" else (2, 0, 1)
    n = len(pos)
    angle = np.broadcast_to(np.asarray(angle, dtype=np.float64), (n,))
    shift3 = np.zeros((n, 3))
    shift3[:, [a, b]] = np.broadcast_to(shift, (n, 2))
    p = np.array(pos, dtype=np.float64)
    if before:
        p += shift3
    elif pivot is not None:
        p[:, [a, b]] -= np.asarray(pivot, dtype=np.float64)
    turn = np.zeros((4, n))
    turn[0] = np.cos(0.5 * angle)
    turn[1 + up] = np.sin(0.5 * angle)
    p = Q.rotate(turn, p.T).T
    if not before:
        p += shift3
        if pivot is not None:
            p[:, [a, b]] += np.asarray(pivot, dtype=np.float64)
    return Q.from_c(Q.mul(turn, Q.to_c(rot))), p


def steps(yaw: np.ndarray, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame path steps: heading change ``(F−1,)`` and ground step ``(F−1, 2)``
    expressed in the frame of the earlier heading."""
    return np.diff(yaw), rotate2(np.diff(ground, axis=0), -yaw[:-1])


def integrate(dyaw: np.ndarray, dground: np.ndarray, yaw0: float, ground0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`steps`: heading ``(N+1,)`` and ground path ``(N+1, 2)``."""
    yaw = yaw0 + np.concatenate([[0.0], np.cumsum(dyaw)])
    moves = rotate2(dground, yaw[:-1])
    ground = np.asarray(ground0, dtype=np.float64) + np.concatenate([np.zeros((1, 2)), np.cumsum(moves, axis=0)])
    return yaw, ground


def carrier_ground_path(motion: Motion) -> np.ndarray:
    """Ground position ``(F, 2)`` of the joint that carries the motion (see :func:`carrier_joint`)."""
    carried, _ = to_root_carried(motion)
    return ground_position(carried)


def reorient(motion: Motion, rotate: float | None = None, heading_deg: float | None = None,
             position=None, translate=None) -> Motion:
    """Rigidly re-orient and re-position the whole motion about the up axis.

    Args:
        rotate: turn by this many degrees (right-handed about the up axis) around the
            character's ground position at frame 0.
        heading_deg: instead of ``rotate``: the new travel direction in degrees (direction
            from the first to the last ground position; 0° = +Z for Y-up, +X for Z-up).
        position: new position at frame 0 of the joint carrying the motion: 2 numbers
            (ground plane, in xyz order: x z for Y-up, x y for Z-up) or 3 (x y z).
        translate: ``(x, y, z)`` added after turning (file units).
    """
    if rotate is not None and heading_deg is not None:
        raise EditError("reorient takes rotate or heading, not both")
    _, a, b = ground_axes(motion)
    path = carrier_ground_path(motion)
    pivot = path[0]
    angle = 0.0
    if rotate is not None:
        angle = math.radians(_finite(rotate, "rotate"))
    elif heading_deg is not None:
        travel = path[-1] - path[0]
        extent = float(np.ptp(motion.root_translation, axis=0).max()) or 1.0
        if np.hypot(*travel) < 1e-3 * extent:
            raise EditError("the motion does not travel (start and end coincide): no heading to set; use rotate")
        angle = math.radians(_finite(heading_deg, "heading")) - math.atan2(travel[1], travel[0])
    shift = np.zeros(3)
    if position is not None:
        pos = np.asarray([_finite(v, "position") for v in position], dtype=np.float64)
        world = np.zeros(3)
        if pos.size == 2:
            axes = sorted((a, b))
            start_ground = dict(zip((a, b), pivot))
            shift[axes] = pos - np.array([start_ground[axes[0]], start_ground[axes[1]]])
        elif pos.size == 3:
            world = _carrier_start(motion)
            shift = pos - world
        else:
            raise EditError(f"position takes 2 (ground) or 3 (x y z) numbers, got {pos.size}")
    if translate is not None:
        t = np.asarray([_finite(v, "translate") for v in translate], dtype=np.float64)
        if t.size != 3:
            raise EditError(f"translate takes 3 numbers (x y z), got {t.size}")
        shift = shift + t
    moved = apply_ground_transform(motion, angle, pivot, shift[[a, b]], before=False)
    root = np.array(moved.root_translation)
    up = ground_axes(motion)[0]
    root[:, up] += shift[up]
    return rebuild(motion, moved.rotations, root, translations_or_none(motion))


def _carrier_start(motion: Motion) -> np.ndarray:
    carried, _ = to_root_carried(motion)
    return carried.root_translation[0]


def _finite(value, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise EditError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise EditError(f"{what} must be finite, got {value!r}")
    return v

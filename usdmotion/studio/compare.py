"""Compare two takes: time alignment (the blend code's DTW, or a manual offset) and
spatial alignment (root position and heading at one frame), for the viewer's ghost."""

from __future__ import annotations

import math

import numpy as np

from usdmotion.motion import Motion
from usdmotion.studio.takes import to_view

#: DTW runs on at most this many frames of each take (every k-th frame); the frame map is
#: interpolated back. The cost matrix is then at most 600 × 600.
DTW_FRAMES = 600


def _strided(motion: Motion, step: int) -> Motion:
    return motion.with_frames(motion.rotations[::step], motion.root_translation[::step],
                              None if motion.joint_translations is None else motion.joint_translations[::step],
                              fps=motion.fps / step, frame_times=np.arange(0, motion.n_frames, step))


def dtw_frame_map(a: Motion, b: Motion) -> np.ndarray:
    """Frame of ``b`` (float) that matches each frame of ``a`` → ``(F_a,)``, monotone.

    Whole-body poses in the root's heading frame (:func:`usdmotion.ops.edit.blend._pose_features`,
    in metres) matched by subsequence DTW (:func:`usdmotion.ops.edit.align.subsequence_dtw`):
    every frame of ``a`` is matched, ``b`` may start and end anywhere.

    Raises:
        EditError: the skeletons share no joint names.
    """
    from usdmotion.ops.edit.align import subsequence_dtw, warp_from_path
    from usdmotion.ops.edit.blend import _pose_features, map_joints

    sa, sb = max(1, math.ceil(a.n_frames / DTW_FRAMES)), max(1, math.ceil(b.n_frames / DTW_FRAMES))
    ma, mb = _strided(a, sa), _strided(b, sb)
    index = map_joints(ma, mb, None, np.zeros(ma.n_joints, dtype=bool))
    if np.count_nonzero(index >= 0) < 2:
        from usdmotion.ops.edit._common import EditError

        raise EditError("automatic alignment needs joints with the same names in both takes; use a manual offset")
    f0, f1 = _pose_features(ma, mb, index, 0, ma.n_frames)
    f0, f1 = f0 * a.meters_per_unit, f1 * b.meters_per_unit
    cost = (f0 * f0).sum(1)[:, None] + (f1 * f1).sum(1)[None] - 2.0 * f0 @ f1.T
    warp = warp_from_path(subsequence_dtw(np.maximum(cost, 0.0)), ma.n_frames) * sb
    return np.interp(np.arange(a.n_frames) / sa, np.arange(ma.n_frames), warp).clip(0, b.n_frames - 1)


def offset_frame_map(a: Motion, b: Motion, offset_s: float) -> np.ndarray:
    """Frame of ``b`` at each frame of ``a`` when ``b`` starts ``offset_s`` seconds later
    (real time, so takes at different rates stay in step) → ``(F_a,)``, clipped to ``b``."""
    t = np.arange(a.n_frames) / a.fps - offset_s
    return (t * b.fps).clip(0, b.n_frames - 1)


def ground_pose(motion: Motion, frame: int, body: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Root position on the ground ``(3,)`` (viewer axes, metres, y = 0) and heading angle
    (radians about +Y, ``atan2(x, z)`` of the facing direction) at ``frame``."""
    from usdmotion.ops.edit._common import ground_axes
    from usdmotion.ops.edit.trajectory import heading

    _, ax, bx = ground_axes(motion)
    yaw = float(heading(motion, body)[frame])
    facing = np.zeros(3)
    facing[ax], facing[bx] = math.cos(yaw), math.sin(yaw)
    facing = to_view(facing, motion.up_axis)
    root = to_view(motion.root_translation[frame] * motion.meters_per_unit, motion.up_axis).astype(np.float64)
    root[1] = 0.0
    return root, math.atan2(facing[0], facing[2])


def spatial_alignment(a: Motion, fa: int, b: Motion, fb: int) -> np.ndarray:
    """4×4 matrix (viewer axes, column vectors) that puts ``b``'s root at frame ``fb`` on
    ``a``'s root at frame ``fa``, on the ground and facing the same way."""
    from usdmotion.ops.edit.trajectory import heading_vector

    body = heading_vector(a) if a.joint_names == b.joint_names else None
    pa, ya = ground_pose(a, fa, body)
    pb, yb = ground_pose(b, fb, body)
    phi = ya - yb
    c, s = math.cos(phi), math.sin(phi)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = pa - rot @ pb
    return m

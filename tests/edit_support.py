"""Synthetic motions with known answers for the editing tests (no shared data needed)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from usdmotion.motion import Motion

NAMES = ("Hips", "Spine", "Head", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")
PARENTS = (-1, 0, 1, 0, 3, 4, 0, 6, 7)
OFFSETS = ((0, 90, 0), (0, 10, 0), (0, 40, 0), (10, 0, 0), (0, -40, 0), (0, -40, 0),
           (-10, 0, 0), (0, -40, 0), (0, -40, 0))


def euler_wxyz(angles_deg: np.ndarray, order: str = "ZXY") -> np.ndarray:
    """wxyz quaternions of intrinsic Euler angles in degrees (SciPy: upper-case = intrinsic)."""
    return Rotation.from_euler(order, angles_deg.reshape(-1, 3), degrees=True).as_quat(
        scalar_first=True).reshape(angles_deg.shape[:-1] + (4,))


def walker(n_frames: int = 240, fps: float = 60.0, period: int = 60, step: float = 1.5, heading_deg: float = 0.0,
           turn_deg_per_frame: float = 0.0, noise_deg: float = 0.0, seed: int = 0) -> Motion:
    """A periodic 'walk': legs swing with ``period`` frames, the hips advance ``step`` per frame
    along the heading (Y-up, heading 0 = +Z), optional constant turn and white noise."""
    t = np.arange(n_frames, dtype=np.float64)
    phase = 2 * np.pi * t / period
    euler = np.zeros((n_frames, len(NAMES), 3))  # (Z, X, Y) angles, order ZXY
    yaw = heading_deg + turn_deg_per_frame * t
    euler[:, 0, 2] = 5 * np.sin(phase)                  # pelvis yaw swing (the heading is added below)
    euler[:, 0, 0] = 3 * np.sin(2 * phase)              # pelvis roll
    euler[:, 1, 1] = 4 * np.sin(phase + 0.3)            # spine
    euler[:, 3, 1] = 30 * np.sin(phase)                 # left thigh
    euler[:, 4, 1] = 25 + 25 * np.sin(phase - 1.0)      # left knee
    euler[:, 6, 1] = -30 * np.sin(phase)                # right thigh
    euler[:, 7, 1] = 25 + 25 * np.sin(phase + np.pi - 1.0)
    if noise_deg:
        euler[:, :, 1:] += np.random.default_rng(seed).normal(0, noise_deg, euler[:, :, 1:].shape)
    rotations = euler_wxyz(euler)
    # the turn is about the world's up axis, outside the pelvis roll: turning walks stay periodic up to a turn
    turn = Rotation.from_euler("Y", yaw[:, None], degrees=True)
    rotations[:, 0] = (turn * Rotation.from_quat(rotations[:, 0], scalar_first=True)).as_quat(scalar_first=True)
    heading = np.radians(yaw)
    direction = np.stack([np.sin(heading), np.zeros_like(heading), np.cos(heading)], axis=-1)
    root = np.cumsum(np.concatenate([np.zeros((1, 3)), step * direction[:-1]]), axis=0)
    root[:, 1] = 90 + 2 * np.cos(2 * phase)
    channels = tuple(("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation") if j == 0
                     else ("Zrotation", "Xrotation", "Yrotation") for j in range(len(NAMES)))
    return Motion(joint_names=NAMES, parents=np.array(PARENTS), offsets=np.array(OFFSETS, float),
                  rotations=rotations, root_translation=root, fps=fps, channels=channels, root_offset="replace")


def angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle (radians) between wxyz quaternions, sign-independent."""
    from usdmotion.rotations import quat_conjugate, quat_mul

    rel = quat_mul(quat_conjugate(q1), q2)  # atan2 form: accurate near zero, unlike arccos(dot)
    return 2 * np.arctan2(np.linalg.norm(rel[..., 1:], axis=-1), np.abs(rel[..., 0]))


def position_spectrum(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """``(X (K, 3J) complex, f (K,) Hz)``: spectrum of the joint positions relative to the root,
    each channel detrended by the line through its first and last frame (no wrap-around step)."""
    from usdmotion.kinematics import joint_positions

    p = joint_positions(motion)
    x = (p - p[:, :1]).reshape(len(p), -1)
    x = x - np.linspace(x[0], x[-1], len(x))
    return np.fft.rfft(x, axis=0), np.fft.rfftfreq(len(x), 1 / motion.fps)


def frame_steps(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame max joint displacement ``(F-1,)`` and max velocity change ``(F-2,)``."""
    step = np.linalg.norm(np.diff(positions, axis=0), axis=-1).max(axis=1)
    jerk = np.linalg.norm(np.diff(positions, 2, axis=0), axis=-1).max(axis=1)
    return step, jerk

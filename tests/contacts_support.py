"""A procedural two-leg walk whose foot contacts are known by construction (tests only).

Every joint has identity rotations; the ankles and toes carry position channels, so their
world positions are exactly the trajectories built here. Each foot alternates a stance
(fixed on the floor) and a swing (eased forward over one stride, lifted by a sine arch).
"""

from __future__ import annotations

import numpy as np

from usdmotion.motion import Motion

NAMES = ("Hips", "Spine", "Neck", "Head", "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm",
         "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RightUpLeg", "RightLeg", "RightFoot",
         "RightToeBase")
PARENTS = (-1, 0, 1, 2, 1, 4, 5, 1, 7, 8, 0, 10, 11, 12, 0, 14, 15, 16)
OFFSETS = {"Spine": (0, 0.3, 0), "Neck": (0, 0.25, 0), "Head": (0, 0.1, 0), "LeftArm": (0.2, 0.2, 0),
           "LeftForeArm": (0.28, 0, 0), "LeftHand": (0.25, 0, 0), "RightArm": (-0.2, 0.2, 0),
           "RightForeArm": (-0.28, 0, 0), "RightHand": (-0.25, 0, 0), "LeftUpLeg": (0.1, -0.05, 0),
           "LeftLeg": (0, -0.42, 0), "LeftFoot": (0, -0.4, 0), "LeftToeBase": (0, -0.06, 0.12),
           "RightUpLeg": (-0.1, -0.05, 0), "RightLeg": (0, -0.42, 0), "RightFoot": (0, -0.4, 0),
           "RightToeBase": (0, -0.06, 0.12)}
ANKLE_HEIGHT, TOE_HEIGHT = 0.08, 0.02
PERIOD, SPEED, LIFT = 1.0, 1.2, 0.12
#: ``(joint, phase offset s, stance start s within the cycle, stance length s, x, z at cycle 0, rest height)``.
FEET = (("LeftFoot", 0.0, 0.0, 0.6, 0.1, 0.0, ANKLE_HEIGHT), ("LeftToeBase", 0.0, 0.05, 0.65, 0.1, 0.12, TOE_HEIGHT),
        ("RightFoot", 0.5, 0.0, 0.6, -0.1, 0.6, ANKLE_HEIGHT),
        ("RightToeBase", 0.5, 0.05, 0.65, -0.1, 0.72, TOE_HEIGHT))


def foot_track(t: np.ndarray, phase: float, start: float, stance: float, x: float, z0: float,
               height: float) -> tuple[np.ndarray, np.ndarray]:
    """``(positions (F, 3) m, contact (F,) bool)`` of one foot joint at times ``t``."""
    tau = t - phase - start
    k = np.floor(tau / PERIOD)
    within = tau - k * PERIOD
    planted = within < stance
    u = np.clip((within - stance) / (PERIOD - stance), 0, 1)
    stride = SPEED * PERIOD
    z = z0 + k * stride + np.where(planted, 0.0, stride * (1 - np.cos(np.pi * u)) / 2)
    y = height + np.where(planted, 0.0, LIFT * np.sin(np.pi * u))
    return np.stack([np.full_like(t, x), y, z], axis=1), planted


def synthetic_walk(fps: float = 120.0, seconds: float = 4.0, floor: float = 0.0) -> tuple[Motion, dict[str, np.ndarray]]:
    """The walk as a Y-up Motion in metres, and the true contact frames of each foot joint."""
    n = int(round(seconds * fps))
    t = np.arange(n) / fps
    index = {name: j for j, name in enumerate(NAMES)}
    offsets = np.array([(0, 0, 0)] + [OFFSETS[name] for name in NAMES[1:]], float)
    root = np.stack([np.zeros(n), np.full(n, 0.95 + floor), SPEED * t + 0.3], axis=1)
    world = {}
    truth = {}
    for joint, phase, start, stance, x, z0, height in FEET:
        world[joint], truth[joint] = foot_track(t, phase, start, stance, x, z0, height)
        world[joint][:, 1] += floor
    translations = np.broadcast_to(offsets, (n,) + offsets.shape).copy()
    for side in ("Left", "Right"):
        hip_to_ankle = root + offsets[index[f"{side}UpLeg"]] + offsets[index[f"{side}Leg"]]
        translations[:, index[f"{side}Foot"]] = world[f"{side}Foot"] - hip_to_ankle
        translations[:, index[f"{side}ToeBase"]] = world[f"{side}ToeBase"] - world[f"{side}Foot"]
    rotations = np.zeros((n, len(NAMES), 4))
    rotations[..., 0] = 1.0
    motion = Motion(NAMES, np.array(PARENTS), offsets, rotations, root, fps, joint_translations=translations,
                    meters_per_unit=1.0)
    return motion, truth

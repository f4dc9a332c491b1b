"""Foot-contact quality metrics: foot skate, floor penetration, floating.

Pure functions of joint positions ``(F, J, 3)`` in **metres**, the frame rate and a
:class:`~usdmotion.ops.contacts.detect.FootContacts` (which joints, which frames, the
floor, each joint's planted clearance, the up axis). Apply them to the source and to any
retargeted result whose contact joints are at ``contacts.indices`` (for another rig, give
its joint indices, floor and clearances with :func:`dataclasses.replace`).

* **Foot skate**: horizontal speed (the up component removed) of a contact joint between
  two consecutive frames that are both contact frames of that joint, cm/s: the mean and
  the maximum over all such steps of all contact joints, and the share of those steps
  faster than ``slide_speed`` (default 2 cm/s).
* **Floor penetration**: depth of a contact joint below its planted level
  (``floor + clearance``) in any frame, cm: the maximum, and the number of frames in
  which any contact joint is deeper than ``tolerance`` (default 1 mm).
* **Below the floor** (:func:`below_floor`): any joint under the floor plane, cm.
* **Floating**: contact frames in which the joint is more than ``float_height``
  (default 2 cm) above its planted level: their share of all contact frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.ops.contacts.detect import UP_INDEX, FootContacts

#: Horizontal speed (cm/s) above which a planted joint counts as sliding.
SLIDE_SPEED_CM_S = 2.0
#: Height (cm) above its planted level above which a planted joint counts as floating.
FLOAT_HEIGHT_CM = 2.0
#: Depth (cm) below the planted level from which a frame counts as penetrating.
PENETRATION_TOLERANCE_CM = 0.1


@dataclass(frozen=True)
class FootMetrics:
    """Contact quality of one motion (see the module docstring).

    Attributes:
        skate_mean_cm_s, skate_max_cm_s: horizontal speed of planted joints (cm/s).
        skate_share: share of planted steps sliding faster than the slide speed (0..1).
        penetration_max_cm: deepest point of a contact joint below its planted level (cm, >= 0).
        penetration_frames: frames in which any contact joint is below it by more than the tolerance.
        floating_share: share of contact frames more than the float height above it (0..1).
        floating_frames: number of such (joint, frame) contacts.
        contact_frames: number of (joint, frame) contacts.
        contact_steps: number of (joint, step) pairs with both frames in contact.
    """

    skate_mean_cm_s: float
    skate_max_cm_s: float
    skate_share: float
    penetration_max_cm: float
    penetration_frames: int
    floating_share: float
    floating_frames: int
    contact_frames: int
    contact_steps: int

    def as_dict(self) -> dict[str, float | int]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}

    def describe(self) -> str:
        """One line: ``foot skate 8.66 cm/s mean (max 49.6; 87 % of planted steps > 2 cm/s), ...``."""
        return (f"foot skate {self.skate_mean_cm_s:.2f} cm/s mean (max {self.skate_max_cm_s:.1f}; "
                f"{100 * self.skate_share:.0f} % of planted steps > {SLIDE_SPEED_CM_S:g} cm/s), "
                f"penetration {self.penetration_max_cm:.2f} cm max ({self.penetration_frames} frames), "
                f"floating {100 * self.floating_share:.0f} % of contact frames (> {FLOAT_HEIGHT_CM:g} cm)")


def _contact_positions(positions: np.ndarray, contacts: FootContacts) -> np.ndarray:
    positions = np.asarray(positions, float)
    if positions.ndim != 3 or positions.shape[-1] != 3 or positions.shape[0] != contacts.n_frames:
        raise ValueError(f"positions must be (F={contacts.n_frames}, J, 3), got {positions.shape}")
    return positions[:, contacts.indices]


def planted_speeds(positions: np.ndarray, fps: float, contacts: FootContacts) -> np.ndarray:
    """Horizontal speeds (cm/s) of every (step, joint) whose two frames are both contacts, 1-D."""
    p = _contact_positions(positions, contacts)
    step = np.diff(p, axis=0)
    step[..., UP_INDEX[contacts.up]] = 0.0
    speed = np.linalg.norm(step, axis=-1) * fps * 100.0
    both = contacts.contact[1:] & contacts.contact[:-1]
    return speed[both]


def foot_skate(positions: np.ndarray, fps: float, contacts: FootContacts,
               slide_speed: float = SLIDE_SPEED_CM_S) -> tuple[float, float, float, int]:
    """``(mean cm/s, max cm/s, share sliding > slide_speed, steps)``; zeros without contact steps."""
    speeds = planted_speeds(positions, fps, contacts)
    if speeds.size == 0:
        return 0.0, 0.0, 0.0, 0
    return float(speeds.mean()), float(speeds.max()), float(np.mean(speeds > slide_speed)), int(speeds.size)


def heights_above_planted(positions: np.ndarray, contacts: FootContacts) -> np.ndarray:
    """``(F, C)`` height of each contact joint above its planted level ``floor + clearance`` (cm)."""
    h = _contact_positions(positions, contacts)[..., UP_INDEX[contacts.up]]
    return (h - contacts.floor - contacts.clearance[None, :]) * 100.0


def floor_penetration(positions: np.ndarray, contacts: FootContacts,
                      tolerance: float = PENETRATION_TOLERANCE_CM) -> tuple[float, int]:
    """``(max depth cm >= 0, frames with any contact joint deeper than tolerance)``, all frames."""
    above = heights_above_planted(positions, contacts)
    if above.size == 0:
        return 0.0, 0
    depth = np.maximum(-above, 0.0)
    return float(depth.max()), int(np.count_nonzero((depth > tolerance).any(axis=1)))


def below_floor(positions: np.ndarray, floor: float, up: str) -> tuple[float, int]:
    """``(max depth cm >= 0, frames)`` of *any* joint below the floor plane itself (no clearance),
    positions ``(F, J, 3)`` in metres: the "no joint under the floor" check of a whole body."""
    h = np.asarray(positions, float)[..., UP_INDEX[up]] - floor
    if h.size == 0:
        return 0.0, 0
    depth = np.maximum(-h.min(axis=1), 0.0) * 100.0
    return float(depth.max()), int(np.count_nonzero(depth > PENETRATION_TOLERANCE_CM))


def floating(positions: np.ndarray, contacts: FootContacts,
             height: float = FLOAT_HEIGHT_CM) -> tuple[float, int, int]:
    """``(share, floating contacts, contacts)``: contact frames more than ``height`` cm above
    the joint's planted level."""
    above = heights_above_planted(positions, contacts)
    total = int(np.count_nonzero(contacts.contact))
    count = int(np.count_nonzero(contacts.contact & (above > height)))
    return (count / total if total else 0.0), count, total


def foot_metrics(positions: np.ndarray, fps: float, contacts: FootContacts) -> FootMetrics:
    """All three metrics with the default thresholds (positions ``(F, J, 3)`` in metres)."""
    mean, top, share, steps = foot_skate(positions, fps, contacts)
    depth, below = floor_penetration(positions, contacts)
    float_share, floats, total = floating(positions, contacts)
    return FootMetrics(mean, top, share, depth, below, float_share, floats, total, steps)


def motion_foot_metrics(motion, contacts: FootContacts) -> FootMetrics:
    """:func:`foot_metrics` of a :class:`~usdmotion.motion.Motion` (its joint positions in metres)."""
    from usdmotion.kinematics import joint_positions

    return foot_metrics(joint_positions(motion) * motion.meters_per_unit, motion.fps, contacts)

"""Plain-data descriptions of a ``Motion`` (for ``usdmotion info`` and reports)."""

from __future__ import annotations

from collections import Counter

import numpy as np

from usdmotion.constants import METERS_PER_UNIT
from usdmotion.channels import default_channels, rotation_order
from usdmotion.kinematics import rest_positions
from usdmotion.motion import POSITION_CHANNELS, ROTATION_CHANNELS, Motion


def unit_name(meters_per_unit: float) -> str | None:
    """The name of a unit (``"cm"``...) if ``meters_per_unit`` is one we know."""
    for name, value in METERS_PER_UNIT.items():
        if abs(value - meters_per_unit) <= 1e-12 * value:
            return name
    return None


def describe(motion: Motion) -> dict:
    """JSON-ready summary: counts, timing, units, channels and the joint hierarchy."""
    channels = motion.channels or default_channels(motion)
    rest = rest_positions(motion)
    height = float(np.ptp(rest, axis=0).max()) if motion.n_joints > 1 else 0.0
    orders = Counter(rotation_order(c) for c in channels if any(n in ROTATION_CHANNELS for n in c))
    with_positions = [motion.joint_names[j] for j, c in enumerate(channels)
                      if j > 0 and any(n in POSITION_CHANNELS for n in c)]
    return {
        "joints": int(np.count_nonzero(~motion.end_sites)),
        "end_sites": int(np.count_nonzero(motion.end_sites)),
        "frames": motion.n_frames,
        "fps": motion.fps,
        "frame_time": motion.frame_time,
        "duration_s": motion.duration,
        "channels": int(sum(len(c) for c in channels)),
        "rotation_orders": dict(orders),
        "joints_with_position_channels": with_positions,
        "meters_per_unit": motion.meters_per_unit,
        "units": unit_name(motion.meters_per_unit),
        "up_axis": motion.up_axis,
        "root_offset": motion.root_offset,
        "rest_extent": height,
        "rest_extent_m": height * motion.meters_per_unit,
        "hierarchy": [
            {
                "name": motion.joint_names[j],
                "parent": None if motion.parents[j] < 0 else motion.joint_names[motion.parents[j]],
                "offset": [float(v) for v in motion.offsets[j]],
                "channels": list(channels[j]),
                "end_site": bool(motion.end_sites[j]),
            }
            for j in range(motion.n_joints)
        ],
    }

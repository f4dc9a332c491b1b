"""Format-neutral channel layouts and length units (used by readers, writers and operations).

A *channel layout* is, per joint, the tuple of BVH-style channel names that animate it
(``("Xposition", ..., "Zrotation", "Xrotation", "Yrotation")``); the order of the rotation
channels is the joint's Euler order. Units are metres per file unit.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from usdmotion.constants import METERS_PER_UNIT
from usdmotion.motion import ROTATION_CHANNELS, Motion

DEFAULT_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
DEFAULT_JOINT_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")


def rotation_order(names: tuple[str, ...]) -> str:
    """Euler order of a joint's channel list: rotation channels in listed order, then
    the missing axes (whose angles are zero), e.g. ``("Zrotation",)`` → ``"ZXY"``."""
    present = "".join(n[0] for n in names if n in ROTATION_CHANNELS)
    return present + "".join(a for a in "XYZ" if a not in present)


def channel_columns(channels: tuple[tuple[str, ...], ...]) -> list[dict[str, int]]:
    """Per joint, channel name → column index in the ``(F, C)`` value array."""
    columns, k = [], 0
    for names in channels:
        columns.append({name: k + i for i, name in enumerate(names)})
        k += len(names)
    return columns


def euler_columns(columns: dict[str, int], order: str, missing: int) -> np.ndarray:
    """Column index of each axis of ``order`` (``missing`` for axes without a channel)."""
    return np.array([columns.get(f"{axis}rotation", missing) for axis in order])


def default_channels(motion: Motion) -> tuple[tuple[str, ...], ...]:
    """A BVH channel layout for a motion read from elsewhere (USD, synthesis).

    Root: 3 positions + ZXY rotations; joints with per-frame translations: the same;
    other joints: ZXY rotations; end sites: none.
    """
    moving = np.zeros(motion.n_joints, bool)
    if motion.joint_translations is not None:
        deviation = np.abs(motion.joint_translations - motion.offsets[None]).max(axis=(0, 2))
        moving = deviation > 1e-9
    layout = []
    for j in range(motion.n_joints):
        if j == 0 or moving[j]:
            layout.append(DEFAULT_ROOT_CHANNELS)
        elif motion.end_sites[j]:
            layout.append(())
        else:
            layout.append(DEFAULT_JOINT_CHANNELS)
    return tuple(layout)


def resolve_units(units: str | float) -> float:
    """Metres per unit from a name (``cm``, ``m``, ``mm``, ``in``, ``ft``, ``asf``) or a number."""
    if isinstance(units, (int, float)):
        value = float(units)
    else:
        key = str(units).strip().lower()
        if key in METERS_PER_UNIT:
            return METERS_PER_UNIT[key]
        try:
            value = float(key)
        except ValueError:
            raise ValueError(f"unknown units {units!r}: use one of {', '.join(METERS_PER_UNIT)} "
                             "or metres per unit as a number") from None
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"units must be a positive number of metres per unit, got {units!r}")
    return value


def override_units_axis(motion: Motion, units: str | float | None = None, up_axis: str | None = None) -> Motion:
    """``motion`` with its ``meters_per_unit`` and/or ``up_axis`` replaced where given
    (``units`` as for :func:`resolve_units`); the file's own values are kept otherwise."""
    changes = {}
    if units is not None:
        changes["meters_per_unit"] = resolve_units(units)
    if up_axis is not None:
        changes["up_axis"] = up_axis
    return dataclasses.replace(motion, **changes) if changes else motion

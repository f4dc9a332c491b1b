"""Format-neutral channel layouts and length units (used by readers, writers and operations).

A *channel layout* is, per joint, the tuple of BVH-style channel names that animate it
(``("Xposition", ..., "Zrotation", "Xrotation", "Yrotation")``); the order of the rotation
channels is the joint's Euler order. Units are metres per file unit.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from usdmotion.constants import MAX_METERS_PER_UNIT, METERS_PER_UNIT, MIN_METERS_PER_UNIT
from usdmotion.errors import UsdMotionWarning
from usdmotion.motion import CHANNEL_NAMES, ROTATION_CHANNELS, Motion

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
    if not (MIN_METERS_PER_UNIT <= value <= MAX_METERS_PER_UNIT):  # NaN fails too
        raise ValueError(f"units must be a number of metres per unit in {MIN_METERS_PER_UNIT:g}.."
                         f"{MAX_METERS_PER_UNIT:g} (a micrometre to 1,000 km), got {units!r}")
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


def trusted_layout(custom: dict, parents: np.ndarray, path: Path, where) -> tuple[np.ndarray, tuple | None]:
    """``(end_sites (J,), channels)`` from the source layout usdmotion keeps in a file (a USD
    skeleton's customData, a glTF skin's extras), distrusted: end sites must be leaves,
    channels known BVH names without repeats and none on an end site; metadata that fails is
    ignored with a warning (defaults: no end sites, a default layout)."""
    n = parents.size
    end_sites = np.zeros(n, bool)
    try:
        listed = np.array([int(j) for j in custom.get("endSites", [])], np.int64)
        channels = custom.get("channels")
        channels = None if channels is None else tuple(tuple(str(c).split()) for c in channels)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a JSON integer past int64
        listed, channels = np.zeros(0, np.int64), None
        warnings.warn(f"{path}: {where}: ignoring malformed usdmotion metadata", UsdMotionWarning, stacklevel=4)
    has_child = np.zeros(n, bool)
    has_child[parents[parents >= 0]] = True
    if listed.size and (np.any((listed < 0) | (listed >= n)) or has_child[listed[(listed >= 0) & (listed < n)]].any()):
        warnings.warn(f"{path}: {where}: ignoring usdmotion endSites that are not leaf joints", UsdMotionWarning,
                      stacklevel=4)
    elif listed.size:
        end_sites[listed] = True
    if channels is not None:
        bad = [c for cs in channels for c in cs if c not in CHANNEL_NAMES]
        repeated = any(len(set(cs)) != len(cs) for cs in channels)
        on_end_site = any(channels[j] for j in np.flatnonzero(end_sites)) if len(channels) == n else False
        if len(channels) != n or bad or repeated or on_end_site:
            why = (f"{bad[0]!r} is not a BVH channel" if bad else "a channel repeats" if repeated
                   else "an end site has channels" if on_end_site else f"{len(channels)} layouts for {n} joints")
            warnings.warn(f"{path}: {where}: ignoring the usdmotion channel layout ({why}); a default layout "
                          "is used for BVH output", UsdMotionWarning, stacklevel=4)
            channels = None
    return end_sites, channels

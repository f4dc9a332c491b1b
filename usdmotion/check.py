"""Kinematic constraint checks: joint ranges of motion and speed limits.

A limits document (JSON/YAML, ``schemas/limits.schema.json``) maps joint names or glob
patterns to limits::

    {"joints": {"LeftLeg":  {"x": [-5, 150], "bend": [0, 150], "max_angular_speed": 1000},
                "*Hand":    {"max_speed": 12}}}

* ``x`` / ``y`` / ``z``: ``[min, max]`` degrees of the joint angle about that axis, in the
  joint's Euler decomposition (its BVH channel order, or the document's ``euler_order``);
  ``null`` leaves a side open.
* ``bend``: ``[min, max]`` degrees between the bone into and out of the joint (0 = straight).
* ``max_angular_speed``: deg/s of the joint relative to its parent (``omega_rel``);
  ``max_segment_angular_speed``: deg/s of its segment in the world (``omega``);
  ``max_angular_acceleration``: deg/s² (relative); ``max_speed``: m/s of the joint
  (file units/s with ``si=False``); ``max_acceleration``: m/s².

:func:`check_kinematics` returns every :class:`Violation` as a run of consecutive frames
with its worst value, so a 40-frame excursion is one line, not forty.
"""

from __future__ import annotations

import fnmatch
import warnings
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from usdmotion.errors import InputError, UsdMotionWarning
from usdmotion.ops.analyse.measures import Kinematics, analyse
from usdmotion.schemas import load_document

RANGE_KEYS = ("x", "y", "z", "bend")
MAX_KEYS = ("max_angular_speed", "max_segment_angular_speed", "max_angular_acceleration", "max_speed",
            "max_acceleration")


@dataclass(frozen=True)
class Violation:
    """One run of consecutive frames where a joint breaks a limit.

    ``first_frame``/``last_frame`` are source frame indices (inclusive); ``value`` is the
    worst value in the run (at ``worst_frame``), ``limit`` the bound it broke, ``bound``
    ``"min"`` or ``"max"``.
    """

    joint: str
    quantity: str
    unit: str
    first_frame: int
    last_frame: int
    start_time: float
    end_time: float
    value: float
    worst_frame: int
    limit: float
    bound: str

    def as_dict(self) -> dict:
        return asdict(self)


def _matching(kin: Kinematics, pattern: str, source: str | None) -> list[int]:
    if not any(c in pattern for c in "*?["):
        if pattern not in kin.joint_names:
            import difflib

            close = difflib.get_close_matches(pattern, kin.joint_names, n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise InputError(source, f"/joints/{pattern}: no joint named {pattern!r}{hint}")
        return [kin.joint_names.index(pattern)]
    found = [j for j, name in enumerate(kin.joint_names) if fnmatch.fnmatchcase(name, pattern)]
    if not found:
        warnings.warn(f"{source or '<limits>'}: /joints/{pattern} matches no joint", UsdMotionWarning, stacklevel=3)
    return found


def _series(kin: Kinematics, j: int, key: str) -> tuple[np.ndarray, str]:
    length = kin.length_unit
    if key in ("x", "y", "z"):
        return kin.euler[:, j, "xyz".index(key)], "deg"
    if key == "bend":
        return kin.bend[:, j], "deg"
    vectors = {"max_angular_speed": (kin.omega_rel, "deg/s"), "max_segment_angular_speed": (kin.omega, "deg/s"),
               "max_angular_acceleration": (kin.alpha_rel, "deg/s^2"), "max_speed": (kin.velocities, f"{length}/s"),
               "max_acceleration": (kin.accelerations, f"{length}/s^2")}
    array, unit = vectors[key]
    return np.linalg.norm(array[:, j], axis=1), unit


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop_exclusive), ...]`` of the True runs of a boolean array."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _violations(kin: Kinematics, j: int, key: str, values: np.ndarray, unit: str, limit: float,
                bound: str) -> list[Violation]:
    bad = values < limit if bound == "min" else values > limit
    out = []
    for start, stop in _runs(bad):
        segment = values[start:stop]
        k = start + int(np.argmin(segment) if bound == "min" else np.argmax(segment))
        quantity = {"x": "angle X", "y": "angle Y", "z": "angle Z"}.get(key, key.removeprefix("max_"))
        if key in ("x", "y", "z"):
            quantity += f" ({kin.euler_orders[j]})"
        out.append(Violation(kin.joint_names[j], quantity, unit, int(kin.frames[start]), int(kin.frames[stop - 1]),
                             round(float(kin.time[start]), 6), round(float(kin.time[stop - 1]), 6),
                             round(float(values[k]), 4), int(kin.frames[k]), float(limit), bound))
    return out


def check_kinematics(kin: Kinematics, limits: Mapping, source: str | None = None) -> list[Violation]:
    """Every limit violation of ``kin`` (see the module docstring for ``limits``).

    Raises:
        InputError: a limit names an unknown joint, or a bend limit is set on a joint
            whose bend angle is undefined (root, leaf, branching joint).
    """
    found: list[Violation] = []
    for pattern, rules in limits.get("joints", {}).items():
        for j in _matching(kin, pattern, source):
            for key, rule in rules.items():
                if key in RANGE_KEYS:
                    values, unit = _series(kin, j, key)
                    if key == "bend" and not np.all(np.isfinite(values)):
                        raise InputError(source, f"/joints/{pattern}/bend: joint {kin.joint_names[j]!r} has no "
                                                 "single bone in and out, so no bend angle")
                    if kin.end_sites[j] and key != "bend":
                        continue
                    low, high = rule
                    if low is not None:
                        found += _violations(kin, j, key, values, unit, low, "min")
                    if high is not None:
                        found += _violations(kin, j, key, values, unit, high, "max")
                elif key in MAX_KEYS:
                    values, unit = _series(kin, j, key)
                    found += _violations(kin, j, key, values, unit, float(rule), "max")
    found.sort(key=lambda v: (v.first_frame, v.joint, v.quantity))
    return found


def check_motion(motion, limits: Mapping, source: str | None = None, **analyse_options) -> list[Violation]:
    """Analyse ``motion`` (options as :func:`usdmotion.ops.analyse.analyse`) and check it.

    ``limits["euler_order"]`` (if set) picks the Euler decomposition of the angle limits.
    """
    options = dict(analyse_options)
    if limits.get("euler_order"):
        options["euler_order"] = limits["euler_order"]
    return check_kinematics(analyse(motion, source=source, **options), limits, source)


def load_limits(path) -> dict:
    """Read and validate a limits document; also checks every ``[min, max]`` is ordered."""
    limits = load_document(path, "limits")
    for pattern, rules in limits.get("joints", {}).items():
        for key in RANGE_KEYS:
            if key in rules:
                low, high = rules[key]
                if low is not None and high is not None and low > high:
                    raise InputError(path, f"/joints/{pattern}/{key}: minimum {low} is above maximum {high}")
    return limits

"""Guess a skeleton's length unit and up axis from the body itself (BVH stores neither).

The body: the head top (else the neck) and the two ankles found by name (:func:`usdmotion.anthropometry.find_landmarks`).

* **Up axis.** The median over up to :data:`SAMPLE_FRAMES` frames of ``head_top - mean(ankles)``
  (a person stands or moves upright most of a take; rest poses are not used: some rigs
  lie along +X at rest). The axis of its largest component, if that is +Y or +Z and
  holds most of its length.
* **Units.** The bone chain from an ankle through the hips to the head top, summed bone
  by bone from the OFFSETs (pose independent, and blind to joint position channels,
  which some files abuse for world positions), is a standing height. The unit among :data:`CANDIDATES`
  for which that chain is :data:`HUMAN_CHAIN_M` long (1.1–2.3 m) is the guess; the
  windows of the candidates do not overlap, so at most one fits.

No head or ankles, or no fitting unit: no guess, and the reason says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.anthropometry import find_landmarks
from usdmotion.constants import METERS_PER_UNIT
from usdmotion.errors import UsdMotionWarning
from usdmotion.kinematics import joint_positions, rest_positions
from usdmotion.motion import Motion

CANDIDATES = ("cm", "m", "mm", "in", "asf", "ft")
HUMAN_CHAIN_M = (1.1, 2.3)     # ankle → head-top chain of an adult-ish human, metres
PLAUSIBLE_HEIGHT_M = (0.5, 3.0)  # outside this, a human skeleton's units are wrong
SAMPLE_FRAMES = 101
UP_SHARE = 0.8                 # the up component's share of the head–ankle vector


@dataclass(frozen=True)
class BodyGuess:
    """What the body says: ``units`` (a :data:`CANDIDATES` name or ``None``),
    ``up_axis`` (``"Y"``, ``"Z"`` or ``None``), and a sentence of reasons for each."""

    units: str | None
    units_reason: str
    up_axis: str | None
    up_reason: str
    chain_units: float | None = None   # ankle → head-top chain length, file units

    @property
    def meters_per_unit(self) -> float | None:
        return None if self.units is None else METERS_PER_UNIT[self.units]


def _path_to_root(parents: np.ndarray, j: int) -> list[int]:
    path = [j]
    while parents[path[-1]] >= 0:
        path.append(int(parents[path[-1]]))
    return path


def _chain_length(parents: np.ndarray, offsets: np.ndarray, a: int, b: int) -> float:
    """Summed bone lengths (``|offsets|``, ``(J, 3)``) on the tree path between joints ``a`` and ``b``."""
    up_a, up_b = _path_to_root(parents, a), _path_to_root(parents, b)
    common = set(up_a) & set(up_b)
    joints = [j for j in up_a if j not in common] + [j for j in up_b if j not in common]
    return float(np.linalg.norm(offsets[joints], axis=1).sum())


def _sample_positions(motion: Motion) -> np.ndarray:
    spread = np.linspace(0, max(motion.n_frames - 1, 0), SAMPLE_FRAMES).astype(int)  # sorted: repeats are neighbours
    idx = spread[np.r_[True, spread[1:] != spread[:-1]]]  # np.unique's result; np.unique imports numpy.ma (0.03 s)
    jt = None if motion.joint_translations is None else motion.joint_translations[idx]
    return joint_positions(motion.with_frames(motion.rotations[idx], motion.root_translation[idx], jt))


def _median_rows(a: np.ndarray) -> np.ndarray:
    """``np.median(a, axis=0)`` of ``a`` ``(n, 3)``, the same numbers (NaN where a column has one)
    without ``np.median``'s import of ``numpy.ma`` (0.03 s of every BVH read; start-up)."""
    s = np.sort(a, axis=0)
    middle = s[len(s) // 2] if len(s) % 2 else (s[len(s) // 2 - 1] + s[len(s) // 2]) / 2
    return np.where(np.isnan(s).any(axis=0), np.nan, middle)


def guess_body(motion: Motion, up: bool = True) -> BodyGuess:
    """Guess units and (if ``up``; it needs forward kinematics) the up axis of ``motion``
    from its head and ankles (see the module docstring)."""
    found, _ = find_landmarks(motion)
    head = found.get("head_top") if found.get("head_top") is not None else found.get("neck")
    ankles = [found.get("left_ankle"), found.get("right_ankle")]
    if head is None or None in ankles:
        why = "no head/neck and ankle joints found by name, so not recognisably a human skeleton"
        return BodyGuess(None, why, None, why)
    up_axis, up_reason = None, "not guessed"
    if up:
        positions = _sample_positions(motion) if motion.n_frames else rest_positions(motion)[None]
        vector = _median_rows(positions[:, head] - positions[:, ankles].mean(axis=1))
        up_axis, up_reason = _up_from(vector, motion.joint_names[head])
    chain = float(np.mean([_chain_length(motion.parents, motion.offsets, head, a) for a in ankles]))
    units, units_reason = _units_from(chain)
    return BodyGuess(units, units_reason, up_axis, up_reason, chain)


def _up_from(vector: np.ndarray, head_name: str) -> tuple[str | None, str]:
    k = int(np.argmax(np.abs(vector)))
    share = float(abs(vector[k]) / max(np.linalg.norm(vector), 1e-300))
    sign = "+" if vector[k] > 0 else "-"
    said = f"the head ({head_name}) is along {sign}{'XYZ'[k]} from the ankles ({share:.0%} of the way)"
    if k in (1, 2) and vector[k] > 0 and share >= UP_SHARE:
        return "XYZ"[k], said + " in the median frame"
    return None, said + ": not a clear +Y or +Z"


def _units_from(chain: float) -> tuple[str | None, str]:
    fits = [u for u in CANDIDATES if HUMAN_CHAIN_M[0] <= chain * METERS_PER_UNIT[u] <= HUMAN_CHAIN_M[1]]
    said = f"the ankle-to-head chain is {chain:.4g} units"
    if len(fits) == 1:
        u = fits[0]
        return u, f"{said}: {chain * METERS_PER_UNIT[u]:.2f} m in {u}, the only unit giving " \
                  f"{HUMAN_CHAIN_M[0]}–{HUMAN_CHAIN_M[1]} m"
    return None, f"{said}: no unit of {', '.join(CANDIDATES)} makes that {HUMAN_CHAIN_M[0]}–{HUMAN_CHAIN_M[1]} m"


def implausible_height(motion: Motion, guess: BodyGuess | None = None) -> str | None:
    """A warning sentence when ``motion`` is a human skeleton whose ankle-to-head chain,
    in its ``meters_per_unit``, is outside :data:`PLAUSIBLE_HEIGHT_M`; else ``None``."""
    guess = guess_body(motion) if guess is None else guess
    if guess.chain_units is None:
        return None
    metres = guess.chain_units * motion.meters_per_unit
    if PLAUSIBLE_HEIGHT_M[0] <= metres <= PLAUSIBLE_HEIGHT_M[1]:
        return None
    hint = f" (it looks like {guess.units}: --units {guess.units})" if guess.units else ""
    return (f"IMPLAUSIBLE UNITS: at {motion.meters_per_unit:g} m per unit this person is {metres:.3g} m tall "
            f"(ankle to head); pass the file's real units{hint}")


def apply_body_guess(motion: Motion, source, auto_units: bool, auto_up: bool, implicit_units: bool = False,
                     implicit_up: bool = False) -> Motion:
    """``motion`` with ``meters_per_unit`` / ``up_axis`` replaced by the body's guess where
    asked (``auto_units``, ``auto_up``); then the implausible-height warning.

    Asked for (``--units auto`` / ``--up-axis auto``), each guess, or why there is none and
    the value kept, is a warning with its reason. ``implicit_*`` (a BVH read without the
    option: auto is the default): a warning only where the guess changes the file's nominal
    reading (cm, Y-up), with its reason and how to choose otherwise; no guess keeps it quietly.
    """
    import dataclasses
    import warnings

    guess = guess_body(motion, up=auto_up)
    changes = {}
    if auto_units:
        if guess.units is not None:
            changes["meters_per_unit"] = guess.meters_per_unit
            if not implicit_units:
                warnings.warn(f"{source}: --units auto: {guess.units} ({guess.units_reason})", UsdMotionWarning,
                              stacklevel=2)
            elif guess.meters_per_unit != motion.meters_per_unit:
                warnings.warn(f"{source}: units guessed from the body: {guess.units} ({guess.units_reason}); "
                              "give --units to choose", UsdMotionWarning, stacklevel=2)
        elif not implicit_units:
            warnings.warn(f"{source}: --units auto: no guess, keeping {motion.meters_per_unit:g} m per unit "
                          f"({guess.units_reason})", UsdMotionWarning, stacklevel=2)
    if auto_up:
        if guess.up_axis is not None:
            changes["up_axis"] = guess.up_axis
            if not implicit_up:
                warnings.warn(f"{source}: --up-axis auto: {guess.up_axis} ({guess.up_reason})", UsdMotionWarning,
                              stacklevel=2)
            elif guess.up_axis != motion.up_axis:
                warnings.warn(f"{source}: up axis guessed from the body: {guess.up_axis} ({guess.up_reason}); "
                              "give --up-axis to choose", UsdMotionWarning, stacklevel=2)
        elif not implicit_up:
            warnings.warn(f"{source}: --up-axis auto: no guess, keeping {motion.up_axis} ({guess.up_reason})",
                          UsdMotionWarning, stacklevel=2)
    motion = dataclasses.replace(motion, **changes) if changes else motion
    loud = implausible_height(motion, guess)
    if loud:
        warnings.warn(f"{source}: {loud}", UsdMotionWarning, stacklevel=2)
    return motion

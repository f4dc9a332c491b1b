"""The factor that brings the source's positions into the target's units and size
(``retarget --scale units|auto|NUMBER``), with the checks that keep the target within reach."""

from __future__ import annotations

import numpy as np

from usdmotion.ops.retarget.hierarchy import RetargetError, UnitsMismatchError

#: Sizes (target / source, after unit conversion) outside this range mean the units disagree.
SIZE_RATIO_RANGE = (0.5, 2.0)


def source_scale(scale, mode: str, units: float, ratio: float, source_meters_per_unit: float, rig) -> float:
    """The factor applied to the source's positions.

    Args:
        scale: ``"units"`` (``units``: the motion keeps its physical size), ``"auto"``
            (``units · ratio``: fitted to the target's size) or a positive number.
        mode: ``"derived"`` (the rig is the source's, edited: always 1) or a target rig's mode.
        units: source metres per unit / target metres per unit.
        ratio: target size / source size after converting units (summed mapped bone lengths).
        source_meters_per_unit: for the message.
        rig: the target rig (``path``, ``meters_per_unit``), for the messages.

    Raises:
        UnitsMismatchError: ``units`` leaves the skeletons more than 2× apart in size.
        RetargetError: a number that is not positive, or that leaves the source more than 2×
            from ``auto``'s size (1e30 wrote a result with an RMS of 1e29 units, exit 0).
    """
    lo, hi = SIZE_RATIO_RANGE
    if mode == "derived":
        if scale not in ("units", "auto", 1, 1.0):
            raise RetargetError("--scale applies to --target only (a derived rig keeps the source's units)")
        return 1.0
    if scale == "units":
        if not lo <= ratio <= hi:
            raise UnitsMismatchError(
                f"{rig.path}: the target skeleton is {ratio:.3g}x the size of the source after converting units "
                f"({source_meters_per_unit:g} -> {rig.meters_per_unit:g} m/unit): the units look mismatched; state "
                "them with --units / --target-units, or pass --scale auto to fit the source to the target's size")
        return units
    if scale == "auto":
        return units * ratio
    s = float(scale)
    if not (np.isfinite(s) and s > 0):
        raise RetargetError(f"--scale must be 'units', 'auto' or a positive number, got {scale!r}")
    if not lo <= units * ratio / s <= hi:  # a factor that leaves the source out of the target's reach solves nothing
        raise RetargetError(
            f"{rig.path}: --scale {s:g} makes the source {s / (units * ratio):.3g}x the size of this target skeleton; "
            f"a factor within {hi:g}x of --scale auto's ({units * ratio:.3g}) keeps it within reach")
    return s

"""Render space: metres, Y up (Z-up files are turned ``(x, y, z) → (x, z, -y)``).

A leaf module (NumPy and kinematics only), so every part of the renderer can place joints
without importing the package that plans renders.
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion


def to_render_space(points: np.ndarray, meters_per_unit: float, up_axis: str) -> np.ndarray:
    """File coordinates ``(..., 3)`` → metres, Y up (Z-up: ``(x, y, z) → (x, z, -y)``)."""
    points = np.asarray(points, dtype=np.float64) * meters_per_unit
    if up_axis == "Z":
        points = np.stack([points[..., 0], points[..., 2], -points[..., 1]], axis=-1)
    return points


def render_joints(motion: Motion, frames: np.ndarray) -> np.ndarray:
    """Joint positions ``(N, J, 3)`` at source ``frames (N,)`` in render space."""
    world = fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)[1]
    return to_render_space(world, motion.meters_per_unit, motion.up_axis)

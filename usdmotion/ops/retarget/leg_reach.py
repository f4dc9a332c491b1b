"""How far a leg reaches, and the root coming down where a planted foot lies beyond it
(the leg IK, :mod:`usdmotion.ops.retarget.leg_ik`, and the snap after the contact phase,
:mod:`usdmotion.ops.retarget.leg_snap`). Arrays over all frames; target units."""

from __future__ import annotations

import numpy as np

from usdmotion.rotations import quat_conjugate, quat_rotate

#: Seconds over which the root's drop is smoothed (see :func:`root_drop`).
DROP_WINDOW_S = 0.15
#: A leg is never stretched beyond this share of its length (a fully straight knee has no
#: bend direction to keep).
REACH = 0.9995


def root_drop(hips: np.ndarray, reach: np.ndarray, ankle_targets: np.ndarray, up: int, fps: float) -> np.ndarray:
    """``(F,)`` how far (target units, ≥ 0) the root must come down so every leg reaches its
    ankle target: per frame the largest over legs of the least drop of the hip ``hips
    (F, L, 3)`` that brings ``ankle_targets (F, L, 3)`` within ``REACH · reach (L,)``, then
    a running maximum and a moving mean of it over :data:`DROP_WINDOW_S` (each mean covers
    only maxima that include its frame, so it never falls below that frame's need)."""
    gap = hips - ankle_targets
    height = gap[..., up]
    horizontal2 = np.sum(gap ** 2, axis=-1) - height ** 2
    limit = (REACH * reach)[None] ** 2
    need = np.where(horizontal2 < limit, height - np.sqrt(np.maximum(limit - horizontal2, 0.0)), height)
    need = np.maximum(need, 0.0).max(axis=1) if need.size else np.zeros(hips.shape[0])
    if not need.any():
        return need
    half = max(1, int(round(DROP_WINDOW_S * fps / 2)))
    padded = np.pad(need, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    peak = np.pad(windows.max(axis=1), half, mode="edge")
    return np.lib.stride_tricks.sliding_window_view(peak, 2 * half + 1).mean(axis=1)


def hip_spikes(height: np.ndarray) -> np.ndarray:
    """``(F,)`` how far (≥ 0) the hips' ``height (F,)`` rises above the median of it and its two
    neighbours: a one-frame upward spike (a mocap glitch). Where the root already comes down
    (:func:`root_drop`: a leg at full reach) it comes down by this much more, so the spike
    leaves the root instead of straightening the planted leg's knee for a frame (86_01 →
    Rokoko frame 430: the hips 7 mm up for one frame turned the right knee 11° and back)."""
    if height.shape[0] < 3:
        return np.zeros_like(height)
    padded = np.pad(height, 1, mode="edge")
    median = np.median(np.lib.stride_tricks.sliding_window_view(padded, 3), axis=1)
    return np.maximum(height - median, 0.0)


def with_hip_spikes(drop: np.ndarray, hips: np.ndarray, up: int) -> np.ndarray:
    """``drop (F,)`` plus :func:`hip_spikes` of the hips' mean height (``hips (F, L, 3)``) where the
    root comes down at all: a one-frame spike of the hips then leaves the root, not the knees."""
    return drop + np.where(drop > 0, hip_spikes(hips[..., up].mean(axis=1)), 0.0)


def leg_reach(world_p: np.ndarray, legs: list) -> np.ndarray:
    """``(L,)`` each leg's hip-to-ankle length (thigh + shin, mean over frames of ``world_p (F, J, 3)``;
    ``legs``: :class:`~usdmotion.ops.retarget.leg_ik.Leg`)."""
    return np.array([np.linalg.norm(world_p[:, leg.knee] - world_p[:, leg.hip], axis=-1).mean()
                     + np.linalg.norm(world_p[:, leg.ankle] - world_p[:, leg.knee], axis=-1).mean() for leg in legs])


def lower_root(t, world_q, world_p, parents, anchor: int, drop: np.ndarray, up: int) -> np.ndarray:
    """Lower ``anchor`` by ``drop (F,)`` on the up axis, in place in ``t``; return ``world_p`` moved with it."""
    if drop.max() <= 0:
        return world_p
    shift = np.zeros((t.shape[0], 3))
    shift[:, up] = -drop
    parent = parents[anchor]
    t[:, anchor] += shift if parent < 0 else quat_rotate(quat_conjugate(world_q[:, parent]), shift)
    return world_p + shift[:, None]

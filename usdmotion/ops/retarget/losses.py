"""The retargeting loss per frame in NumPy float64 (the solvers' loss, recomputed exactly).

Used by the pipeline to choose the initial guess and by the report to describe the output.
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import fk_arrays


def frame_losses(offsets_or_t: np.ndarray, rotations: np.ndarray, parents: np.ndarray, mapped: np.ndarray,
                 targets: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per-frame loss ``(F,)``: ``Σ_m w_m ‖p_m − target_m‖²`` with NumPy float64 FK.

    ``offsets_or_t`` is ``(F, J, 3)`` local translations (root: world position);
    ``targets`` ``(F, J, 3)`` indexed by target joint.
    """
    _, world_p = fk_arrays(rotations, offsets_or_t, parents)
    d = world_p[:, mapped] - targets[:, mapped]
    return np.einsum("fmk,fmk,m->f", d, d, weights[mapped])

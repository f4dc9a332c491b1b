"""The static structure of a retargeting problem and the solvers' constants.

Shared by the solvers (:mod:`usdmotion.ops.retarget.solve`) and the tree-structured LM
step (:mod:`usdmotion.ops.retarget.tree_step`), which import it and not each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.ops.retarget.hierarchy import ancestor_matrix

#: Levenberg–Marquardt damping: start, factor down on success / up on failure, bounds.
LM_LAMBDA0 = 1e-2
LM_DOWN, LM_UP = 0.2, 5.0
LM_LAMBDA_MIN, LM_LAMBDA_MAX = 1e-5, 1e8
#: Floor of the damping matrix relative to the mean curvature of each joint.
LM_DIAG_FLOOR = 1e-3
#: Damping not scaled by λ (relative to each joint's mean curvature): a fixed trust region
#: that keeps steps out of the loss's null space (the twist of a bone with one mapped
#: child), so twists stay as smooth over time as the initial guess instead of drifting
#: on float32 noise; it slows well-determined directions by ~0.1 %.
LM_NULL_DAMPING = 1e-3
ADAM_LR = 0.1
#: LM stops when every frame of a chunk went two iterations without gaining LM_RTOL (relative)
#: or when the chunk's total loss gained less than LM_RTOL_TOTAL twice in a row; at most
#: LM_ITERATIONS iterations.
LM_ITERATIONS = 100
LM_RTOL = 1e-5
LM_RTOL_TOTAL = 1e-6
LM_ATOL = 1e-12  # ... or when its loss fell below this fraction of where it started
ADAM_ITERATIONS = 500


@dataclass(frozen=True, eq=False)
class Problem:
    """Static structure of a retargeting problem (topology-sized NumPy arrays).

    Attributes:
        parents: ``(J,)`` target parent indices.
        mapped: ``(M,)`` target joints compared with source positions.
        weights: ``(M,)`` loss weight per mapped joint.
        rot_joints: ``(R,)`` joints whose rotation is optimised.
        trans_joints: ``(T,)`` joints whose local translation is optimised.
        orders: ``R`` Euler orders (``"ZXY"``...) of ``rot_joints`` (Adam's parameters).
    """

    parents: np.ndarray
    mapped: np.ndarray
    weights: np.ndarray
    rot_joints: np.ndarray
    trans_joints: np.ndarray
    orders: tuple[str, ...]

    def key(self) -> tuple:
        return (tuple(self.parents.tolist()), tuple(self.mapped.tolist()), tuple(np.round(self.weights, 12).tolist()),
                tuple(self.rot_joints.tolist()), tuple(self.trans_joints.tolist()), self.orders)

    @property
    def n_params(self) -> int:
        return 3 * (len(self.rot_joints) + len(self.trans_joints))


def masks(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """``(rot_mask (M, R), trans_mask (M, T))``: which parameters move which mapped joint."""
    anc = ancestor_matrix(problem.parents)
    rot = anc[problem.rot_joints][:, problem.mapped].T
    sub = anc | np.eye(len(problem.parents), dtype=bool)
    trans = sub[problem.trans_joints][:, problem.mapped].T
    return rot.astype(np.float32), trans.astype(np.float32)

"""The static structure of a retargeting problem and the solvers' constants.

Shared by the solvers (:mod:`usdmotion.ops.retarget.solve`) and the tree-structured LM
step (:mod:`usdmotion.ops.retarget.tree_step`), which import it and not each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdmotion.ops.retarget.hierarchy import ancestor_matrix

#: Levenberg–Marquardt damping: start, bounds and the update rule. ``"nielsen"`` (default):
#: from the gain ratio ``ρ`` (actual / predicted loss reduction), ``λ ← λ · max(1/3,
#: 1 − (2ρ − 1)³)`` after an accepted step and ``λ ← λ · ν`` after a rejected one, ``ν``
#: doubling on every rejection in a row (Madsen, Nielsen & Tingleff, *Methods for non-linear
#: least squares problems*, 2004, §3.2). ``"fixed"``: ÷5 after an accepted step, ×5 after a
#: rejected one; those factors return after every accepted step to the λ that had just
#: failed, so on walk → DAZ and 86_01 → Rokoko every other iteration is rejected, the solve
#: runs 48 / 56 iterations and frames in different chunks stop at different points along
#: directions the positions barely determine (Rokoko's head stepped 19°/frame at a chunk
#: boundary). Nielsen's rule needs 17 / 21 there and ends at lower losses on every pair of
#: ``benchmarks/retarget_contacts.py``, with no rotation step above the no-flip limit; it
#: runs 18 instead of 6 iterations on walk → Bandai, where the fixed rule stopped 3 % above
#: the optimum (docs/retarget.md, *Speed of the plain solve*).
LM_DAMPING_UPDATES = ("fixed", "nielsen")
LM_DAMPING_UPDATE = "nielsen"
LM_DOWN, LM_UP = 0.2, 5.0
LM_LAMBDA0 = 1e-2
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
#: LM_ITERATIONS iterations. LM_RTOL was 1e-5: the frames of a cross-rig take converge
#: together and linearly (walk → Bandai: every frame within 1e-2 of its final loss at
#: iteration 7, 1e-3 at 10, 1e-4 at 13 of 18), so the last iterations each gained less than
#: 1e-4 of a loss that no figure of the report resolves. At 1e-4 the six pairs of
#: ``benchmarks/retarget_contacts.py`` run 15 / 14 / 6 / 14 / 5 / 5 iterations instead of
#: 18 / 17 / 9 / 22 / 6 / 6, every RMS the same to 3 decimals (the largest change 5.8964 →
#: 5.8969 cm, walk → DAZ); the within-rig walk and 86_01 stay at 0.0591 % / 0.859 %.
#: A rejected step counts towards these only once the frame has moved (a step accepted, or
#: λ at LM_LAMBDA_MAX): from a start far from the targets the first steps can all be
#: rejected while λ rises, and two of them had stopped the solve with no gain at all.
LM_ITERATIONS = 100
LM_RTOL = 1e-4
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
        contact_joints: ``(C,)`` target joints with a contact term (per-frame weight and
            target position, e.g. a planted foot); empty for the plain solve.
        floor_joints: ``(G,)`` target joints kept above the floor (a one-sided term on
            their height, weight ``floor_weight`` per unit² below it).
        up: index of the vertical axis (1: Y-up, 2: Z-up) for the floor term.
        smooth: ``(R,)`` weight per rotation joint of the temporal term (units² per
            radian², 0 = off): the world rotation's distance from the midpoint of its
            neighbouring frames' (a second difference: constant angular velocity is free).
        prior: ``(R,)`` weight per rotation joint of the distance of its world rotation from
            the initial guess's (units² per radian², 0 = off): directions the positions
            barely determine (the twist of a nearly straight limb) stay where the
            continuous initial guess put them instead of wandering between frames.
    """

    parents: np.ndarray
    mapped: np.ndarray
    weights: np.ndarray
    rot_joints: np.ndarray
    trans_joints: np.ndarray
    orders: tuple[str, ...]
    contact_joints: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    floor_joints: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    up: int = 1
    floor_weight: float = 0.0
    smooth: np.ndarray = field(default_factory=lambda: np.zeros(0))
    prior: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def key(self) -> tuple:
        return (tuple(self.parents.tolist()), tuple(self.mapped.tolist()), tuple(np.round(self.weights, 12).tolist()),
                tuple(self.rot_joints.tolist()), tuple(self.trans_joints.tolist()), self.orders,
                tuple(self.contact_joints.tolist()), tuple(self.floor_joints.tolist()), self.up,
                round(float(self.floor_weight), 12), tuple(np.round(self.smooth, 12).tolist()),
                tuple(np.round(self.prior, 12).tolist()))

    @property
    def points(self) -> np.ndarray:
        """``(M + C + G,)`` the joints of every position residual: mapped, contact, floor."""
        return np.concatenate([self.mapped, self.contact_joints, self.floor_joints]).astype(np.int64)

    @property
    def smoothing(self) -> bool:
        return bool(len(self.smooth)) and bool(np.any(self.smooth > 0))

    @property
    def anchored(self) -> bool:
        return bool(len(self.prior)) and bool(np.any(self.prior > 0))

    def point_weights(self) -> np.ndarray:
        """``(M + C,)`` default weights of the mapped and contact points (contacts: 0, i.e. off)."""
        return np.concatenate([self.weights, np.zeros(len(self.contact_joints))])

    @property
    def n_params(self) -> int:
        return 3 * (len(self.rot_joints) + len(self.trans_joints))


def masks(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """``(rot_mask (P, R), trans_mask (P, T))``: which parameters move which residual point
    (:attr:`Problem.points`)."""
    anc = ancestor_matrix(problem.parents)
    rot = anc[problem.rot_joints][:, problem.points].T
    sub = anc | np.eye(len(problem.parents), dtype=bool)
    trans = sub[problem.trans_joints][:, problem.points].T
    return rot.astype(np.float32), trans.astype(np.float32)

"""The legs back onto their contacts after the LM contact phase: the end of the contact solve.

The contact phase (:mod:`usdmotion.ops.retarget.contact_phase`) re-fits the hips and legs
to the source with every contact joint pulled, not pinned, to where the leg IK
(:mod:`usdmotion.ops.retarget.leg_ik`) put it, so its result misses the contacts by up to a
few millimetres. :func:`snap_legs` moves each leg back onto the IK's points by the least it
can: the ankle and toe targets are the phase's own joints moved towards the IK's by the
phase's own contact weights (1 on contact frames, fading out over ``CONTACT_FADE_S``), a
toe-only contact keeps the ankle on the sphere of the foot's length about the toe; the root
comes down only where a target lies beyond a leg's reach (and by a hip spike more there, as in
the leg IK); the two-bone IK keeps each knee in the phase's own bend plane. Running the
whole leg IK again instead (its targets, fixed points moved within reach and knee-hinge rule
from scratch) undid part of the phase's re-fit: joint-position RMS 0.92 against 0.95 cm on
walk → legs 0.8×, 1.01 against 1.03 on 1.2×, 4.11 against 4.13 on 86_01 → Rokoko
(``benchmarks/retarget_contacts.py``).
"""

from __future__ import annotations

import numpy as np

from usdmotion.ops.retarget.leg_ik import Leg, chain_joints, fk_of, toes_above_floor, two_bone, up_to_level
from usdmotion.ops.retarget.leg_reach import leg_reach, lower_root, root_drop, with_hip_spikes


def snap_legs(q: np.ndarray, t: np.ndarray, parents: np.ndarray, anchor: int, legs: list[Leg], held: np.ndarray,
              contact: np.ndarray, near: np.ndarray, level: np.ndarray, up: int, fps: float,
              floor: float) -> tuple[np.ndarray, np.ndarray]:
    """``(q, t)``: the contact phase's local rotations ``q (F, J, 4)`` and translations
    ``t (F, J, 3)`` (anchor world-placed) with every leg's contact joints on ``held (F, C, 3)``
    (where the leg IK put them) on their ``contact (F, C)`` frames, blended into the phase's
    own positions by ``near (F, C)`` (the phase's contact weights over ``CONTACT_WEIGHT``: 1 on
    contact frames, fading to 0; :func:`~usdmotion.ops.retarget.leg_ik.nearness`); ankles
    never below their ``level (C,)``, the joints below each toe never below ``floor`` (target
    units); ``fps``: the motion's, for the root's smoothed drop."""
    chain = chain_joints(parents, legs, anchor)
    world_q, world_p = fk_of(q, t, parents, chain)
    q, t = q.copy(), t.copy()
    targets = []
    for leg in legs:
        ankle = world_p[:, leg.ankle] + near[:, leg.ankle_c, None] * (held[:, leg.ankle_c] - world_p[:, leg.ankle])
        ankle[:, up] = np.maximum(ankle[:, up], level[leg.ankle_c])
        toe = toe_level = None
        if leg.toe >= 0:
            toe = world_p[:, leg.toe] + near[:, leg.toe_c, None] * (held[:, leg.toe_c] - world_p[:, leg.toe])
            length = np.linalg.norm(world_p[:, leg.toe] - world_p[:, leg.ankle], axis=-1, keepdims=True)
            away = ankle - toe
            on_sphere = toe + length * away / np.maximum(np.linalg.norm(away, axis=-1, keepdims=True), 1e-300)
            only_toe = contact[:, leg.toe_c] & ~contact[:, leg.ankle_c]
            ankle = np.where(only_toe[:, None], up_to_level(on_sphere, toe, level[leg.ankle_c], up), ankle)
            toe_level = level[leg.toe_c]
        targets.append((ankle, toe, toe_level))
    ankles = np.stack([ankle for ankle, _, _ in targets], axis=1)
    hips = world_p[:, [leg.hip for leg in legs]]
    drop = with_hip_spikes(root_drop(hips, leg_reach(world_p, legs), ankles, up, fps), hips, up)
    world_p = lower_root(t, world_q, world_p, parents, anchor, drop, up)
    for leg, (ankle, toe, toe_level) in zip(legs, targets):
        q = two_bone(q, world_q, world_p, parents, leg, ankle, toe, up, toe_level, hinge=0.0)
    return toes_above_floor(q, t, parents, legs, floor, up, chain), t

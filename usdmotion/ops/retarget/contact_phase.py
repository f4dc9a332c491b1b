"""The LM contact phase of the contact-aware solve (issue 17).

After the leg IK (:mod:`usdmotion.ops.retarget.leg_ik`) has planted the feet, a few
iterations of the same batched LM solve re-fit the hips and legs to the source with every
contact joint held where the IK put it (:func:`contact_phase`); the legs are then snapped
back onto those points (:func:`usdmotion.ops.retarget.leg_snap.snap_legs`), so the contacts
hold exactly. Contact terms:
:class:`usdmotion.ops.retarget.problem.Problem` ``contact_joints`` with per-frame weights.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from usdmotion.ops.retarget.contact_terms import leg_joints
from usdmotion.ops.retarget.hierarchy import ancestor_matrix, with_ancestors
from usdmotion.ops.retarget.leg_ik import fk_of, nearness
from usdmotion.ops.retarget.leg_snap import snap_legs
from usdmotion.ops.retarget.problem import Problem
from usdmotion.ops.retarget.rotation_terms import smooth_scale
from usdmotion.ops.retarget.solve import solve

#: Iterations of the LM contact phase of the contact solve (0: off), warm-started from the
#: leg IK's result; the legs are snapped back onto the IK's points after it.
CONTACT_ITERATIONS = 5
#: Weight of a planted contact joint's distance from where the leg IK put it, in the
#: contact phase (the mapped joints weigh 1 per unit²).
CONTACT_WEIGHT = 100.0
#: Seconds over which that weight fades out around each contact (the held points there are
#: the IK's blends into the swing).
CONTACT_FADE_S = 0.2
#: Pull of each upper-body joint (spine, neck, head, arms) towards its world rotation after
#: the leg IK, per radian² in units of the positions it moves (``smooth_scale``): they turn
#: in the contact phase too, so the upper body keeps the source's pose while the hips tilt
#: under it. Without the pull (or at 0.1) Rokoko's head stepped 20-99°/frame; at 0.3 no joint
#: steps above its no-flip limit on the benchmark's six pairs, and the contact solve's RMS to
#: the source fell on all six (86_01 -> Rokoko 4.46 -> 4.33 cm, walk -> DAZ 6.19 -> 6.01 cm,
#: the leg-scaled walks 1.11 / 1.02 -> 0.98 / 1.00 cm), for up to ~20 % of its speed. Off (None:
#: the upper body keeps the plain solve's local rotations) since the ankles are planted where
#: the plain solve stands them (``contact_terms.solved_ankle_levels``): the hips then move less,
#: the pull gained 0.04-0.18 cm and stepped jumps -> Mixamo's head over its no-flip limit
#: (9.6 / 9.3°/frame; 9.2 in the plain solve), at any pull from 0.3 to 1.0.
UPPER_BODY_PRIOR: float | None = None


def contact_phase(setup, terms, legs, q: np.ndarray, t: np.ndarray, problem: Problem, iterations: int):
    """``(q, t, Solution)``: the LM solve of ``problem`` (the plain solve's) again from the
    leg IK's result ``q, t`` (anchor world-placed) for ``iterations`` iterations, every contact
    joint held where the IK put it on its contact frames (weight :data:`CONTACT_WEIGHT`, fading out around them): the
    root, the hips and the ``legs`` (:class:`~usdmotion.ops.retarget.leg_ik.Leg`) re-fit
    the source given the planted feet (what the root's drop and the IK's knees cost); where
    :data:`UPPER_BODY_PRIOR` is set (off by default) the upper body turns too, held near its
    world rotations. The legs then snap back onto the held points
    (:func:`~usdmotion.ops.retarget.leg_snap.snap_legs`): the contacts hold exactly."""
    mapped, anchor = setup.mapped, setup.anchor
    base = problem
    # the hips (and what carries them) and each leg's hip, knee and ankle turn freely, the upper body
    # against a pull where one is set; the toes, the joints between the hips and a leg (and, without
    # the pull, the upper body) keep the plain solve's rotations
    ancestor = ancestor_matrix(setup.rig.parents)  # [i, j]: i is an ancestor of j
    turn = (ancestor | np.eye(setup.rig.n_joints, dtype=bool))[:, setup.top]
    turn[[j for leg in legs for j in (leg.hip, leg.knee, leg.ankle)]] = True
    fixed = np.zeros(setup.rig.n_joints, bool)
    for leg in legs:
        fixed |= ancestor[leg.ankle] | (ancestor[:, leg.hip] & ancestor[setup.top])
    upper = ~(turn | fixed)[base.rot_joints]
    pulled = len(base.prior) and UPPER_BODY_PRIOR is not None  # a pull needs the prior term
    keep = turn[base.rot_joints] | (upper if pulled else False)
    prior = base.prior.copy()
    if pulled:
        prior[upper] = UPPER_BODY_PRIOR * smooth_scale(setup)[upper]
    problem = dataclasses.replace(base, rot_joints=base.rot_joints[keep], contact_joints=terms.joints, up=terms.up,
                                  orders=tuple(o for o, k in zip(base.orders, keep) if k),
                                  prior=prior[keep] if len(prior) else prior,
                                  smooth=base.smooth[keep] if len(base.smooth) else base.smooth)
    centre = setup.translations[:, anchor]
    t0 = t.copy()
    t0[:, anchor] -= centre
    held = fk_of(q, t, setup.rig.parents, with_ancestors(setup.rig.parents, terms.joints))[1][:, terms.joints]
    targets = np.concatenate([setup.targets[:, mapped], held], axis=1) - centre[:, None]
    contact = np.asarray(terms.target_contacts.contact, bool)
    fade = CONTACT_FADE_S * terms.target_contacts.fps  # weights that switch in one frame make steps
    near = np.stack([nearness(contact[:, c], fade) for c in range(contact.shape[1])], axis=1)
    weights = np.concatenate([np.broadcast_to(setup.weights[mapped], (q.shape[0], len(mapped))),
                              CONTACT_WEIGHT * near], axis=1)
    solution = solve(problem, q, t0, targets, iterations=iterations, weights=weights)
    t = solution.t
    t[:, anchor] += centre
    q, t = snap_legs(solution.q, t, setup.rig.parents, anchor, legs, held, contact, near, terms.level, terms.up,
                     terms.target_contacts.fps, terms.floor)
    return q, t, solution


def body_weight(setup, terms) -> float:
    """Summed loss weight of the mapped joints off the legs: what a root drop moves."""
    return float(setup.weights[np.setdiff1d(setup.mapped, leg_joints(setup, terms.joints))].sum())

"""The ``aim`` initial guess of retargeting: every optimised joint aims its rest bone(s) at
the source direction(s) of its nearest mapped descendants, all frames at once."""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import depth_levels, fk_arrays
from usdmotion.ops.retarget.hierarchy import ancestor_matrix, with_ancestors
from usdmotion.rotations import matrix_to_quat, quat_between, quat_conjugate, quat_mul, quat_rotate


def identity_quats(shape) -> np.ndarray:
    q = np.zeros(tuple(shape) + (4,))
    q[..., 0] = 1.0
    return q



def _rays(rig, offsets: np.ndarray, mapped_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every joint's nearest mapped descendants as padded arrays: ``(ends (J, R) int, rest
    vectors (J, R, 3) from the joint to each end, count (J,))``; padding rows are ``(0, 0⃗)``
    (``R`` the largest count, at least 1)."""
    children = [[] for _ in range(rig.n_joints)]
    for j in range(1, rig.n_joints):
        children[rig.parents[j]].append(j)
    found_all = []
    for j in range(rig.n_joints):  # a walk of the hierarchy (no frames): setup, not a hot path
        found, stack = [], [(c, offsets[c]) for c in children[j]]
        while stack:
            c, v = stack.pop()
            if mapped_mask[c]:
                if np.linalg.norm(v) > 1e-9:
                    found.append((c, v))
            else:
                stack.extend((g, v + offsets[g]) for g in children[c])
        found_all.append(found)
    count = np.array([len(found) for found in found_all], np.int64)
    ends = np.zeros((rig.n_joints, max(1, int(count.max(initial=0)))), np.int64)
    vectors = np.zeros(ends.shape + (3,))
    for j, found in enumerate(found_all):
        for r, (c, v) in enumerate(found):
            ends[j, r], vectors[j, r] = c, v
    return ends, vectors, count


def aim_init(setup, copied: np.ndarray | None = None) -> np.ndarray:
    """Heuristic rotations ``(F, J, 4)``: every optimised joint aims its rest bone(s) at the
    source direction(s) of its nearest mapped descendants (one: shortest swing; several:
    least-squares rotation, Kabsch), one depth level of joints at a time from the root, all
    frames at once.

    One bone: the swing starts from the parent's frame (identity local rotation) or, with
    ``copied`` (the source's local rotations), from the copied rotation, whichever stays
    farther from a half turn over the whole take: a shortest swing near 180° picks its
    twist at random, and a take-wide choice keeps the twist continuous (with the copied
    start it is the source's own twist)."""
    rig, offsets = setup.rig, setup.offsets
    n_frames = setup.targets.shape[0]
    mapped_mask = np.zeros(rig.n_joints, bool)
    mapped_mask[setup.mapped] = True
    ends, vectors, count = _rays(rig, offsets, mapped_mask)
    aimed = np.zeros(rig.n_joints, bool)
    aimed[setup.rot_joints] = True
    aimed &= count > 0
    local = identity_quats((n_frames, rig.n_joints))
    world_q = identity_quats((n_frames, rig.n_joints))
    world_p = np.zeros((n_frames, rig.n_joints, 3))
    placed = np.zeros(rig.n_joints, bool)  # what the aimed joints need: they and their ancestors
    placed[with_ancestors(rig.parents, np.flatnonzero(aimed))] = True
    for level, _ in depth_levels(rig.parents):  # parents of a level are all placed
        level = level[placed[level]]
        parents = rig.parents[level]
        parent_q = np.where((parents >= 0)[:, None], world_q[:, parents], identity_quats((1, len(level))))
        parent_p = np.where((parents >= 0)[:, None], world_p[:, parents], 0.0)
        world_p[:, level] = parent_p + quat_rotate(parent_q, setup.translations[:, level])
        k = np.flatnonzero(aimed[level])
        if len(k):
            joints, base = level[k], parent_q[:, k]
            bases = [base] if copied is None else [base, quat_mul(base, copied[:, joints])]
            world = _aim(bases, world_p[:, joints], ends[joints], vectors[joints], count[joints], setup.targets)
            local[:, joints] = quat_mul(quat_conjugate(base), world)
        world_q[:, level] = quat_mul(parent_q, local[:, level])
    return local  # joints not aimed keep the identity: their parent's frame


#: Several rays count as one direction (swing, not Kabsch) when the second singular value
#: of their correlation is below this share of the first: a roll about nearly collinear
#: rays is decided by noise and would flip between frames.
COLLINEAR = 0.05


def _swing(bases, u, v) -> np.ndarray:
    """World rotations ``(F, K, 4)`` turning each joint's rest vector ``u (K, 3)`` carried by
    one of ``bases`` (``(F, K, 4)`` world rotations) onto ``v (F, K, 3)`` by the shortest arc;
    per joint, the base whose largest swing over the take is smallest (the first of equals).
    A further base is always tried: the parent's frame (``bases[0]``) turned once, for the
    whole take, so ``u`` points along the mean direction of ``v`` in that frame — its swings
    stay far from a half turn unless the bone sweeps more than a hemisphere around its parent."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    mean = np.sum(quat_rotate(quat_conjugate(bases[0]), v / np.maximum(length, 1e-300)), axis=0)  # (K, 3)
    turnable = (np.linalg.norm(mean, axis=-1) > 1e-9) & (np.linalg.norm(u, axis=-1) > 1e-12)
    ones = np.array([1.0, 0.0, 0.0])
    turn = quat_between(np.where(turnable[:, None], u, ones), np.where(turnable[:, None], mean, ones))
    candidates = np.stack([*bases, quat_mul(bases[0], turn)])  # (C, F, K, 4)
    carried = quat_rotate(candidates, u)  # (C, F, K, 3)
    cos = np.sum(carried * v, -1) / np.maximum(np.linalg.norm(carried, axis=-1) * length[..., 0], 1e-300)
    angle = np.arccos(np.clip(cos, -1.0, 1.0)).max(axis=1)  # (C, K): the largest swing over the take
    angle[-1, ~turnable] = np.inf
    k = np.arange(len(u))
    chosen = np.zeros(len(u), np.int64)
    for i in range(1, len(candidates)):  # a later base only where it beats the chosen one by more than 1e-9
        chosen = np.where(angle[i] < angle[chosen, k] - 1e-9, i, chosen)
    return quat_mul(quat_between(carried[chosen, :, k].swapaxes(0, 1), v), candidates[chosen, :, k].swapaxes(0, 1))


def _aim(bases, origin, ends, vectors, count, targets) -> np.ndarray:
    """World rotations ``(F, K, 4)`` of ``K`` joints aiming their rest vectors (joint frame;
    ``ends (K, R)``, ``vectors (K, R, 3)``, ``count (K,)`` from :func:`_rays`) from
    ``origin (F, K, 3)`` at their ends' ``targets``; ``bases[0]`` (``(F, K, 4)``) is the
    parents' world rotation."""
    real = np.arange(ends.shape[1]) < count[:, None]  # (K, R)
    v = np.where(real[..., None], targets[:, ends] - origin[:, :, None], 0.0)  # (F, K, R, 3) world
    swing = _swing(bases, vectors.sum(axis=1), v.sum(axis=2))
    several = np.flatnonzero(count >= 2)
    if not len(several):
        return swing
    h = np.einsum("fkrx,kry->fkxy", v[:, several], vectors[several])  # Σ v uᵀ
    w_, s, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(w_ @ vt))
    fix = np.ones(d.shape + (3,))
    fix[..., 2] = d
    kabsch = matrix_to_quat(w_ @ (fix[..., :, None] * vt))
    planar = s[..., 1] > COLLINEAR * np.maximum(s[..., 0], 1e-300)
    swing[:, several] = np.where(planar[..., None], kabsch, swing[:, several])
    return swing


def aim_single_points(setup, q: np.ndarray, t: np.ndarray, initial: np.ndarray | None = None) -> np.ndarray:
    """``q (F, J, 4)`` with every optimised joint whose subtree holds exactly one mapped joint
    (a hand before its one mapped finger, a toe before its tip, a head before its top; the
    topmost of such a chain) turned by the shortest swing that points it at that joint's
    target from where the solve put it: the exact minimiser of the only position it moves
    (``t (F, J, 3)`` local translations, root: world; ``setup.targets`` the same frame).

    The LM solve stops when a frame's *whole* loss gains less than 10⁻⁵ of itself; a bone
    that moves one point near the joint barely shows in it, so such bones stopped anywhere
    short of their target — at a different place in neighbouring frames: CMU walk → DAZ
    hands stepped 7°/frame where the source's step ≤ 2°. The swing keeps the twist.

    A chain with joints between the top and its mapped joint (MotionBuilder HumanIK's
    ``InHand`` helpers between hand and finger) has, with ``initial (F, J, 4)`` (the
    initial guess), those joints at the guess's rotations and the top swung from the guess's
    world rotation onto the source's direction from the top to the mapped joint (where the top
    is mapped): the loss leaves the twist and the helpers' bend free, the LM left them wherever
    each frame stopped, and from a top that the solve misplaced by a bone's length the
    direction to a nearby target is noise (CMU walk onto the HumanIK rig of
    ``wspr_milad_blank_line_6ch_125fps.bvh``: hands 21.6° / 12.7° in a frame, now 5.8° / 8.5°;
    the source's ≤ 2.1° / 2.7°)."""
    rig, mapped = setup.rig, setup.mapped
    anc = ancestor_matrix(rig.parents)
    below = anc[:, mapped]  # (J, M): mapped strict descendants
    single = {int(j) for j in setup.rot_joints if below[j].sum() == 1}
    tops = [j for j in sorted(single) if rig.parents[j] not in single]
    if not tops:
        return q
    q = q.copy()
    helpers = sorted(single - set(tops)) if initial is not None else []  # between a top and its mapped joint
    helped = {j for j in tops if anc[j, helpers].any()}
    if helpers:
        q[:, helpers] = initial[:, helpers]
    mapped_set = set(mapped.tolist())
    world_q, world_p = fk_arrays(q, t, rig.parents)
    initial_q = fk_arrays(initial, t, rig.parents)[0] if helped else None
    for j in tops:  # disjoint subtrees under unchanged parents: one FK serves all
        m = mapped[np.flatnonzero(below[j])[0]]
        start = world_q[:, j]
        now, want = world_p[:, m] - world_p[:, j], setup.targets[:, m] - world_p[:, j]
        if j in helped:
            start = initial_q[:, j]
            now = quat_rotate(start, quat_rotate(quat_conjugate(world_q[:, j]), now))  # the chain turned with the top
            if j in mapped_set:
                want = setup.targets[:, m] - setup.targets[:, j]
        size = np.minimum(np.linalg.norm(now, axis=-1), np.linalg.norm(want, axis=-1))
        ok = size > 1e-9 * max(1.0, float(np.abs(setup.offsets).max()))
        swing = np.where(ok[:, None], quat_between(np.where(ok[:, None], now, 1.0), np.where(ok[:, None], want, 1.0)),
                         identity_quats((len(q),)))
        parent_q = world_q[:, rig.parents[j]] if rig.parents[j] >= 0 else identity_quats((len(q),))
        q[:, j] = quat_mul(quat_conjugate(parent_q), quat_mul(swing, start))
    return q

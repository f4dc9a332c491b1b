"""The ``aim`` initial guess of retargeting: every optimised joint aims its rest bone(s) at
the source direction(s) of its nearest mapped descendants, all frames at once."""

from __future__ import annotations

import numpy as np

from usdmotion.rotations import matrix_to_quat, quat_between, quat_conjugate, quat_mul, quat_rotate


def identity_quats(shape) -> np.ndarray:
    q = np.zeros(tuple(shape) + (4,))
    q[..., 0] = 1.0
    return q



def _rays(rig, offsets: np.ndarray, mapped_mask: np.ndarray) -> list[list[tuple[int, np.ndarray]]]:
    """Per joint: ``(d, rest vector from the joint to d)`` for its nearest mapped descendants."""
    children = [[] for _ in range(rig.n_joints)]
    for j in range(1, rig.n_joints):
        children[rig.parents[j]].append(j)
    rays = []
    for j in range(rig.n_joints):
        found, stack = [], [(c, offsets[c]) for c in children[j]]
        while stack:
            c, v = stack.pop()
            if mapped_mask[c]:
                if np.linalg.norm(v) > 1e-9:
                    found.append((c, v))
            else:
                stack.extend((g, v + offsets[g]) for g in children[c])
        rays.append(found)
    return rays


def aim_init(setup, copied: np.ndarray | None = None) -> np.ndarray:
    """Heuristic rotations ``(F, J, 4)``: every optimised joint aims its rest bone(s) at the
    source direction(s) of its nearest mapped descendants (one: shortest swing; several:
    least-squares rotation, Kabsch), joint by joint from the root, all frames at once.

    One bone: the swing starts from the parent's frame (identity local rotation) or, with
    ``copied`` (the source's local rotations), from the copied rotation, whichever stays
    farther from a half turn over the whole take: a shortest swing near 180° picks its
    twist at random, and a take-wide choice keeps the twist continuous (with the copied
    start it is the source's own twist)."""
    rig, offsets = setup.rig, setup.offsets
    n_frames = setup.targets.shape[0]
    mapped_mask = np.zeros(rig.n_joints, bool)
    mapped_mask[setup.mapped] = True
    rays = _rays(rig, offsets, mapped_mask)
    optimised = np.zeros(rig.n_joints, bool)
    optimised[setup.rot_joints] = True
    local = identity_quats((n_frames, rig.n_joints))
    world_q = identity_quats((n_frames, rig.n_joints))
    world_p = np.zeros((n_frames, rig.n_joints, 3))
    for j in range(rig.n_joints):
        p = rig.parents[j]
        parent_q = world_q[:, p] if p >= 0 else identity_quats((n_frames,))
        parent_p = world_p[:, p] if p >= 0 else np.zeros((n_frames, 3))
        world_p[:, j] = parent_p + quat_rotate(parent_q, setup.translations[:, j])
        if optimised[j] and rays[j]:
            bases = [parent_q] if copied is None else [parent_q, quat_mul(parent_q, copied[:, j])]
            local[:, j] = quat_mul(quat_conjugate(parent_q), _aim(bases, world_p[:, j], rays[j], setup.targets))
        world_q[:, j] = quat_mul(parent_q, local[:, j])
    return local


#: Several rays count as one direction (swing, not Kabsch) when the second singular value
#: of their correlation is below this share of the first: a roll about nearly collinear
#: rays is decided by noise and would flip between frames.
COLLINEAR = 0.05


def _swing(bases, u, v) -> np.ndarray:
    """World rotations ``(F, 4)`` turning rest vector ``u (3,)`` carried by one of ``bases``
    (``(F, 4)`` world rotations) onto ``v (F, 3)`` by the shortest arc; the base whose
    largest swing over the take is smallest. A further base is always tried: the parent's
    frame (``bases[0]``) turned once, for the whole take, so ``u`` points along the mean
    direction of ``v`` in that frame — its swings stay far from a half turn unless the
    bone sweeps more than a hemisphere around its parent."""
    mean = np.sum(quat_rotate(quat_conjugate(bases[0]), v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True),
                                                                        1e-300)), axis=0)
    if np.linalg.norm(mean) > 1e-9 and np.linalg.norm(u) > 1e-12:
        bases = [*bases, quat_mul(bases[0], quat_between(u, mean))]
    best, best_angle = None, np.inf
    for base in bases:
        carried = quat_rotate(base, u)
        cos = np.sum(carried * v, -1) / np.maximum(np.linalg.norm(carried, axis=-1) * np.linalg.norm(v, axis=-1),
                                                   1e-300)
        angle = float(np.arccos(np.clip(cos, -1.0, 1.0)).max())
        if angle < best_angle - 1e-9:
            best, best_angle = quat_mul(quat_between(carried, v), base), angle
    return best


def _aim(bases, origin, rays, targets) -> np.ndarray:
    """World rotation ``(F, 4)`` aiming rest vectors (joint frame) at target directions;
    ``bases[0]`` is the parent's world rotation."""
    u = np.stack([v for _, v in rays])  # (R, 3) joint frame
    v = np.stack([targets[:, d] - origin for d, _ in rays], axis=1)  # (F, R, 3) world
    swing = _swing(bases, u.sum(axis=0), v.sum(axis=1))
    if len(rays) < 2:
        return swing
    h = np.einsum("frk,rl->fkl", v, u)  # Σ v uᵀ
    w_, s, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(w_ @ vt))
    fix = np.ones((len(d), 3))
    fix[:, 2] = d
    kabsch = matrix_to_quat(w_ @ (fix[:, :, None] * vt))
    planar = s[:, 1] > COLLINEAR * np.maximum(s[:, 0], 1e-300)
    return np.where(planar[:, None], kabsch, swing)


def aim_single_points(setup, q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``q (F, J, 4)`` with every optimised joint whose subtree holds exactly one mapped joint
    (a hand before its one mapped finger, a toe before its tip, a head before its top; the
    topmost of such a chain) turned by the shortest swing that points it at that joint's
    target from where the solve put it: the exact minimiser of the only position it moves
    (``t (F, J, 3)`` local translations, root: world; ``setup.targets`` the same frame).

    The LM solve stops when a frame's *whole* loss gains less than 10⁻⁵ of itself; a bone
    that moves one point near the joint barely shows in it, so such bones stopped anywhere
    short of their target — at a different place in neighbouring frames: CMU walk → DAZ
    hands stepped 7°/frame where the source's step ≤ 2°. The swing keeps the twist."""
    from usdmotion.kinematics import fk_arrays
    from usdmotion.ops.retarget.hierarchy import ancestor_matrix

    rig, mapped = setup.rig, setup.mapped
    below = ancestor_matrix(rig.parents)[:, mapped]  # (J, M): mapped strict descendants
    single = {int(j) for j in setup.rot_joints if below[j].sum() == 1}
    tops = [j for j in sorted(single) if rig.parents[j] not in single]
    if not tops:
        return q
    world_q, world_p = fk_arrays(q, t, rig.parents)
    q = q.copy()
    for j in tops:  # disjoint subtrees under unchanged parents: one FK serves all
        m = mapped[np.flatnonzero(below[j])[0]]
        now, want = world_p[:, m] - world_p[:, j], setup.targets[:, m] - world_p[:, j]
        size = np.minimum(np.linalg.norm(now, axis=-1), np.linalg.norm(want, axis=-1))
        ok = size > 1e-9 * max(1.0, float(np.abs(setup.offsets).max()))
        swing = np.where(ok[:, None], quat_between(np.where(ok[:, None], now, 1.0), np.where(ok[:, None], want, 1.0)),
                         identity_quats((len(q),)))
        parent_q = world_q[:, rig.parents[j]] if rig.parents[j] >= 0 else identity_quats((len(q),))
        q[:, j] = quat_mul(quat_conjugate(parent_q), quat_mul(swing, world_q[:, j]))
    return q

"""The Gauss–Newton model of the retargeting loss, for Nielsen's damping update of the LM solve
(:mod:`usdmotion.ops.retarget.solve`)."""

from __future__ import annotations

import numpy as np

from usdmotion.ops.retarget.hierarchy import ancestor_matrix
from usdmotion.ops.retarget.problem import Problem, masks


def make_model_gain(problem: Problem):
    """``(world_p (B,J,3), r (B,P,3), w (B,P), step (B,P'), rot_r=None (B,R,3), rot_w=None (B,R))
    -> (B,)``: the loss reduction the Gauss–Newton model predicts for ``step``,
    ``m(0) − m(step)`` with ``m(x) = Σ_p w_p ‖r_p + J_p x‖² + Σ_k w_k ‖ρ_k + Σ_{j ⪯ k} x_j‖²``:
    a point moves by ``Σ_j x_j × (p_m − p_j)`` over the rotation joints above it plus the
    translation increments above it, a world rotation residual by the increments of the
    rotation joints at or above it (the Jacobians :func:`make_tree_step` uses). Costs two
    small matrix products per iteration; Nielsen's damping update needs it."""
    import jax.numpy as jnp

    anc = ancestor_matrix(problem.parents)
    points = problem.points
    n_rot, n_trans = len(problem.rot_joints), len(problem.trans_joints)
    rot_mask, trans_mask = (jnp.asarray(m) for m in masks(problem))  # (P, R), (P, T)
    at_or_above = anc | np.eye(len(problem.parents), dtype=bool)
    rot_rot = jnp.asarray(at_or_above[problem.rot_joints][:, problem.rot_joints].T.astype(np.float32))  # (R, R)
    rot_j, point_j = jnp.asarray(problem.rot_joints), jnp.asarray(points)

    def gain(world_p, r, w, step, rot_r=None, rot_w=None):
        x = step[:, : 3 * n_rot].reshape(step.shape[0], n_rot, 3)
        pm = world_p[:, point_j]
        moved = jnp.zeros_like(r)
        if n_rot:
            spin = jnp.einsum("pr,brk->bpk", rot_mask.astype(r.dtype), x)
            lever = jnp.einsum("pr,brk->bpk", rot_mask.astype(r.dtype), jnp.cross(x, world_p[:, rot_j]))
            moved = jnp.cross(spin, pm) - lever
        if n_trans:
            delta = step[:, 3 * n_rot:].reshape(step.shape[0], n_trans, 3)
            moved = moved + jnp.einsum("pt,btk->bpk", trans_mask.astype(r.dtype), delta)
        # m(0) − m(x) = −Σ w (2 r·Jx + ‖Jx‖²)
        out = -jnp.einsum("bpk,bpk,bp->b", moved, 2.0 * r + moved, w)
        if rot_w is not None and n_rot:
            turned = jnp.einsum("kr,brc->bkc", rot_rot.astype(r.dtype), x)
            out = out - jnp.einsum("bkc,bkc,bk->b", turned, 2.0 * rot_r + turned, rot_w)
        return out

    return gain

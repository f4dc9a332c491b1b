"""Rotation residuals of the LM solve: the pull towards the initial guess and the temporal term.

Both are residuals of a joint's world rotation (radians, world-frame axis-angle), whose
Jacobian with respect to the world-frame increments of the joint and its ancestors is the
identity (see :func:`usdmotion.ops.retarget.tree_step.make_tree_step`).
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import rest_arrays
from usdmotion.ops.retarget.hierarchy import ancestor_matrix
from usdmotion.ops.retarget.problem import Problem
from usdmotion.rotations import quat_log, quat_mul, quat_normalize


def make_rotation_terms(problem: Problem, axis: str | None = None, shards: int = 1):
    """``(world_q (B,J,4), mask (B,)) -> (rot_r (B,R,3), rot_w (B,R), loss (B,))``: the
    temporal term of the rotation joints. ``rot_r = log(W_j(f) · M_j(f)⁻¹)`` (world frame,
    radians) with ``M_j(f)`` the normalised quaternion mean of ``W_j(f−1)`` and
    ``W_j(f+1)`` (hemisphere-aligned): a second difference, so constant angular velocity
    costs nothing and a flip costs a lot. ``mask`` is 1 on frames whose both neighbours are
    real consecutive frames of the batch. Within one LM iteration the neighbours are held
    (a Jacobi sweep over time; they move at the next iteration).

    ``axis``, ``shards``: inside a ``shard_map`` over ``shards`` consecutive blocks of frames
    (mapped axis ``axis``), the first and last frame of a block take their neighbours from
    the blocks beside it, so the term is the one of the whole batch."""
    import jax
    import jax.numpy as jnp

    rot_j = jnp.asarray(problem.rot_joints)
    weight = jnp.asarray(problem.smooth if problem.smoothing else np.zeros(len(problem.rot_joints)), jnp.float32)
    prior_w = jnp.asarray(problem.prior if problem.anchored else np.zeros(len(problem.rot_joints)), jnp.float32)
    conj = jnp.asarray([1.0, -1.0, -1.0, -1.0], jnp.float32)

    def midpoints(world_q):
        wq = world_q[:, rot_j]
        before, after = wq[:1], wq[-1:]
        if axis is not None:  # the blocks' edge frames (zeros at the batch's ends, where the mask is 0)
            before = jax.lax.ppermute(after, axis, [(k, k + 1) for k in range(shards - 1)])
            after = jax.lax.ppermute(wq[:1], axis, [(k + 1, k) for k in range(shards - 1)])
        prev = jnp.concatenate([before, wq[:-1]], axis=0)
        nxt = jnp.concatenate([wq[1:], after], axis=0)
        align = lambda a: a * jnp.where(jnp.sum(a * wq, -1, keepdims=True) < 0, -1.0, 1.0)  # noqa: E731
        return quat_normalize(align(prev) + align(nxt))

    def smoothness(world_q, mask, mid=None, prior=None):
        """Both rotation terms folded into one residual per joint (the weighted mean of
        the two residuals, the summed weight) and their loss."""
        wq = world_q[:, rot_j]
        rot_r = jnp.zeros(wq.shape[:-1] + (3,), wq.dtype)
        rot_w = jnp.zeros(wq.shape[:-1], wq.dtype)
        loss = jnp.zeros(wq.shape[:1], wq.dtype)
        if problem.smoothing:
            mid = midpoints(world_q) if mid is None else mid
            r = quat_log(quat_mul(wq, mid * conj.astype(wq.dtype)))
            w = mask[:, None].astype(wq.dtype) * weight.astype(wq.dtype)[None, :]
            rot_r, rot_w, loss = r * w[..., None], w, jnp.einsum("brk,brk,br->b", r, r, w)
        if prior is not None and problem.anchored:
            r = quat_log(quat_mul(wq, prior * conj.astype(wq.dtype)))
            w = jnp.broadcast_to(prior_w.astype(wq.dtype)[None, :], rot_w.shape)
            rot_r, rot_w, loss = rot_r + r * w[..., None], rot_w + w, loss + jnp.einsum("brk,brk,br->b", r, r, w)
        return rot_r / jnp.maximum(rot_w, 1e-30)[..., None], rot_w, loss

    smoothness.midpoints = midpoints
    smoothness.prior_weights = prior_w  # (R,): the prior's weights, the same every iteration
    return smoothness


def smooth_scale(setup) -> np.ndarray:
    """``(R,)`` per rotation joint ``Σ_m w_m ‖rest(m) − rest(j)‖²`` over its mapped descendants
    (units²): a rotation error of ``θ`` moves them by about ``θ`` times their distance, so the
    temporal term weighs a radian like the positions it moves."""
    rest = rest_arrays(setup.offsets, setup.rig.parents)[1]
    anc = ancestor_matrix(setup.rig.parents)[setup.rot_joints][:, setup.mapped]  # (R, M)
    d2 = np.sum((rest[setup.mapped][None] - rest[setup.rot_joints][:, None]) ** 2, axis=-1)
    return np.sum(anc * d2 * setup.weights[setup.mapped][None], axis=1)

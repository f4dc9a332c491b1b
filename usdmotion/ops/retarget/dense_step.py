"""The LM step from the explicit Jacobian and a dense Cholesky solve: the reference that
:func:`usdmotion.ops.retarget.tree_step.make_tree_step` (the solver's O(joints) step) is
tested against, and ``solve._make_lm(linear="dense")``."""

from __future__ import annotations

import numpy as np

from usdmotion.ops.retarget.problem import LM_DIAG_FLOOR, LM_NULL_DAMPING, Problem, masks


def _skew(a):
    """``(..., 3, 3)`` cross-product matrices ``[a]_×`` of ``a (..., 3)``."""
    import jax.numpy as jnp

    z = jnp.zeros_like(a[..., 0])
    x, y, w = a[..., 0], a[..., 1], a[..., 2]
    return jnp.stack([jnp.stack([z, -w, y], -1), jnp.stack([w, z, -x], -1), jnp.stack([-y, x, z], -1)], -2)


def make_jacobian(problem: Problem):
    """``(world_p (B,J,3), w=None (B,P)) -> J (B, 3P, P')``: the analytic Jacobian of the
    weighted residuals ``√w_m (p_m − p̂_m)`` of the points :attr:`Problem.points` with
    respect to world-frame rotation increments ``ω_j`` of the rotation joints
    (``∂p_m/∂ω_j = [p_j − p_m]_×`` for descendants ``m``) and world-frame increments of
    the free translations (identity on their subtree); ``w``: per-frame weights (default
    the problem's static ones)."""
    import jax.numpy as jnp

    mapped = jnp.asarray(problem.points)
    default_w = jnp.asarray(np.r_[problem.point_weights(), np.zeros(len(problem.floor_joints))], jnp.float32)
    rot_j = jnp.asarray(problem.rot_joints)
    rot_mask, trans_mask = (jnp.asarray(m) for m in masks(problem))
    n_rot, n_trans, n_map = len(problem.rot_joints), len(problem.trans_joints), len(problem.points)
    eye3 = jnp.eye(3, dtype=jnp.float32)

    def jacobian(world_p, w=None):
        batch = world_p.shape[0]
        sqrt_w = jnp.sqrt(jnp.broadcast_to(default_w if w is None else w, (batch, n_map)).astype(world_p.dtype))
        blocks = []
        if n_rot:
            a = world_p[:, None, rot_j] - world_p[:, mapped, None]  # (B, M, R, 3)
            jr = _skew(a) * rot_mask[None, :, :, None, None]  # (B, M, R, 3, 3)
            blocks.append(jnp.transpose(jr, (0, 1, 3, 2, 4)).reshape(batch, 3 * n_map, 3 * n_rot))
        if n_trans:
            jt = trans_mask[:, None, :, None] * eye3[None, :, None, :]  # (M, 3, T, 3)
            blocks.append(jnp.broadcast_to(jt.reshape(1, 3 * n_map, 3 * n_trans), (batch, 3 * n_map, 3 * n_trans)))
        jac = jnp.concatenate(blocks, axis=-1) if len(blocks) > 1 else blocks[0]
        return jac * jnp.repeat(sqrt_w, 3, axis=-1)[:, :, None]

    return jacobian


def make_dense_step(problem: Problem):
    """``(world_p, r, lam, w=None) -> step``: the same LM step as :func:`make_tree_step`
    (point residuals only) from the explicit Jacobian, ``JᵀWJ`` and a batched Cholesky
    factorisation (reference)."""
    import jax
    import jax.numpy as jnp

    jacobian = make_jacobian(problem)
    default_w = jnp.asarray(np.r_[problem.point_weights(), np.zeros(len(problem.floor_joints))], jnp.float32)

    def step(world_p, r, lam, w=None):
        w = jnp.broadcast_to(default_w if w is None else w, r.shape[:2]).astype(r.dtype)
        jac = jacobian(world_p, w)
        rw = (r * jnp.sqrt(w)[..., None]).reshape(r.shape[0], -1)
        h, g = jnp.einsum("bri,brj->bij", jac, jac), jnp.einsum("bri,br->bi", jac, rw)
        diag = jnp.diagonal(h, axis1=1, axis2=2).reshape(h.shape[0], -1, 3)
        mean = jnp.mean(diag, axis=-1, keepdims=True)
        damp = lam[:, None, None] * (diag + LM_DIAG_FLOOR * mean + 1e-12) + LM_NULL_DAMPING * mean
        damp = damp.reshape(h.shape[0], -1)
        damped = h + damp[:, :, None] * jnp.eye(h.shape[-1], dtype=h.dtype)
        return -jax.scipy.linalg.cho_solve((jnp.linalg.cholesky(damped), True), g[..., None])[..., 0]

    return step

"""The paper's reference solver: per-frame Adam on Euler angles, vmapped over frames (JAX)."""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import fk_arrays
from usdmotion.ops.retarget.problem import Problem
from usdmotion.rotations import euler_to_quat


def _euler_quats(theta, orders_groups, n_rot):
    """Quaternions ``(B, R, 4)`` of Euler angles ``(B, R, 3)``, one conversion per order group."""
    import jax.numpy as jnp

    out = jnp.zeros(theta.shape[:-1] + (4,), theta.dtype)
    for order, idx in orders_groups:
        out = out.at[:, idx].set(euler_to_quat(theta[:, idx], order))
    return out


def make_adam(problem: Problem, iterations: int, lr: float):
    """A jitted ``(q, t, targets, theta0) -> (q, t, loss, initial loss)`` per-frame Adam."""
    import jax
    import jax.numpy as jnp
    import optax

    parents = problem.parents
    mapped = jnp.asarray(problem.mapped)
    w = jnp.asarray(problem.weights, jnp.float32)
    rot_j = jnp.asarray(problem.rot_joints)
    trans_j = jnp.asarray(problem.trans_joints)
    groups = {}
    for k, order in enumerate(problem.orders):
        groups.setdefault(order, []).append(k)
    groups = tuple((order, np.asarray(idx)) for order, idx in groups.items())
    n_rot = len(problem.rot_joints)
    optimiser = optax.adam(lr)

    def frame_losses(params, q, t, targets):
        theta, tt = params
        q = q.at[:, rot_j].set(_euler_quats(theta, groups, n_rot)) if n_rot else q
        t = t.at[:, trans_j].set(tt) if len(problem.trans_joints) else t
        _, world_p = fk_arrays(q, t, parents)
        d = world_p[:, mapped] - targets
        per_frame = jnp.sum(w[None, :] * jnp.sum(d * d, axis=-1), axis=1)
        return jnp.sum(per_frame), per_frame

    grad = jax.value_and_grad(frame_losses, has_aux=True)

    def solve(q, t, targets, theta0):
        params = (theta0, t[:, trans_j])
        state = optimiser.init(params)
        (_, initial), _ = grad(params, q, t, targets)

        def body(_, carry):
            params, state, best, best_loss = carry
            (_, loss), g = grad(params, q, t, targets)
            better = loss < best_loss  # the loss of the current params, before the update
            best = jax.tree.map(lambda b, p: jnp.where(better.reshape((-1,) + (1,) * (p.ndim - 1)), p, b), best, params)
            best_loss = jnp.where(better, loss, best_loss)
            updates, state = optimiser.update(g, state, params)
            return optax.apply_updates(params, updates), state, best, best_loss

        params, state, best, best_loss = jax.lax.fori_loop(0, iterations, body, (params, state, params, initial))
        (_, last), _ = grad(params, q, t, targets)
        better = last < best_loss
        best = jax.tree.map(lambda b, p: jnp.where(better.reshape((-1,) + (1,) * (p.ndim - 1)), p, b), best, params)
        best_loss = jnp.where(better, last, best_loss)
        theta, tt = best
        q = q.at[:, rot_j].set(_euler_quats(theta, groups, n_rot)) if n_rot else q
        t = t.at[:, trans_j].set(tt) if len(problem.trans_joints) else t
        return q, t, best_loss, initial, jnp.int32(iterations)

    return jax.jit(solve)

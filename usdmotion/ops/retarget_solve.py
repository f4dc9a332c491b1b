"""JAX solvers for step 2 of retargeting (rotations), all frames at once.

This is the only module of the retargeting code that imports JAX. It works in
**float32** (JAX's default, what GPUs are fast at) on whatever device JAX picks; inputs
are centred per frame on the source root so float32 keeps ~1e-7 relative precision of
the body size rather than of the distance travelled.

Loss per frame (the paper's): ``L(f) = Σ_m w_m ‖p_{t(m)}(f) − p̂_m(f)‖²`` over the mapped
target joints ``t(m)`` and their source positions ``p̂_m`` (already scaled and axis-
converted to the target's units).

Methods:

* ``lm`` (default): batched Levenberg–Marquardt on the rotation manifold. Every
  optimised joint ``j`` gets a world-frame tangent update ``ω_j`` applied as
  ``q_j ← q_j · exp(R(W_j)ᵀ ω_j)``; the Jacobian is analytic,
  ``∂p_m/∂ω_j = [p_j − p_m]_×`` for every mapped descendant ``m`` of ``j`` (and the
  identity for free translations), built for all frames in one array expression.
  Steps are accepted per frame only when they lower the loss, so the current iterate
  is always the best one seen.
* ``adam``: the paper's reference: Adam (lr 0.1, 500 iterations, Kingma–Ba defaults)
  on the Euler angles (radians, each joint's channel order) of every optimised joint,
  for every frame separately — vmapped, which is mathematically the same as a loop
  over frames because Adam is element-wise and frames do not share parameters — keeping
  each frame's best iterate.

Compiled functions are cached per skeleton structure, method, iteration count and
chunk size (frames are solved in fixed-size chunks, the last one padded).
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from usdmotion.kinematics import fk_arrays
from usdmotion.rotations import euler_to_quat, quat_exp, quat_mul, quat_normalize, quat_rotate

#: Levenberg–Marquardt damping: start, factor down on success / up on failure, bounds.
LM_LAMBDA0 = 1e-2
LM_DOWN, LM_UP = 0.2, 5.0
LM_LAMBDA_MIN, LM_LAMBDA_MAX = 1e-5, 1e8
#: Floor of the damping matrix relative to the mean curvature (twist null spaces).
LM_DIAG_FLOOR = 1e-3
ADAM_LR = 0.1
LM_ITERATIONS = 10
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


def _masks(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """``(rot_mask (M, R), trans_mask (M, T))``: which parameters move which mapped joint."""
    from usdmotion.ops.hierarchy import ancestor_matrix

    anc = ancestor_matrix(problem.parents)
    rot = anc[problem.rot_joints][:, problem.mapped].T
    sub = anc | np.eye(len(problem.parents), dtype=bool)
    trans = sub[problem.trans_joints][:, problem.mapped].T
    return rot.astype(np.float32), trans.astype(np.float32)


def _skew(a):
    """``(..., 3, 3)`` cross-product matrices ``[a]_×`` of ``a (..., 3)``."""
    import jax.numpy as jnp

    z = jnp.zeros_like(a[..., 0])
    x, y, w = a[..., 0], a[..., 1], a[..., 2]
    return jnp.stack([jnp.stack([z, -w, y], -1), jnp.stack([w, z, -x], -1), jnp.stack([-y, x, z], -1)], -2)


def _pairs(problem: Problem) -> np.ndarray:
    """``(R, R)`` index of the deeper joint of every pair of rotation joints on one line of
    descent (the common descendants are that joint's), ``-1`` for unrelated pairs."""
    from usdmotion.ops.hierarchy import ancestor_matrix

    rot = problem.rot_joints
    anc = ancestor_matrix(problem.parents)[np.ix_(rot, rot)] | np.eye(len(rot), dtype=bool)
    k_below = anc  # [j, k]: rot j is an ancestor-or-self of rot k
    idx = np.arange(len(rot))
    return np.where(k_below, idx[None, :], np.where(k_below.T, idx[:, None], -1))


def make_normal_equations(problem: Problem):
    """``(world_p (B,J,3), residual (B,M,3)) -> (H (B,P,P), g (B,P))`` for LM, where
    ``H = JᵀWJ`` and ``g = JᵀW r`` of the analytic Jacobian (see :func:`make_jacobian`),
    built from moments of the mapped descendants of every rotation joint instead of
    ``J`` itself: ``H_jk = tr(X) I − X`` with ``X = Σ_m w_m (p_k − p_m)(p_j − p_m)ᵀ`` over
    the common mapped descendants ``m`` (those of the deeper of ``j``, ``k``), and
    ``g_j = Σ_m w_m (p_m − p_j) × r_m``. The moments ``Σ w``, ``Σ w p``, ``Σ w p pᵀ``,
    ``Σ w r``, ``Σ w p × r`` of all joints come from one matrix product with the
    ``(M, R)`` descendant mask. Positions must be centred per frame (float32).
    """
    import jax.numpy as jnp

    mapped = jnp.asarray(problem.mapped)
    w = jnp.asarray(problem.weights, jnp.float32)
    rot_j = jnp.asarray(problem.rot_joints)
    rot_mask, trans_mask = _masks(problem)
    n_rot, n_trans = len(problem.rot_joints), len(problem.trans_joints)
    pairs = _pairs(problem)
    deeper = jnp.asarray(np.maximum(pairs, 0))
    related = jnp.asarray(pairs >= 0, jnp.float32)
    # one mask for every moment: rotation joints' strict descendants, then translation subtrees
    mask = jnp.asarray(np.concatenate([rot_mask, trans_mask], axis=1) * np.asarray(problem.weights)[:, None], jnp.float32)
    totals = jnp.sum(mask, axis=0)  # (R + T,)
    eye3 = jnp.eye(3, dtype=jnp.float32)

    def equations(world_p, r):
        batch = world_p.shape[0]
        pm = world_p[:, mapped]  # (B, M, 3)
        outer = (pm[..., :, None] * pm[..., None, :]).reshape(pm.shape[:2] + (9,))
        feats = jnp.concatenate([pm, outer, r, jnp.cross(pm, r)], axis=-1)  # (B, M, 18)
        n_feat = feats.shape[-1]
        moments = (jnp.swapaxes(feats, 1, 2).reshape(batch * n_feat, -1) @ mask).reshape(batch, n_feat, -1)
        s1, s2, rs, cr = moments[:, 0:3], moments[:, 3:12], moments[:, 12:15], moments[:, 15:18]
        blocks_g = []
        h = None
        if n_rot:
            pr = world_p[:, rot_j]  # (B, R, 3)
            sd = jnp.swapaxes(s1[:, :, :n_rot], 1, 2)[:, deeper]  # (B, R, R, 3)
            qd = jnp.swapaxes(s2[:, :, :n_rot], 1, 2)[:, deeper].reshape(batch, n_rot, n_rot, 3, 3)
            wd = totals[:n_rot][deeper]
            p_j, p_k = pr[:, :, None, :], pr[:, None, :, :]
            x = (wd[None, :, :, None, None] * p_k[..., :, None] * p_j[..., None, :] - p_k[..., :, None] * sd[..., None, :]
                 - sd[..., :, None] * p_j[..., None, :] + qd)
            trace = x[..., 0, 0] + x[..., 1, 1] + x[..., 2, 2]
            h_rr = (trace[..., None, None] * eye3 - x) * related[None, :, :, None, None]
            h = jnp.transpose(h_rr, (0, 1, 3, 2, 4)).reshape(batch, 3 * n_rot, 3 * n_rot)
            # g_j = Σ w (p_m − p_j) × r_m = Σ w p_m × r_m − p_j × Σ w r_m
            g_r = jnp.swapaxes(cr[:, :, :n_rot], 1, 2) - jnp.cross(pr, jnp.swapaxes(rs[:, :, :n_rot], 1, 2))
            blocks_g.append(g_r.reshape(batch, 3 * n_rot))
        if n_trans:
            h_tt = jnp.kron(jnp.asarray(trans_mask.T @ (trans_mask * np.asarray(problem.weights)[:, None])), eye3)
            h_tt = jnp.broadcast_to(h_tt, (batch, 3 * n_trans, 3 * n_trans))
            blocks_g.append(jnp.swapaxes(rs[:, :, n_rot:], 1, 2).reshape(batch, 3 * n_trans))
            if n_rot:
                # Σ_{m ∈ sub(t) ∩ desc(j)} w (p_j − p_m): the translation subtree holds every
                # optimised joint's descendants when it holds the joint itself
                inside = jnp.asarray(_trans_contains(problem), jnp.float32)  # (T, R)
                a = (totals[:n_rot][None, :, None] * pr[:, None] - jnp.swapaxes(s1[:, :, :n_rot], 1, 2)[:, None])
                h_tr = _skew(a * inside[None, :, :, None])  # (B, T, R, 3, 3)
                h_tr = jnp.transpose(h_tr, (0, 1, 3, 2, 4)).reshape(batch, 3 * n_trans, 3 * n_rot)
                h = jnp.concatenate([jnp.concatenate([h, jnp.swapaxes(h_tr, 1, 2)], axis=2),
                                     jnp.concatenate([h_tr, h_tt], axis=2)], axis=1)
            else:
                h = h_tt
        g = jnp.concatenate(blocks_g, axis=1) if len(blocks_g) > 1 else blocks_g[0]
        return h, g

    return equations


def _trans_contains(problem: Problem) -> np.ndarray:
    """``(T, R)`` bool: rotation joint inside the subtree of translation joint (itself included).

    Raises ``ValueError`` when a rotation joint has descendants both inside and outside a
    translation subtree (never for the problems :mod:`usdmotion.ops.retarget` builds).
    """
    from usdmotion.ops.hierarchy import ancestor_matrix

    sub = ancestor_matrix(problem.parents) | np.eye(len(problem.parents), dtype=bool)
    inside = sub[problem.trans_joints][:, problem.rot_joints]
    rot_mask, trans_mask = _masks(problem)
    for t in range(len(problem.trans_joints)):
        for r in np.flatnonzero(~inside[t]):
            if np.any(rot_mask[:, r].astype(bool) & trans_mask[:, t].astype(bool)):
                raise ValueError("a rotation joint outside a translation subtree moves joints inside it")
    return inside


def make_jacobian(problem: Problem):
    """``world_p (B,J,3) -> J (B, 3M, P)``: the analytic Jacobian of the weighted residuals
    ``√w_m (p_m − p̂_m)`` with respect to world-frame rotation increments ``ω_j`` of the
    rotation joints (``∂p_m/∂ω_j = [p_j − p_m]_×`` for mapped descendants ``m``) and
    world-frame increments of the free translations (identity on their subtree)."""
    import jax.numpy as jnp

    mapped = jnp.asarray(problem.mapped)
    sqrt_w = jnp.asarray(np.sqrt(problem.weights), jnp.float32)
    rot_j = jnp.asarray(problem.rot_joints)
    rot_mask, trans_mask = (jnp.asarray(m) for m in _masks(problem))
    n_rot, n_trans, n_map = len(problem.rot_joints), len(problem.trans_joints), len(problem.mapped)
    eye3 = jnp.eye(3, dtype=jnp.float32)

    def jacobian(world_p):
        batch = world_p.shape[0]
        blocks = []
        if n_rot:
            a = world_p[:, None, rot_j] - world_p[:, mapped, None]  # (B, M, R, 3)
            jr = _skew(a) * rot_mask[None, :, :, None, None]  # (B, M, R, 3, 3)
            blocks.append(jnp.transpose(jr, (0, 1, 3, 2, 4)).reshape(batch, 3 * n_map, 3 * n_rot))
        if n_trans:
            jt = trans_mask[:, None, :, None] * eye3[None, :, None, :]  # (M, 3, T, 3)
            blocks.append(jnp.broadcast_to(jt.reshape(1, 3 * n_map, 3 * n_trans), (batch, 3 * n_map, 3 * n_trans)))
        jac = jnp.concatenate(blocks, axis=-1) if len(blocks) > 1 else blocks[0]
        return jac * jnp.repeat(sqrt_w, 3)[None, :, None]

    return jacobian


def make_apply(problem: Problem):
    """``(q, t, world_q, step (B, P)) -> (q, t)``: apply world-frame increments on the manifold.

    Rotation joint ``j``: ``q_j ← normalize(q_j · exp(R(W_j)ᵀ ω_j))`` (``W_j`` its world
    rotation), i.e. its world rotation becomes ``exp(ω_j) · W_j``; free translation ``k``:
    ``t_k ← t_k + R(W_parent)ᵀ δ_k``.
    """
    import jax.numpy as jnp

    parents = problem.parents
    rot_j = jnp.asarray(problem.rot_joints)
    trans_j = jnp.asarray(problem.trans_joints)
    trans_parent = jnp.asarray(np.where(parents[problem.trans_joints] < 0, len(parents),
                                        parents[problem.trans_joints]))
    n_rot, n_trans = len(problem.rot_joints), len(problem.trans_joints)

    def apply(q, t, world_q, step):
        conj = jnp.asarray([1.0, -1.0, -1.0, -1.0], q.dtype)
        if n_rot:
            omega = step[:, : 3 * n_rot].reshape(-1, n_rot, 3)
            local = quat_rotate(world_q[:, rot_j] * conj, omega)
            q = q.at[:, rot_j].set(quat_normalize(quat_mul(q[:, rot_j], quat_exp(local))))
        if n_trans:
            delta = step[:, 3 * n_rot:].reshape(-1, n_trans, 3)
            identity = jnp.broadcast_to(jnp.asarray([1.0, 0, 0, 0], q.dtype), (q.shape[0], 1, 4))
            parent_q = jnp.concatenate([world_q, identity], axis=1)[:, trans_parent]
            t = t.at[:, trans_j].add(quat_rotate(parent_q * conj, delta))
        return q, t

    return apply


def make_residuals(problem: Problem):
    """``(q, t, targets) -> (world_q, world_p, r (B, M, 3), loss (B,))`` with
    ``r = p_mapped − targets`` and ``loss = Σ_m w_m ‖r_m‖²`` per frame."""
    import jax.numpy as jnp

    parents = problem.parents
    mapped = jnp.asarray(problem.mapped)
    w = jnp.asarray(problem.weights, jnp.float32)

    def residuals(q, t, targets):
        world_q, world_p = fk_arrays(q, t, parents)
        r = world_p[:, mapped] - targets
        return world_q, world_p, r, jnp.einsum("bmk,bmk,m->b", r, r, w.astype(r.dtype))

    return residuals


def _make_lm(problem: Problem, iterations: int):
    """A jitted ``(q, t, targets) -> (q, t, loss (B,), initial loss (B,))`` LM solver."""
    import jax
    import jax.numpy as jnp

    jacobian = make_jacobian(problem)
    sqrt_w = jnp.sqrt(jnp.asarray(problem.weights, jnp.float32))
    evaluate = make_residuals(problem)
    apply = make_apply(problem)

    def normal_equations(world_p, r):
        jac = jacobian(world_p)
        rw = (r * sqrt_w[:, None]).reshape(r.shape[0], -1)
        return jnp.einsum("bri,brj->bij", jac, jac), jnp.einsum("bri,br->bi", jac, rw)

    def solve(q, t, targets):
        world_q, world_p, r, loss = evaluate(q, t, targets)
        initial = loss
        lam = jnp.full(loss.shape, LM_LAMBDA0, jnp.float32)

        def body(_, carry):
            q, t, world_q, world_p, r, loss, lam = carry
            h, g = normal_equations(world_p, r)
            diag = jnp.diagonal(h, axis1=1, axis2=2)
            floor = LM_DIAG_FLOOR * jnp.mean(diag, axis=1, keepdims=True) + 1e-12
            damped = h + (lam[:, None] * (diag + floor))[:, :, None] * jnp.eye(h.shape[-1], dtype=h.dtype)
            chol = jnp.linalg.cholesky(damped)
            step = -jax.scipy.linalg.cho_solve((chol, True), g[..., None])[..., 0]
            q2, t2 = apply(q, t, world_q, step)
            world_q2, world_p2, r2, loss2 = evaluate(q2, t2, targets)
            ok = (loss2 < loss) & jnp.isfinite(loss2)
            pick = lambda new, old: jnp.where(ok.reshape((-1,) + (1,) * (new.ndim - 1)), new, old)  # noqa: E731
            lam = jnp.clip(jnp.where(ok, lam * LM_DOWN, lam * LM_UP), LM_LAMBDA_MIN, LM_LAMBDA_MAX)
            return (pick(q2, q), pick(t2, t), pick(world_q2, world_q), pick(world_p2, world_p), pick(r2, r),
                    pick(loss2, loss), lam)

        carry = jax.lax.fori_loop(0, iterations, body, (q, t, world_q, world_p, r, loss, lam))
        return carry[0], carry[1], carry[5], initial

    return jax.jit(solve)


def _euler_quats(theta, orders_groups, n_rot):
    """Quaternions ``(B, R, 4)`` of Euler angles ``(B, R, 3)``, one conversion per order group."""
    import jax.numpy as jnp

    out = jnp.zeros(theta.shape[:-1] + (4,), theta.dtype)
    for order, idx in orders_groups:
        out = out.at[:, idx].set(euler_to_quat(theta[:, idx], order))
    return out


def _make_adam(problem: Problem, iterations: int, lr: float):
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
        return q, t, best_loss, initial

    return jax.jit(solve)


_EXECUTABLES: dict = {}


def _executable(problem: Problem, method: str, iterations: int, lr: float, args) -> tuple[object, float]:
    """``(compiled function, seconds spent compiling)`` for these argument shapes (cached)."""
    import time

    key = (problem.key(), method, iterations, lr, tuple((a.shape, str(a.dtype)) for a in args))
    if key in _EXECUTABLES:
        return _EXECUTABLES[key], 0.0
    start = time.perf_counter()
    fn = _make_lm(problem, iterations) if method == "lm" else _make_adam(problem, iterations, lr)
    compiled = fn.lower(*args).compile()
    if len(_EXECUTABLES) >= 32:
        _EXECUTABLES.pop(next(iter(_EXECUTABLES)))
    _EXECUTABLES[key] = compiled
    return compiled, time.perf_counter() - start


def _bucket(n: int, smallest: int = 16) -> int:
    """Smallest ``2^k · (8 + i) / 8 ≥ n`` (≤ 12.5 % padding, few distinct compiled sizes)."""
    if n <= smallest:
        return smallest
    base = 1 << (int(n).bit_length() - 1)
    return next(base * (8 + i) // 8 for i in range(9) if base * (8 + i) // 8 >= n)


def chunk_plan(n_frames: int, problem: Problem, budget_bytes: float = 64e6) -> tuple[int, int]:
    """``(frames per compiled call, number of calls)``: equal chunks under a memory budget
    (Jacobian and normal matrices, float32), each padded to a :func:`_bucket` size."""
    n_params, n_rows = max(problem.n_params, 3), 3 * len(problem.mapped)
    per_frame = 4 * 3 * (n_rows * n_params + n_params * n_params)
    largest = int(min(4096, max(64, budget_bytes // per_frame)))
    calls = -(-n_frames // largest)
    return _bucket(-(-n_frames // calls)), calls


@dataclass(frozen=True)
class Solution:
    """Result of :func:`solve`: float64 NumPy arrays and timings.

    Attributes:
        q: ``(F, J, 4)`` local rotations (unit wxyz).
        t: ``(F, J, 3)`` local translations (same centring as the input).
        loss: ``(F,)`` final loss per frame (float32 solver arithmetic).
        initial: ``(F,)`` loss of the initial guess.
        compile_s: seconds spent compiling (0 when cached).
        run_s: seconds spent optimising.
        chunk: frames per compiled call; calls: number of calls.
    """

    q: np.ndarray
    t: np.ndarray
    loss: np.ndarray
    initial: np.ndarray
    compile_s: float
    run_s: float
    chunk: int
    calls: int


def solve(problem: Problem, q0: np.ndarray, t0: np.ndarray, targets: np.ndarray, method: str = "lm",
          iterations: int | None = None, chunk: int | None = None, lr: float = ADAM_LR,
          progress=None) -> Solution:
    """Optimise rotations (and free translations) of all frames.

    Args:
        problem: static structure.
        q0: ``(F, J, 4)`` initial local rotations (wxyz).
        t0: ``(F, J, 3)`` local translations (root: world position), already centred.
        targets: ``(F, M, 3)`` source positions of the mapped joints, same frame/centring.
        method: ``"lm"`` or ``"adam"``.
        iterations: LM iterations (default 10) or Adam iterations (default 500).
        chunk: frames per compiled call (default :func:`chunk_plan`).
        lr: Adam's learning rate.
        progress: optional ``callable(frames_done)``.
    """
    import time

    import jax
    import jax.numpy as jnp

    from usdmotion.rotations import quat_to_euler

    if method not in ("lm", "adam"):
        raise ValueError(f"unknown method {method!r}")
    iterations = int(iterations if iterations is not None else (LM_ITERATIONS if method == "lm" else ADAM_ITERATIONS))
    n_frames = q0.shape[0]
    chunk = chunk or chunk_plan(n_frames, problem)[0]
    theta0 = None
    if method == "adam":
        theta0 = np.zeros(q0.shape[:1] + (len(problem.rot_joints), 3))
        for k, (j, order) in enumerate(zip(problem.rot_joints, problem.orders)):
            theta0[:, k] = quat_to_euler(q0[:, j], order)
    outs, compile_s, run_s, calls = [], 0.0, 0.0, 0
    for start in range(0, n_frames, chunk):
        stop = min(start + chunk, n_frames)
        pad = np.r_[np.arange(start, stop), np.full(chunk - (stop - start), stop - 1)]
        args = [jnp.asarray(a[pad], jnp.float32) for a in (q0, t0, targets)]
        if theta0 is not None:
            args.append(jnp.asarray(theta0[pad], jnp.float32))
        fn, seconds = _executable(problem, method, iterations, float(lr), args)
        compile_s += seconds
        began = time.perf_counter()
        result = jax.block_until_ready(fn(*args))
        run_s += time.perf_counter() - began
        outs.append([np.asarray(x, np.float64)[: stop - start] for x in result])
        calls += 1
        if progress is not None:
            progress(stop - start)
    q, t, loss, initial = (np.concatenate(parts) for parts in zip(*outs))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Solution(q, t, loss, initial, compile_s, run_s, chunk, calls)


def device_description() -> str:
    """The device JAX computes on, e.g. ``"cpu"`` or ``"gpu (NVIDIA H100)"``."""
    import jax

    device = jax.devices()[0]
    kind = getattr(device, "device_kind", "")
    return device.platform + (f" ({kind})" if kind and kind.lower() != device.platform else "")


def enable_compilation_cache() -> str | None:
    """Turn on JAX's persistent compilation cache (for command-line runs); returns its folder.

    Folder: ``$USDMOTION_JAX_CACHE``, else ``$XDG_CACHE_HOME/usdmotion/jax`` (default
    ``~/.cache/usdmotion/jax``); ``USDMOTION_JAX_CACHE=off`` disables it. A cache folder
    the user already configured for JAX is left alone. Repeat runs on the same skeletons
    then skip most of the XLA compile time.
    """
    import os
    from pathlib import Path

    import jax

    setting = os.environ.get("USDMOTION_JAX_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false") or jax.config.jax_compilation_cache_dir:
        return jax.config.jax_compilation_cache_dir or None
    folder = Path(setting) if setting else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "usdmotion" / "jax"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    return str(folder)

"""JAX solvers for step 2 of retargeting (rotations), all frames at once.

The solve loop and its residuals live here; the steps and terms it composes are in
``tree_step``, ``dense_step``, ``rotation_terms``, ``lm_model`` and ``adam``, and
``jax_runtime`` picks the devices. It works in
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
  identity for free translations). The damped normal equations are solved on the
  joint tree in O(joints) (:mod:`usdmotion.ops.retarget.tree_step`); the dense Cholesky
  form is kept as a reference (``linear="dense"``, :mod:`usdmotion.ops.retarget.dense_step`).
  On a CPU a chunk's frames are split into consecutive blocks, one per JAX CPU device
  (one per core, ``jax_runtime.use_cpu_cores``), run in lockstep inside ``shard_map``:
  XLA:CPU would run the whole chunk's small per-frame operations on one core. Steps are
  accepted per frame only when they lower the loss, so the current iterate is always the
  best one seen.
* ``adam``: the paper's reference: Adam (lr 0.1, 500 iterations, Kingma–Ba defaults)
  on the Euler angles (radians, each joint's channel order) of every optimised joint,
  for every frame separately — vmapped, which is mathematically the same as a loop
  over frames because Adam is element-wise and frames do not share parameters — keeping
  each frame's best iterate.

Compiled functions are cached per skeleton structure, method, iteration count and
chunk size (frames are solved in fixed-size chunks, the last one padded).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from usdmotion.kinematics import fk_arrays
from usdmotion.ops.retarget.hierarchy import ancestor_matrix, restricted_parents, with_ancestors
from usdmotion.ops.retarget.problem import (ADAM_ITERATIONS, ADAM_LR, LM_ATOL, LM_DAMPING_UPDATE,
                                            LM_DAMPING_UPDATES, LM_DOWN, LM_ITERATIONS, LM_LAMBDA0, LM_LAMBDA_MAX,
                                            LM_LAMBDA_MIN, LM_RTOL, LM_RTOL_TOTAL, LM_UP, Problem)
from usdmotion.ops.retarget.adam import make_adam
from usdmotion.ops.retarget.dense_step import make_dense_step
from usdmotion.ops.retarget.jax_runtime import frame_blocks, frame_mesh, frame_shards, lower_stored, use_cpu_cores
from usdmotion.ops.retarget.lm_model import make_model_gain
from usdmotion.ops.retarget.rotation_terms import make_rotation_terms
from usdmotion.ops.retarget.tree_step import make_tree_step
from usdmotion.progress import Progress
from usdmotion.rotations import (quat_exp, quat_mul, quat_normalize, quat_rotate,
                                 quat_to_euler)

# JAX (and optax) are imported inside the functions that use them: a deliberately deferred
# heavy dependency (seconds of start-up), needed only once a solve runs.

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
    """``(q, t, targets (B, M+C, 3), w=None (B, M+C), floor=None (B,)) -> (world_q, world_p,
    r (B, P, 3), loss (B,), w (B, P))``.

    ``r`` holds the residuals of the points :attr:`Problem.points`: ``p − target`` for the
    mapped and contact joints, and for the floor joints ``(p_up − floor)`` on the vertical
    axis where a joint is below the floor (0 elsewhere; weight ``floor_weight`` there, 0
    elsewhere — a one-sided term). ``loss = Σ w ‖r‖²`` per frame. ``w`` defaults to the
    problem's static weights (contact terms off). The LM step treats a floor residual like
    the others, i.e. as the distance to the joint's projection onto the floor held at the
    current iterate: the same gradient, and a Gauss–Newton model that also resists sliding
    a joint that is below the floor."""
    import jax.numpy as jnp

    parents = problem.parents
    near = jnp.asarray(np.r_[problem.mapped, problem.contact_joints].astype(np.int64))
    floor_j = jnp.asarray(problem.floor_joints)
    default_w = jnp.asarray(problem.point_weights(), jnp.float32)
    n_floor, up = len(problem.floor_joints), int(problem.up)

    def residuals(q, t, targets, w=None, floor=None):
        world_q, world_p = fk_arrays(q, t, parents)
        r = world_p[:, near] - targets
        w = jnp.broadcast_to(default_w if w is None else w, r.shape[:2]).astype(r.dtype)
        if n_floor:
            height = world_p[:, floor_j, up] - (0.0 if floor is None else floor[:, None])
            below = height < 0
            r = jnp.concatenate([r, jnp.zeros(height.shape + (3,), r.dtype).at[..., up].set(
                jnp.where(below, height, 0.0))], axis=1)
            w = jnp.concatenate([w, jnp.where(below, problem.floor_weight, 0.0).astype(r.dtype)], axis=1)
        return world_q, world_p, r, jnp.einsum("bmk,bmk,bm->b", r, r, w), w

    return residuals


def single_point_joints(problem: Problem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotation joints whose subtree holds exactly one mapped joint: ``(slot in
    rot_joints, joint, that mapped joint)``. Their twist about the line to it is a null
    direction of the loss."""

    anc = ancestor_matrix(problem.parents)[:, problem.mapped]  # (J, M): mapped strict descendants
    rows = [(k, int(j), int(problem.mapped[np.flatnonzero(anc[j])[0]]))
            for k, j in enumerate(problem.rot_joints) if anc[j].sum() == 1]
    return tuple(np.array([r[i] for r in rows], np.int64) for i in range(3))  # type: ignore[return-value]


def make_lm_step(problem: Problem, linear: str = "tree"):
    """``(world_p, r, lam, w=None, rot_r=None, rot_w=None) -> step (B, P)``: the LM step
    (``linear``: ``"tree"`` or ``"dense"``, which takes no rotation residuals) with the
    twist of every :func:`single_point_joints` joint about the line
    to its one mapped descendant removed: the loss cannot see it, so left in, float32
    noise would make it drift over the iterations and flip bones by up to 180° between
    frames. The twist then stays where the (smooth) initial guess put it."""
    import jax.numpy as jnp


    linear_step = make_tree_step(problem) if linear == "tree" else make_dense_step(problem)
    slot, joint, point = (jnp.asarray(a) for a in single_point_joints(problem))
    n_rot = len(problem.rot_joints)

    def lm_step(world_p, r, lam, w=None, rot_r=None, rot_w=None):
        step = linear_step(world_p, r, lam, w, rot_r, rot_w) if linear == "tree" else linear_step(world_p, r, lam, w)
        if slot.size == 0:
            return step
        omega = step[:, : 3 * n_rot].reshape(step.shape[0], n_rot, 3)
        axis = world_p[:, point] - world_p[:, joint]
        axis = axis / jnp.maximum(jnp.linalg.norm(axis, axis=-1, keepdims=True), 1e-20)
        w = omega[:, slot]
        omega = omega.at[:, slot].set(w - jnp.sum(w * axis, -1, keepdims=True) * axis)
        return step.at[:, : 3 * n_rot].set(omega.reshape(step.shape[0], -1))

    return lm_step


def _make_lm(problem: Problem, linear: str = "tree", damping: str = LM_DAMPING_UPDATE, shards: int = 1):
    """A jitted ``(q, t, targets, w, floor, smooth_mask, iterations) -> (q, t, loss (B,),
    initial loss (B,), iterations run)`` LM solver (at most ``iterations``, a runtime int32
    scalar so one compiled function serves every cap; stops early when every frame has
    converged). ``targets (B, M+C, 3)`` and ``w (B, M+C)``: positions and weights of the
    mapped and contact points; ``floor (B,)``: floor height (centred like the positions);
    ``smooth_mask (B,)``: frames whose neighbours are real (the temporal term).

    ``linear``: ``"tree"`` (:func:`make_tree_step`, default) or ``"dense"``
    (:func:`make_dense_step`, without the temporal term); both solve the same damped system.
    ``damping``: the λ update rule (:data:`usdmotion.ops.retarget.problem.LM_DAMPING_UPDATES`).
    ``shards``: CPU devices the frames are split over (equal consecutive blocks, one per
    device, ``B`` a multiple of it). The blocks run in lockstep: the stop tests and the
    temporal term's neighbours span the whole batch, so every frame takes the steps it
    would take in one block (the float sums aside).
    """
    import jax
    import jax.numpy as jnp

    axis = "frames" if shards > 1 else None
    total = (lambda x: jax.lax.psum(x, axis)) if axis else (lambda x: x)  # noqa: E731

    evaluate = make_residuals(problem)
    apply = make_apply(problem)
    lm_step = make_lm_step(problem, linear)
    smoothing = (problem.smoothing or problem.anchored) and linear == "tree"
    # contact and floor terms weigh 100–1000× the positions: rejected steps are common while
    # λ adapts, so they must not count as convergence
    stiff = bool(len(problem.contact_joints) or len(problem.floor_joints))
    smoothness = make_rotation_terms(problem, axis, shards) if smoothing else None
    nielsen = damping == "nielsen"
    model_gain = make_model_gain(problem) if nielsen else None
    rot_j = jnp.asarray(problem.rot_joints)

    def solve(q, t, targets, w, floor, smooth_mask, iterations):
        world_q, world_p, r, loss, w_all = evaluate(q, t, targets, w, floor)
        prior = world_q[:, rot_j] if problem.anchored else None
        # the rotation residuals of the iterate, carried for the prior alone (none without rotation terms)
        rot_r = jnp.zeros(world_q.shape[:1] + (len(problem.rot_joints) if smoothing else 0, 3), world_q.dtype)
        if smoothing:
            rot_r, _, s_loss = smoothness(world_q, smooth_mask, None, prior)
            loss = loss + s_loss
        initial = loss
        lam = jnp.full(loss.shape, LM_LAMBDA0, loss.dtype)
        nu = jnp.full(loss.shape, 2.0, loss.dtype)  # Nielsen's factor for the next rejection
        stall = jnp.zeros(loss.shape, jnp.int32)  # iterations in a row without real progress
        moved = jnp.zeros(loss.shape, bool)  # a step of the frame was accepted (or λ reached its largest)

        def cond(carry):
            i, loss, stall, flat = carry[0], carry[6], carry[8], carry[9]
            frames_done = (stall >= 2) | (loss <= LM_ATOL * initial)
            return (i < iterations) & (total(jnp.sum(~frames_done)) > 0) & (flat < 2)

        def body(carry):
            i, q, t, world_q, world_p, r, loss, lam, stall, flat, w_all, nu, rot_r, moved = carry
            rot_w = mid = None
            if problem.smoothing:  # neighbours held for this iteration (Jacobi over time)
                mid = smoothness.midpoints(world_q)
                rot_r, rot_w, s_loss = smoothness(world_q, smooth_mask, mid, prior)
                loss = evaluate_loss(r, w_all) + s_loss
            elif smoothing:  # the prior alone: the residuals were computed with the iterate, its weights are fixed
                rot_w = jnp.broadcast_to(smoothness.prior_weights, rot_r.shape[:2]).astype(rot_r.dtype)
            step = lm_step(world_p, r, lam, w_all, rot_r, rot_w) if smoothing else lm_step(world_p, r, lam, w_all)
            predicted = model_gain(world_p, r, w_all, step, rot_r, rot_w) if nielsen else None
            q2, t2 = apply(q, t, world_q, step)
            world_q2, world_p2, r2, loss2, w2 = evaluate(q2, t2, targets, w, floor)
            rot_r2 = rot_r
            if smoothing:
                rot_r2, _, s_loss2 = smoothness(world_q2, smooth_mask, mid, prior)
                loss2 = loss2 + s_loss2
            ok = (loss2 < loss) & jnp.isfinite(loss2)
            gain = jnp.where(ok, (loss - loss2) / jnp.maximum(loss, 1e-30), 0.0)
            # a rejected step only raises λ until the frame has moved (a step accepted, or λ at its
            # largest): a start far from the targets can need several (a distorted source: the LM
            # stopped after two rejections without any gain); with contact or floor terms, which
            # weigh 100–1000× the positions, rejections never count, as λ adapts all the way
            moved = moved | ok | (lam >= LM_LAMBDA_MAX)
            counts = ok | (lam >= LM_LAMBDA_MAX) if stiff else moved
            stall = jnp.where(gain > LM_RTOL, 0, jnp.where(counts, stall + 1, stall))
            pick = lambda new, old: jnp.where(ok.reshape((-1,) + (1,) * (new.ndim - 1)), new, old)  # noqa: E731
            new_loss = pick(loss2, loss)
            before, after = total(jnp.sum(loss)), total(jnp.sum(new_loss))
            total_gain = (before - after) / jnp.maximum(before, 1e-30)
            waiting = total(jnp.sum(~moved)) > 0  # frames still looking for their first step
            flat = jnp.where((total_gain < LM_RTOL_TOTAL) & ~waiting, flat + 1, 0)
            if nielsen:  # ρ = actual / predicted reduction (see problem.LM_DAMPING_UPDATE)
                rho = (loss - loss2) / jnp.maximum(predicted, 1e-30 * jnp.maximum(loss, 1e-30))
                shrink = jnp.maximum(1.0 / 3.0, 1.0 - (2.0 * jnp.clip(rho, 0.0, 1.0) - 1.0) ** 3)
                lam = jnp.clip(jnp.where(ok, lam * shrink, lam * nu), LM_LAMBDA_MIN, LM_LAMBDA_MAX)
                nu = jnp.where(ok, 2.0, jnp.minimum(2.0 * nu, 1e6))
            else:
                lam = jnp.clip(jnp.where(ok, lam * LM_DOWN, lam * LM_UP), LM_LAMBDA_MIN, LM_LAMBDA_MAX)
            return (i + 1, pick(q2, q), pick(t2, t), pick(world_q2, world_q), pick(world_p2, world_p), pick(r2, r),
                    new_loss, lam, stall, flat, pick(w2, w_all), nu, pick(rot_r2, rot_r), moved)

        carry = jax.lax.while_loop(cond, body, (jnp.int32(0), q, t, world_q, world_p, r, loss, lam, stall,
                                                jnp.int32(0), w_all, nu, rot_r, moved))
        return carry[1], carry[2], carry[6], initial, carry[0]

    if not axis:
        return jax.jit(solve)
    from jax.sharding import PartitionSpec

    blocks = PartitionSpec(axis)
    return jax.jit(jax.shard_map(solve, mesh=frame_mesh(shards), in_specs=(blocks,) * 6 + (PartitionSpec(),),
                                 out_specs=(blocks,) * 4 + (PartitionSpec(),), check_vma=False))




def evaluate_loss(r, w):
    """``Σ_p w_p ‖r_p‖²`` per frame of residuals ``r (B, P, 3)`` and weights ``w (B, P)``."""
    import jax.numpy as jnp

    return jnp.einsum("bmk,bmk,bm->b", r, r, w)


_EXECUTABLES: dict = {}
#: LM's λ update rule for :func:`solve` calls that name none (a benchmark may switch it).
DAMPING = LM_DAMPING_UPDATE


#: XLA options for the solvers' compiles on a CPU.
#:
#: * Loop emitters: the LM's loop body is ~15,000 lines of small elementwise HLO (the tree
#:   step's unrolled 6×6 algebra); XLA:CPU's fusion emitters took 16.5 s to compile it for
#:   512 walk frames, the older loop emitters 10.0 s, and the compiled solve ran as fast
#:   (641 / 669 ms on one device, 481 / 479 ms on two; same loss), throwaway
#:   ``/tmp/exp/ctime3.py``. Compiling is most of a first retarget's time on a new rig.
#: * YNNPACK for matrix products only: by default XLA:CPU also hands reductions (the
#:   per-frame loss sums ``Σ w ‖r‖²``, the norms) to YNNPACK, which took up to ~0.3 ms for
#:   one over 576 frames, about a quarter of an LM iteration's time in all. Products only:
#:   the plain solve took 0.67–0.83× the time on the benchmark's pairs (min of 10 alternated
#:   runs, two devices: walk → Bandai 74.1 → 54.5 ms, 86_01 → Rokoko 239.0 → 159.5 ms; no
#:   YNNPACK at all: 64.7 / 207.6 ms), same losses to 6 digits (``/tmp/exp/ynn_solve.py``).
CPU_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False,
                       "xla_cpu_experimental_ynn_fusion_type": "LIBRARY_FUSION_TYPE_DOT"}


def compile_lowered(lowered):
    """``lowered.compile()`` with :data:`CPU_COMPILER_OPTIONS` when JAX computes on a CPU
    (plain ``compile()`` elsewhere, or if this jaxlib no longer knows an option)."""
    import jax

    if jax.default_backend() != "cpu" or not CPU_COMPILER_OPTIONS:
        return lowered.compile()
    try:
        return lowered.compile(compiler_options=CPU_COMPILER_OPTIONS)
    except Exception as exc:  # noqa: BLE001 - an unknown option is a jaxlib error type of its own
        if not any(name in str(exc) for name in CPU_COMPILER_OPTIONS):
            raise
        return lowered.compile()


def _executable(problem: Problem, method: str, iterations: int, lr: float, args,
                damping: str = LM_DAMPING_UPDATE, shards: int = 1) -> tuple[object, float]:
    """``(compiled function, seconds spent compiling)`` for these argument shapes (cached)."""

    key = (problem.key(), method, None if method == "lm" else iterations, lr, damping, shards,
           tuple((a.shape, str(a.dtype)) for a in args))
    if key in _EXECUTABLES:
        return _EXECUTABLES[key], 0.0
    start = time.perf_counter()
    fn = _make_lm(problem, damping=damping, shards=shards) if method == "lm" else make_adam(problem, iterations, lr)
    compiled = compile_lowered(lower_stored(fn, args, key))
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
    n_params, n_rows = max(problem.n_params, 3), 3 * len(problem.points)
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
        iterations: most iterations any chunk ran (LM stops early when converged).
    """

    q: np.ndarray
    t: np.ndarray
    loss: np.ndarray
    initial: np.ndarray
    compile_s: float
    run_s: float
    chunk: int
    calls: int
    iterations: int


def solve(problem: Problem, q0: np.ndarray, t0: np.ndarray, targets: np.ndarray, method: str = "lm",
          iterations: int | None = None, chunk: int | None = None, lr: float = ADAM_LR,
          progress: Progress | None = None, weights: np.ndarray | None = None,
          floor: np.ndarray | None = None, damping: str | None = None, shards: int | None = None) -> Solution:
    """Optimise rotations (and free translations) of all frames.

    Args:
        problem: static structure.
        q0: ``(F, J, 4)`` initial local rotations (wxyz).
        t0: ``(F, J, 3)`` local translations (root: world position), already centred.
        targets: ``(F, M, 3)`` source positions of the mapped joints, same frame/centring.
        method: ``"lm"`` or ``"adam"``.
        iterations: LM's maximum (default 100; it stops when converged) or Adam's count (500).
        chunk: frames per compiled call (default :func:`chunk_plan`).
        lr: Adam's learning rate.
        progress: optional :class:`usdmotion.progress.Progress`, called ``(frames done, n_frames, message)``
            after every chunk.
        weights: ``(F, M + C)`` per-frame weights of the mapped and contact points (default:
            the problem's static weights; contact terms off). ``targets`` is then
            ``(F, M + C, 3)``.
        floor: ``(F,)`` floor height on the up axis, centred like ``t0`` (floor term).
        damping: LM's λ update, ``"fixed"`` or ``"nielsen"`` (default: the module setting
            :data:`DAMPING`, i.e. :data:`usdmotion.ops.retarget.problem.LM_DAMPING_UPDATE`;
            ``benchmarks/retarget_contacts.py --damping`` sets it to compare).
        shards: LM only: CPU devices each chunk's frames are split over, in lockstep
            (default :func:`usdmotion.ops.retarget.jax_runtime.frame_shards`: all of them on
            a CPU, 1 on an accelerator); the result is the one-device result up to float32
            rounding.

    LM solves every chunk of consecutive frames in one compiled call; the temporal term
    (``problem.smooth``) links neighbouring frames inside a chunk (not across chunks).
    """
    use_cpu_cores()  # before JAX's first computation in this process, if this is it
    import jax

    if method not in ("lm", "adam"):
        raise ValueError(f"unknown method {method!r}")
    damping = damping or DAMPING
    if damping not in LM_DAMPING_UPDATES:
        raise ValueError(f"unknown damping update {damping!r}")
    full_q0, full_t0 = q0, t0
    problem, keep = needed_joints(problem)  # joints that move no residual point: not computed at all
    q0, t0 = q0[:, keep], t0[:, keep]
    extra = len(problem.contact_joints) or len(problem.floor_joints) or problem.smoothing or problem.anchored
    if method == "adam" and extra:
        raise ValueError("the contact, floor and temporal terms need method 'lm'")
    n_near = len(problem.mapped) + len(problem.contact_joints)
    if weights is None:
        weights = np.broadcast_to(problem.point_weights(), (q0.shape[0], n_near))
    if targets.shape[1] < n_near:
        targets = np.concatenate([targets, np.zeros((targets.shape[0], n_near - targets.shape[1], 3))], axis=1)
    floor = np.zeros(q0.shape[0]) if floor is None else np.asarray(floor, np.float64)
    iterations = int(iterations if iterations is not None else (LM_ITERATIONS if method == "lm" else ADAM_ITERATIONS))
    n_frames = q0.shape[0]
    chunk = chunk or chunk_plan(n_frames, problem)[0]
    shards = 1 if method != "lm" else shards or frame_shards(chunk)
    chunk = -(-chunk // shards) * shards
    place = frame_blocks(shards)
    theta0 = None
    if method == "adam":
        theta0 = np.zeros(q0.shape[:1] + (len(problem.rot_joints), 3))
        for k, (j, order) in enumerate(zip(problem.rot_joints, problem.orders)):
            theta0[:, k] = quat_to_euler(q0[:, j], order)
    outs, compile_s, run_s, calls, ran = [], 0.0, 0.0, 0, 0
    for start in range(0, n_frames, chunk):
        stop = min(start + chunk, n_frames)
        pad = np.r_[np.arange(start, stop), np.full(chunk - (stop - start), stop - 1)]
        # float32 in NumPy, then one transfer (a JAX conversion would dispatch an op and copy twice)
        args = [np.asarray(a[pad], np.float32) for a in (q0, t0, targets)]
        if theta0 is not None:
            args.append(np.asarray(theta0[pad], np.float32))
        else:
            inner = np.zeros(chunk, np.float32)  # frames with two real neighbours in this chunk
            inner[1: stop - start - 1] = 1.0
            args += [np.asarray(weights[pad], np.float32), np.asarray(floor[pad], np.float32), inner,
                     np.int32(iterations)]
            args = place(args)
        fn, seconds = _executable(problem, method, iterations, float(lr), args, damping, shards)
        compile_s += seconds
        began = time.perf_counter()
        result = jax.block_until_ready(fn(*args))
        run_s += time.perf_counter() - began
        outs.append([np.asarray(x, np.float64)[: stop - start] for x in result[:4]])
        ran = max(ran, int(result[4]))
        calls += 1
        if progress is not None:
            progress(stop, n_frames, "retargeting")
    q_kept, t_kept, loss, initial = (np.concatenate(parts) for parts in zip(*outs))
    q, t = np.array(full_q0, np.float64), np.array(full_t0, np.float64)
    q[:, keep], t[:, keep] = q_kept, t_kept
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Solution(q, t, loss, initial, compile_s, run_s, chunk, calls, ran)


def needed_joints(problem: Problem) -> tuple[Problem, np.ndarray]:
    """``(problem on the needed joints, keep (J,) bool)``: the joints whose world transform
    the solve uses — every residual point's joint, every optimised joint and all their
    ancestors — with the problem's joint indices renumbered onto them (parents still
    before children). Large rigs carry many joints no mapped point hangs from (DAZ's and
    Rokoko's fingers, face and twist bones: 57 → 25 and 73 → 29 joints); their rotations
    and translations come back unchanged, so forward kinematics inside the solve skips them."""
    used = np.concatenate([problem.points, problem.rot_joints, problem.trans_joints])
    joints = with_ancestors(problem.parents, used)
    keep = np.zeros(len(problem.parents), bool)
    keep[joints] = True
    if keep.all():
        return problem, keep
    renumber = lambda j: np.searchsorted(joints, np.asarray(j, np.int64))  # noqa: E731
    return replace(
        problem, parents=restricted_parents(problem.parents, joints), mapped=renumber(problem.mapped),
        rot_joints=renumber(problem.rot_joints), trans_joints=renumber(problem.trans_joints),
        contact_joints=renumber(problem.contact_joints), floor_joints=renumber(problem.floor_joints)), keep

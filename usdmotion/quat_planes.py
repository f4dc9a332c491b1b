"""Fast NumPy quaternion kernels on component planes, for the editing operations and analysis.

The core :mod:`usdmotion.rotations` functions work on ``(..., 4)`` arrays for NumPy and
JAX alike; on ``(10_000, 38, 4)`` arrays their strided component access costs 2-4x more
than needed. These kernels take **component-first** arrays ``(4, ...)`` (contiguous
w, x, y, z planes; same wxyz convention and Hamilton product as ``rotations``) and are
used inside the hot paths of :mod:`usdmotion.ops.edit` and by :mod:`usdmotion.ops.analyse.measures`
(sign continuity). Convert with :func:`to_c` / :func:`from_c` once per operation.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from usdmotion import parallel
from usdmotion.constants import tol


def to_c(q: np.ndarray) -> np.ndarray:
    """``(..., 4)`` wxyz → contiguous component-first ``(4, ...)``."""
    return np.ascontiguousarray(np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0))


def gather_c(q: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Component-first ``(4, F, S)`` copy of ``q[:, joints]`` for ``q (F, J, 4)`` (one pass)."""
    return np.moveaxis(q, -1, 0)[:, :, joints]


def scatter_c(out: np.ndarray, joints: np.ndarray, qc: np.ndarray) -> None:
    """``out[:, joints] = qc`` for ``out (F, J, 4)`` and component-first ``qc (4, F, S)`` (in place)."""
    np.moveaxis(out, -1, 0)[:, :, joints] = qc


def from_c(qc: np.ndarray) -> np.ndarray:
    """Component-first ``(4, ...)`` → contiguous ``(..., 4)``."""
    return np.ascontiguousarray(np.moveaxis(qc, 0, -1))


def mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of component-first quaternions (broadcasting).

    :func:`usdmotion.rotations.hamilton`'s operations in the same order (so the same bits),
    written into one preallocated array with ``out=`` and in-place updates: calling it and
    stacking would allocate the twelve products and copy the result once more, on the
    editing operations' hot paths. (``hamilton`` cannot write in place: JAX arrays, traced
    by forward kinematics, allow no ``out=``.)
    """
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    out = np.empty((4,) + np.broadcast_shapes(aw.shape, bw.shape))
    w, x, y, z = out  # written in place: no stacking copy
    np.multiply(aw, bw, out=w)
    w -= ax * bx
    w -= ay * by
    w -= az * bz
    np.multiply(aw, bx, out=x)
    x += ax * bw
    x += ay * bz
    x -= az * by
    np.multiply(aw, by, out=y)
    y -= ax * bz
    y += ay * bw
    y += az * bx
    np.multiply(aw, bz, out=z)
    z += ax * by
    z -= ay * bx
    z += az * bw
    return out


def conj(q: np.ndarray) -> np.ndarray:
    """Inverse of unit component-first quaternions."""
    out = -q
    out[0] = q[0]
    return out


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit-norm copies of component-first quaternions."""
    return q / np.sqrt(np.einsum("i...,i...->...", q, q))


def align_signs(q: np.ndarray, axis: int = 1) -> np.ndarray:
    """Flip signs along ``axis`` (time) so consecutive quaternions have a non-negative dot.

    Makes the 4-vector signal continuous (``q`` and ``-q`` are the same rotation);
    the first sample keeps its sign.
    """
    n = q.shape[axis]
    if n < 2:
        return q.copy()
    head = (slice(None),) * axis + (slice(1, None),)
    tail = (slice(None),) * axis + (slice(None, -1),)
    flips = np.einsum("i...,i...->...", q[head], q[tail]) < 0.0
    if not flips.any():
        return q.copy()
    parity = np.cumsum(flips, axis=axis - 1, dtype=np.int8) & 1  # int8 wraps, parity survives
    out = q.copy()
    flip = np.concatenate([np.zeros_like(parity[(slice(None),) * (axis - 1) + (slice(0, 1),)]), parity],
                          axis=axis - 1).astype(bool)
    out[:, flip] *= -1.0
    return out


def log(q: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(3, ...)`` of component-first unit quaternions, **unwrapped**.

    Unlike :func:`usdmotion.rotations.quat_log` the sign is not canonicalised: the angle
    is ``2·atan2(‖v‖, w)`` in ``[0, 2π]``, so a sign-continuous quaternion signal (see
    :func:`align_signs`) gives a continuous rotation-vector signal through ±180°.
    ``exp(log(q)) == q`` (same sign).
    """
    w = q[0]
    v = q[1:]
    n = np.sqrt(np.einsum("i...,i...->...", v, v))
    angle = 2.0 * np.arctan2(n, w)
    small = n < tol.small_angle
    scale = np.divide(angle, n, out=np.zeros_like(n), where=~small)
    # near the identity (w ≈ ±1): atan2(n, w)·2/n → 2/w
    scale = np.where(small, 2.0 / np.where(w < 0, np.minimum(w, -0.5), np.maximum(w, 0.5)), scale)
    return v * scale[None]


def exp(v: np.ndarray) -> np.ndarray:
    """Component-first quaternions ``(4, ...)`` of rotation vectors ``(3, ...)``."""
    theta = np.sqrt(np.einsum("i...,i...->...", v, v))
    half = 0.5 * theta
    small = theta < tol.small_angle
    scale = np.divide(np.sin(half), theta, out=np.full_like(theta, 0.5), where=~small)
    out = np.empty((4,) + theta.shape)
    out[0] = np.cos(half)
    out[1:] = v * scale[None]
    return out


def slerp(a: np.ndarray, b: np.ndarray, t) -> np.ndarray:
    """Spherical interpolation (short path) between component-first ``a`` and ``b`` at ``t``.

    ``t`` broadcasts against ``a[0]``; returns unit quaternions in ``a``'s hemisphere.
    """
    t = np.asarray(t, dtype=np.float64)
    dot = np.einsum("i...,i...->...", a, b)
    b = np.where(dot < 0.0, -b, b)
    dot = np.abs(dot)
    omega = np.arccos(np.minimum(dot, 1.0))
    sin_omega = np.sin(omega)
    near = sin_omega < 1e-6
    safe = np.where(near, 1.0, sin_omega)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * omega) / safe)
    wb = np.where(near, t, np.sin(t * omega) / safe)
    out = wa[None] * a + wb[None] * b
    return normalize(out) if np.any(near) else out


def nlerp(a: np.ndarray, b: np.ndarray, t) -> np.ndarray:
    """Normalised linear interpolation (short path) of component-first quaternions."""
    t = np.asarray(t, dtype=np.float64)
    dot = np.einsum("i...,i...->...", a, b)
    sign = np.where(dot < 0.0, -1.0, 1.0)
    return normalize((1.0 - t)[None] * a + (t * sign)[None] * b)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``(3, ...)`` by component-first unit quaternions ``(4, ...)``."""
    w, u = q[0], q[1:]
    t = 2.0 * np.cross(u, v, axis=0)
    return v + w[None] * t + np.cross(u, t, axis=0)


def over_chunks(work: Callable[[np.ndarray], None], joints: np.ndarray, n_frames: int,
                min_elements: int = 200_000) -> None:
    """Run ``work(joint_indices)`` on a few chunks of ``joints`` in threads.

    NumPy releases the GIL inside its array loops, so per-joint-chunk work on large
    motions uses every core; small inputs run in one call. ``work`` must write disjoint
    parts of its output.
    """
    workers = min(4, parallel.workers(), len(joints), max(1, (len(joints) * n_frames) // min_elements))
    if workers <= 1:
        work(joints)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        list(pool.map(work, np.array_split(joints, workers)))

"""Quaternion and Euler-angle conversions, shared by NumPy and ``jax.numpy`` code.

Conventions (everywhere in usdmotion):

* Quaternions are ``(..., 4)`` arrays in **wxyz** order (real part first), unit norm.
  Helpers named ``*_xyzw`` convert at the boundaries (USD's ``Vt.QuatfArray.FromNumpy``
  and SciPy use xyzw).
* Rotations act on column vectors: ``v_parent = R @ v_child``; ``quat_mul(a, b)`` is the
  rotation ``R_a @ R_b`` (apply ``b`` first).
* Euler angles are **intrinsic** in the given ``order`` as BVH writes them: the channel
  line ``Zrotation Xrotation Yrotation`` means ``R = Rz(z) @ Rx(x) @ Ry(y)``, order
  ``"ZXY"`` and ``angles[..., 0]`` is the Z angle. Angles are radians unless a name says
  ``deg``.

Functions take NumPy arrays or JAX arrays and return the same kind, so forward
kinematics and the retargeting loss share one implementation. ``quat_to_euler`` is
NumPy-only (it is used when writing files, never inside an optimiser).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from usdmotion.constants import tol

AXES = "XYZ"
EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


def array_namespace(*arrays: Any):
    """Return ``jax.numpy`` if any argument is a JAX array (or tracer), else ``numpy``."""
    for a in arrays:
        if type(a).__module__.startswith(("jax", "jaxlib")):
            import jax.numpy as jnp

            return jnp
    return np


def check_euler_order(order: str) -> str:
    """Validate an Euler order such as ``"ZXY"``; raises ``ValueError`` if malformed."""
    if not isinstance(order, str) or order.upper() not in EULER_ORDERS:
        raise ValueError(f"Euler order must be one of {', '.join(EULER_ORDERS)}, got {order!r}")
    return order.upper()


def hamilton(a, b) -> tuple:
    """Hamilton product ``a * b`` of quaternions given as their four components ``(w, x, y, z)``
    (each an array, broadcasting; NumPy or JAX). The one product formula of the package:
    :func:`quat_mul` (wxyz-last arrays) and forward kinematics (component planes, traced
    under ``jax.jit``) call it; :func:`usdmotion.quat_planes.mul` writes the same operations,
    in the same order, into one preallocated NumPy array.
    """
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def quat_mul(a, b):
    """Hamilton product ``a * b`` of wxyz quaternions ``(..., 4)`` (broadcasting)."""
    xp = array_namespace(a, b)
    return xp.stack(hamilton([a[..., k] for k in range(4)], [b[..., k] for k in range(4)]), axis=-1)


def quat_conjugate(q):
    """Inverse of a unit quaternion ``(..., 4)``."""
    xp = array_namespace(q)
    return q * xp.asarray([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def cross(a, b):
    """Cross products of 3-vectors ``(..., 3)`` (broadcasting): ``np.cross``'s values, bit for
    bit. NumPy's own spends most of its time on axis bookkeeping for the small arrays of a
    take (34 against 15 µs for 523 vectors); JAX arrays go to ``jnp.cross``."""
    xp = array_namespace(a, b)
    if xp is not np:
        return xp.cross(a, b)
    a, b = np.asarray(a), np.asarray(b)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.result_type(a, b))
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(ay * bz, az * by, out=out[..., 0])
    np.subtract(az * bx, ax * bz, out=out[..., 1])
    np.subtract(ax * by, ay * bx, out=out[..., 2])
    return out


def quat_rotate(q, v):
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)`` (broadcasting)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def quat_normalize(q):
    """Scale quaternions ``(..., 4)`` to unit norm."""
    xp = array_namespace(q)
    return q / xp.linalg.norm(q, axis=-1, keepdims=True)


def quat_canonical(q):
    """Sign-flip quaternions ``(..., 4)`` so that ``w >= 0`` (same rotation)."""
    xp = array_namespace(q)
    return xp.where(q[..., :1] < 0, -q, q)


def quat_to_matrix(q):
    """Rotation matrices ``(..., 3, 3)`` of unit wxyz quaternions ``(..., 4)``."""
    xp = array_namespace(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    rows = [
        xp.stack([1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)], axis=-1),
        xp.stack([2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)], axis=-1),
        xp.stack([2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)], axis=-1),
    ]
    return xp.stack(rows, axis=-2)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit wxyz quaternions ``(..., 4)`` of rotation matrices ``(..., 3, 3)`` (NumPy).

    Uses SciPy's robust (Markley) conversion; nearly-orthogonal input is projected.
    """
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=np.float64)
    flat = Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    return flat.reshape(m.shape[:-2] + (4,))


def wxyz_to_xyzw(q):
    """Reorder ``(..., 4)`` quaternions from wxyz to xyzw."""
    return q[..., [1, 2, 3, 0]]


def xyzw_to_wxyz(q):
    """Reorder ``(..., 4)`` quaternions from xyzw to wxyz."""
    return q[..., [3, 0, 1, 2]]


def axis_angle_quat(axis: str, angle):
    """Quaternions ``(..., 4)`` of rotations by ``angle (...)`` radians about ``"X"|"Y"|"Z"``."""
    xp = array_namespace(angle)
    half = 0.5 * angle
    c, s = xp.cos(half), xp.sin(half)
    zero = xp.zeros_like(half)
    parts = [c, zero, zero, zero]
    parts[1 + AXES.index(axis)] = s
    return xp.stack(parts, axis=-1)


def euler_to_quat(angles, order: str):
    """Quaternions ``(..., 4)`` of intrinsic Euler ``angles (..., 3)`` in radians.

    ``order="ZXY"`` means ``R = Rz(angles[..., 0]) @ Rx(angles[..., 1]) @ Ry(angles[..., 2])``.
    """
    xp = array_namespace(angles)
    half = 0.5 * xp.moveaxis(angles, -1, 0)
    return half_angles_to_quat(half[0], half[1], half[2], order)


def half_angles_to_quat(h1, h2, h3, order: str):
    """Quaternions ``(..., 4)`` from the three *half* Euler angles as separate arrays ``(...)``.

    Closed form of ``(c1 + s1 e_i)(c2 + s2 e_j)(c3 + s3 e_k)`` with ``e_i e_j = σ e_k``; the
    plane-per-axis inputs let callers (the BVH reader) skip a transpose.
    """
    order = check_euler_order(order)
    xp = array_namespace(h1, h2, h3)
    i, j, k = (AXES.index(a) for a in order)
    sigma = 1.0 if (j - i) % 3 == 1 else -1.0
    c1, c2, c3 = xp.cos(h1), xp.cos(h2), xp.cos(h3)
    s1, s2, s3 = xp.sin(h1), xp.sin(h2), xp.sin(h3)
    c1c2, s1s2, c1s2, s1c2 = c1 * c2, s1 * s2, c1 * s2, s1 * c2
    parts = [None, None, None, None]
    parts[0] = c1c2 * c3 - sigma * (s1s2 * s3)
    parts[1 + i] = s1c2 * c3 + sigma * (c1s2 * s3)
    parts[1 + j] = c1s2 * c3 - sigma * (s1c2 * s3)
    parts[1 + k] = c1c2 * s3 + sigma * (s1s2 * c3)
    return xp.stack(parts, axis=-1)


def quat_to_euler(q: np.ndarray, order: str, reference: np.ndarray | None = None) -> np.ndarray:
    """Intrinsic Euler angles ``(..., 3)`` in radians of wxyz quaternions ``(..., 4)``.

    Every rotation has two Euler triples (``(a, b, c)`` and ``(a+π, π-b, c+π)``), each
    defined up to multiples of 2π. With ``reference`` (same shape as the result), the
    equivalent triple closest to it is returned, so angles beyond ±180° or the
    alternative triple written by a capture program survive a round trip. Without it,
    SciPy's principal triple is unwrapped along axis 0 (time) for continuity.
    """
    from scipy.spatial.transform import Rotation

    order = check_euler_order(order)
    q = np.asarray(q, dtype=np.float64)
    flat = q.reshape(-1, 4)
    import warnings

    with warnings.catch_warnings():  # gimbal lock is handled by the reference choice
        warnings.simplefilter("ignore", UserWarning)
        principal = Rotation.from_quat(flat, scalar_first=True).as_euler(order, degrees=False)
    principal = principal.reshape(q.shape[:-1] + (3,))
    if reference is None:
        return np.unwrap(principal, axis=0) if principal.ndim >= 2 else principal
    reference = np.broadcast_to(np.asarray(reference, dtype=np.float64), principal.shape)
    return closest_equivalent_euler(principal, reference)


def closest_equivalent_euler(angles: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Among the Euler triples equivalent to ``angles (..., 3)``, the one nearest ``reference``."""
    two_pi = 2.0 * np.pi
    alternative = angles + np.array([np.pi, 0.0, np.pi])
    alternative[..., 1] = np.pi - angles[..., 1]
    best = None
    best_cost = None
    for candidate in (angles, alternative):
        shifted = candidate + two_pi * np.round((reference - candidate) / two_pi)
        cost = np.sum((shifted - reference) ** 2, axis=-1)
        if best is None:
            best, best_cost = shifted, cost
        else:
            take = cost < best_cost
            best = np.where(take[..., None], shifted, best)
    return best


def _safe_norm(v, xp):
    """Return ``(‖v‖, mask_small)`` with a gradient that is finite at ``v = 0``."""
    sq = xp.sum(v * v, axis=-1)
    small = sq < tol.small_angle**2
    return xp.where(small, 0.0, xp.sqrt(xp.where(small, 1.0, sq))), small


def quat_exp(rotvec):
    """Quaternions ``(..., 4)`` of rotation vectors ``(..., 3)`` (axis × angle, radians).

    Grad-safe at zero (Taylor branch selected with the safe-``where`` trick).
    """
    xp = array_namespace(rotvec)
    angle, small = _safe_norm(rotvec, xp)
    half = 0.5 * angle
    safe_angle = xp.where(small, 1.0, angle)
    scale = xp.where(small, 0.5 - angle * angle / 48.0, xp.sin(half) / safe_angle)
    return xp.concatenate([xp.cos(half)[..., None], scale[..., None] * rotvec], axis=-1)


def quat_log(q):
    """Rotation vectors ``(..., 3)`` (axis × angle, angle in [0, π]) of unit quaternions."""
    xp = array_namespace(q)
    q = quat_canonical(q)
    w = xp.clip(q[..., 0], -1.0, 1.0)
    v = q[..., 1:]
    sin_half, small = _safe_norm(v, xp)
    angle = 2.0 * xp.arctan2(sin_half, w)
    safe_sin = xp.where(small, 1.0, sin_half)
    scale = xp.where(small, 2.0 / xp.where(small, w, 1.0), angle / safe_sin)
    return scale[..., None] * v


def quat_slerp(a, b, t):
    """Spherical interpolation from ``a`` to ``b`` (``(..., 4)``) at ``t (...)`` in [0, 1].

    Takes the short path (``b`` is sign-flipped where ``a·b < 0``).
    """
    xp = array_namespace(a, b, t)
    dot = xp.sum(a * b, axis=-1, keepdims=True)
    b = xp.where(dot < 0, -b, b)
    delta = quat_log(quat_mul(quat_conjugate(a), b))
    t = xp.asarray(t)[..., None]
    return quat_normalize(quat_mul(a, quat_exp(t * delta)))


def quat_between(u, v):
    """Shortest-arc quaternions ``(..., 4)`` rotating directions ``u`` onto ``v`` (``(..., 3)``).

    Opposite vectors get a 180° turn about an axis perpendicular to ``u``.
    """
    xp = array_namespace(u, v)
    u = u / xp.linalg.norm(u, axis=-1, keepdims=True)
    v = v / xp.linalg.norm(v, axis=-1, keepdims=True)
    w = 1.0 + xp.sum(u * v, axis=-1, keepdims=True)
    axis = cross(u, v)
    # opposite: pick any axis perpendicular to u
    helper = xp.where(xp.abs(u[..., :1]) < 0.9, xp.asarray([1.0, 0.0, 0.0]), xp.asarray([0.0, 1.0, 0.0]))
    perp = cross(u, helper)
    perp = perp / xp.linalg.norm(perp, axis=-1, keepdims=True)
    opposite = w < 1e-9
    q = xp.where(opposite, xp.concatenate([xp.zeros_like(w), perp], axis=-1), xp.concatenate([w, axis], axis=-1))
    return quat_normalize(q)

"""Time: sampling at fractional frames, speed curves, resampling to another fps, trimming.

Rotations are interpolated as rotations: ``interp="linear"`` is per-frame slerp (the
geodesic between neighbouring frames, translations linear); ``interp="cubic"`` (default)
is an interpolating cubic B-spline (SciPy ``make_interp_spline``, C²) through the
sign-continuous quaternions, renormalised, and through the translations, so a slowed-down
motion has no velocity kinks at the original frames.
"""

from __future__ import annotations

import math

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.motion import Motion
from usdmotion.ops.edit._common import (EditError, animated_translation_joints, check_result_frames, frame_range, rebuild,
                                        select_joints)

INTERPOLATIONS = ("cubic", "linear")


def _check_interp(interp: str) -> None:
    if interp not in INTERPOLATIONS:
        raise EditError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got {interp!r}")


def sample_rotations(rotations: np.ndarray, tau: np.ndarray, interp: str = "cubic") -> np.ndarray:
    """Rotations ``(F, S, 4)`` sampled at fractional frames ``tau (M,)`` → ``(M, S, 4)``."""
    _check_interp(interp)
    n = rotations.shape[0]
    tau = np.clip(np.asarray(tau, dtype=np.float64), 0.0, n - 1)
    if n == 1 or rotations.shape[1] == 0:
        return np.repeat(rotations[:1], len(tau), axis=0) if n == 1 else rotations[np.zeros(len(tau), int)]
    whole = tau == np.round(tau)
    if whole.all():
        return np.ascontiguousarray(rotations[tau.astype(np.int64)])
    out = np.empty((len(tau),) + rotations.shape[1:])

    def work(chunk: np.ndarray) -> None:
        q = Q.align_signs(Q.gather_c(rotations, chunk), axis=1)
        if interp == "cubic" and n >= 4:
            from scipy.interpolate import make_interp_spline

            spline = make_interp_spline(np.arange(n, dtype=np.float64), np.moveaxis(q, 1, 0), k=3, axis=0)
            Q.scatter_c(out, chunk, Q.normalize(np.moveaxis(spline(tau), 0, 1)))
        else:
            i0 = np.minimum(np.floor(tau).astype(np.int64), n - 2)
            Q.scatter_c(out, chunk, Q.slerp(q[:, i0], q[:, i0 + 1], (tau - i0)[:, None]))

    Q.over_chunks(work, np.arange(rotations.shape[1]), max(n, len(tau)))
    return out


def sample_values(values: np.ndarray, tau: np.ndarray, interp: str = "cubic") -> np.ndarray:
    """Per-frame values ``(F, ...)`` (translations) sampled at fractional frames ``tau``."""
    _check_interp(interp)
    n = values.shape[0]
    tau = np.clip(np.asarray(tau, dtype=np.float64), 0.0, n - 1)
    if n == 1:
        return np.repeat(values[:1], len(tau), axis=0)
    if (tau == np.round(tau)).all():
        return np.ascontiguousarray(values[tau.astype(np.int64)])
    if interp == "cubic" and n >= 4:
        from scipy.interpolate import make_interp_spline

        return make_interp_spline(np.arange(n, dtype=np.float64), values, k=3, axis=0)(tau)
    i0 = np.minimum(np.floor(tau).astype(np.int64), n - 2)
    t = (tau - i0).reshape((-1,) + (1,) * (values.ndim - 1))
    return values[i0] * (1.0 - t) + values[i0 + 1] * t


def sample_motion(motion: Motion, tau: np.ndarray, interp: str = "cubic",
                  joints: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(rotations, root_translation, joint_translations)`` of ``motion`` at frames ``tau``.

    ``joints``: mask of joints to sample (others are copied from frame 0; cheaper when
    only a subtree is needed). End sites are never interpolated.
    """
    tau = np.clip(np.asarray(tau, dtype=np.float64), 0.0, motion.n_frames - 1)
    if np.all(tau == np.round(tau)):  # whole frames: one gather
        frames = tau.astype(np.int64)
        jt = None if motion.joint_translations is None else motion.joint_translations[frames]
        return motion.rotations[frames], motion.root_translation[frames], jt
    mask = ~motion.end_sites if joints is None else (joints & ~motion.end_sites)
    idx = np.flatnonzero(mask)
    rotations = np.repeat(motion.rotations[:1], len(tau), axis=0)
    rotations[:, idx] = sample_rotations(motion.rotations[:, idx], tau, interp)
    root = sample_values(motion.root_translation, tau, interp)
    jt = None
    if motion.joint_translations is not None:
        jt = np.repeat(motion.joint_translations[:1], len(tau), axis=0)
        moving = np.flatnonzero(animated_translation_joints(motion) & mask)
        if moving.size:
            jt[:, moving] = sample_values(motion.joint_translations[:, moving], tau, interp)
    return rotations, root, jt


def speed_times(n_frames: int, factor: float | None = None, keys=None, n_joints: int = 1) -> np.ndarray:
    """Source frames ``τ_k`` of the output frames for a speed curve ``s(τ)``.

    The next output frame is ``s`` source frames after the previous one
    (``dτ/dk = s(τ)``): ``s = 2`` plays twice as fast. ``keys``: ``[(source_frame, s), ...]``
    joined by a monotone cubic (PCHIP, so ``s`` stays within the keyed values and positive),
    constant before the first and after the last key.
    """
    if (factor is None) == (keys is None):
        raise EditError("speed needs exactly one of a constant factor or speed keys")
    last = float(n_frames - 1)
    if factor is not None:
        s = _positive(factor, "speed")
        count = int(math.floor(last / s + 1e-9)) + 1
        check_result_frames(count, n_joints, f"speed {s:g}")
        return np.minimum(np.arange(count) * s, last)
    frames, speeds = _speed_keys(keys, n_frames)
    if len(frames) == 1:
        return speed_times(n_frames, factor=speeds[0], n_joints=n_joints)
    from scipy.integrate import cumulative_trapezoid
    from scipy.interpolate import PchipInterpolator

    curve = PchipInterpolator(frames, speeds, extrapolate=False)
    grid = np.linspace(0.0, last, max(2, 8 * n_frames))  # 8 samples per frame: trapezoid error ≪ 1e-3 frame
    s = curve(np.clip(grid, frames[0], frames[-1]))
    elapsed = cumulative_trapezoid(1.0 / s, grid, initial=0.0)  # output frames k(τ)
    count = int(math.floor(elapsed[-1] + 1e-9)) + 1
    check_result_frames(count, n_joints, "the speed keys")
    return np.interp(np.arange(count, dtype=np.float64), elapsed, grid)


def _positive(value, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise EditError(f"{what} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise EditError(f"{what} must be a positive number, got {value!r}")
    return v


def _speed_keys(keys, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    try:
        pairs = [(float(f), _positive(s, "speed key value")) for f, s in keys]
    except (TypeError, ValueError) as exc:
        if isinstance(exc, EditError):
            raise
        raise EditError(f"speed keys must be (frame, speed) pairs, got {keys!r}") from None
    if not pairs:
        raise EditError("speed keys: need at least one (frame, speed) pair")
    frames = np.array([p[0] for p in pairs])
    if np.any(~np.isfinite(frames)) or np.any(frames < 0) or np.any(frames > n_frames - 1):
        raise EditError(f"speed key frames must lie in 0..{n_frames - 1}, got {frames.tolist()}")
    if np.any(np.diff(frames) <= 0):
        raise EditError(f"speed key frames must increase strictly, got {frames.tolist()}")
    return frames, np.array([p[1] for p in pairs])


def speed(motion: Motion, factor: float | None = None, keys=None, joint: str | None = None,
          subtree: bool = False, interp: str = "cubic") -> Motion:
    """Time-warp by a speed curve (see :func:`speed_times`); the fps stays.

    Whole body: the frame count changes (``s = 2`` halves it). With ``joint``: only that
    joint (or subtree) is warped, the frame count stays and the warped joints hold their
    last pose once their time runs out.
    """
    _check_interp(interp)
    tau = speed_times(motion.n_frames, factor, keys, motion.n_joints)
    if joint is None:
        rotations, root, jt = sample_motion(motion, tau, interp)
        return rebuild(motion, rotations, root, jt, frame_times=tau)
    mask = select_joints(motion, joint, subtree)
    n = motion.n_frames
    tau = np.concatenate([tau, np.full(max(0, n - len(tau)), float(n - 1))])[:n]
    rotations, root, jt = sample_motion(motion, tau, interp, joints=mask)
    out_rot = np.array(motion.rotations)
    out_rot[:, mask] = rotations[:, mask]
    out_root = root if mask[0] else np.array(motion.root_translation)
    out_jt = None if jt is None else np.array(motion.joint_translations)
    if jt is not None:
        out_jt[:, mask] = jt[:, mask]
    return rebuild(motion, out_rot, out_root, out_jt)


def resample(motion: Motion, fps: float, interp: str = "cubic") -> Motion:
    """The same motion (same duration) sampled at another frame rate."""
    _check_interp(interp)
    fps = _positive(fps, "fps")
    count = int(math.floor(motion.duration * fps + 1e-6)) + 1
    check_result_frames(count, motion.n_joints, f"resampling to {fps:g} fps")
    tau = np.minimum(np.arange(count) * (motion.fps / fps), motion.n_frames - 1)
    rotations, root, jt = sample_motion(motion, tau, interp)
    return rebuild(motion, rotations, root, jt, fps=fps, frame_times=tau)


def trim(motion: Motion, start: int | None = None, stop: int | None = None) -> Motion:
    """Frames ``[start, stop)`` (negative numbers count from the end); keeps the Euler hint."""
    lo, hi = frame_range(motion, start, stop, "trim range")
    return motion.sliced(lo, hi)

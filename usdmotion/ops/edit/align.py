"""Timing alignment for blending: peak matching (MotionLab) and dynamic time warping."""

from __future__ import annotations

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.ops.edit._common import EditError

CHANNELS = ("auto", "rx", "ry", "rz")


def rotation_channels(rot0: np.ndarray, rot1: np.ndarray, channel: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Scalar signals of one joint's rotations ``(F0, 4)``, ``(F1, 4)`` in a shared chart.

    Both are expressed as rotation vectors relative to the first motion's mean rotation;
    ``rx``/``ry``/``rz`` take a component, ``auto`` the projection on the first motion's
    principal axis (for a thigh: flexion/extension), with one sign for both.
    """
    if channel not in CHANNELS:
        raise EditError(f"alignment channel must be one of {', '.join(CHANNELS)}, got {channel!r}")
    q0 = Q.align_signs(Q.to_c(rot0), axis=1)
    mean = Q.normalize(q0.mean(axis=1, keepdims=True))
    inv = Q.conj(mean)

    def chart(rot: np.ndarray) -> np.ndarray:
        q = Q.to_c(rot)
        rel = Q.mul(inv, q)
        rel = np.where(rel[:1] < 0, -rel, rel)  # within π of the mean
        return Q.log(rel).T  # (F, 3)

    d0, d1 = chart(rot0), chart(rot1)
    if channel != "auto":
        axis = "xyz".index(channel[1])
        return d0[:, axis], d1[:, axis]
    centred = d0 - d0.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axis = vt[0]
    axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    return d0 @ axis, d1 @ axis


def peaks(signal: np.ndarray, prominence: float = 0.25) -> np.ndarray:
    """Frames of the local maxima of ``signal`` whose prominence is at least
    ``prominence × (max − min)`` (SciPy ``find_peaks``)."""
    from scipy.signal import find_peaks

    span = float(np.ptp(signal)) if signal.size else 0.0
    if span <= 0:
        return np.zeros(0, dtype=np.int64)
    found, _ = find_peaks(signal, prominence=prominence * span)
    return found.astype(np.int64)


def peak_offset(s0: np.ndarray, s1: np.ndarray, at: int, transition: int) -> int:
    """Where the second motion's frame 0 goes on the first's timeline (MotionLab's rule).

    The last peak of ``s0`` at or before the middle of the transition is put onto the
    first peak of ``s1`` that lets the second motion start by the transition's start.
    """
    p0 = peaks(s0)
    p1 = peaks(s1)
    if p0.size == 0 or p1.size == 0:
        which = "first" if p0.size == 0 else "second"
        raise EditError(f"peak alignment: the {which} motion's channel has no clear peak; "
                        "choose another joint or channel, or align 'none'")
    middle = at + transition / 2.0
    before = p0[p0 <= middle]
    anchor = int(before[-1] if before.size else p0[0])
    usable = p1[p1 >= anchor - at]
    if usable.size == 0:
        raise EditError(f"peak alignment: no peak of the second motion at or after frame {anchor - at} "
                        "(it would have to start after the transition begins)")
    return anchor - int(usable[0])


def subsequence_dtw(cost: np.ndarray) -> np.ndarray:
    """Dynamic time warping of every row of ``cost (N, M)`` onto a stretch of its columns.

    Open begin and end on the column side (the query, rows, is matched completely);
    steps (1,1), (1,0), (0,1). Returns the path as ``(K, 2)`` int pairs ``(i, j)``.
    Each row is solved at once: ``D[i, j] = c[i, j] + min(a_j, D[i, j−1])`` with
    ``a_j = min(D[i−1, j−1], D[i−1, j])`` unrolls to a running minimum of
    ``a_k − S_{k−1}`` plus the prefix sum ``S_j`` of the row.
    """
    cost = np.asarray(cost, dtype=np.float64)
    n, m = cost.shape
    acc = np.empty((n, m))
    acc[0] = cost[0]
    for i in range(1, n):  # rows only; each row is vectorised
        prev = acc[i - 1]
        a = np.minimum(prev, np.concatenate([[np.inf], prev[:-1]]))
        s = np.cumsum(cost[i])
        s_before = np.concatenate([[0.0], s[:-1]])
        acc[i] = s + np.minimum.accumulate(a - s_before)
    i, j = n - 1, int(np.argmin(acc[-1]))
    path = [(i, j)]
    while i > 0:  # backtrack: at most N + M steps
        options = [(acc[i - 1, j - 1] if j > 0 else np.inf, i - 1, j - 1), (acc[i - 1, j], i - 1, j),
                   (acc[i, j - 1] if j > 0 else np.inf, i, j - 1)]
        _, i, j = min(options)
        path.append((i, j))
    return np.array(path[::-1], dtype=np.int64)


def warp_from_path(path: np.ndarray, n: int) -> np.ndarray:
    """Monotone, lightly smoothed column position ``(n,)`` for each row of a DTW path."""
    sums = np.bincount(path[:, 0], weights=path[:, 1], minlength=n)
    counts = np.bincount(path[:, 0], minlength=n)
    w = sums / np.maximum(counts, 1)
    if n >= 5:
        padded = np.pad(w, 2, mode="reflect")
        w = np.convolve(padded, np.ones(5) / 5.0, mode="valid")
    return np.maximum.accumulate(w)

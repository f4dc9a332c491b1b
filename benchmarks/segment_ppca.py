"""PPCA segmentation baseline (Barbič, Safonova, Pan, Faloutsos, Hodgins, Pollard: "Segmenting
Motion Capture Data into Distinct Behaviors", Graphics Interface 2004, §3.2), for
``benchmarks/segment.py``. A baseline to compare with, not a shipped method.

As in the paper: every frame is the vector of joint rotations as quaternions (all joints but the
root and end sites; signs made continuous over time). Starting at the current segment's first
frame, a Gaussian is fitted by probabilistic PCA to frames ``[start, K)``: mean ``x̄``, the ``r``
leading principal directions kept (``r``: the fewest capturing ``tau`` of the variance of the
segment's first ``T`` frames), the rest modelled as isotropic noise ``σ²`` (mean of the discarded
eigenvalues). ``H(K)`` is the mean Mahalanobis distance of the next ``T`` frames ``[K, K+T)``
under that Gaussian. ``K`` grows by ``Δ`` frames; with ``d(K) = H(K) − H(K−Δ)``, a cut is declared
at the first peak of ``H`` after ``d`` exceeds ``mean(d) + R·std(d)`` (statistics of ``d`` since
the segment began, after a burn-in of ``T`` frames whose fits rest on too few frames — our
addition: without it the first, wild values of ``d`` hide every later change), and the search
restarts at the cut. Paper settings at 120 Hz: ``T = 150``
frames, ``Δ = 10``, ``R = 3``, ``tau = 0.95`` (the frame counts are scaled to other rates).
"""

from __future__ import annotations

import numpy as np

from usdmotion.motion import Motion


def quaternion_features(motion: Motion) -> np.ndarray:
    """``(F, 4·J')`` local joint quaternions (root and end sites left out), sign-continuous in time."""
    joints = np.flatnonzero(~motion.end_sites)[1:]
    q = np.array(motion.rotations[:, joints])                           # (F, J', 4)
    flips = np.einsum("fjc,fjc->fj", q[1:], q[:-1]) < 0.0
    parity = np.concatenate([np.zeros((1, q.shape[1]), bool), np.cumsum(flips, axis=0) % 2 == 1])
    q[parity] *= -1.0
    return q.reshape(q.shape[0], -1)


def _rank(eigenvalues: np.ndarray, tau: float) -> int:
    share = np.cumsum(eigenvalues[::-1]) / max(eigenvalues.sum(), 1e-300)
    return int(np.searchsorted(share, tau) + 1)


def ppca_cuts(motion: Motion, window_s: float = 1.25, step_s: float = 10 / 120, threshold: float = 3.0,
              tau: float = 0.95) -> np.ndarray:
    """Cut frames ``(K,)`` of ``motion`` by the PPCA method (module docstring).

    Args:
        window_s: ``T`` in seconds (paper: 150 frames at 120 Hz).
        step_s: ``Δ`` in seconds (paper: 10 frames).
        threshold: ``R``, in standard deviations of ``d``.
        tau: variance share that fixes the PPCA rank ``r``.
    """
    x = quaternion_features(motion)
    n, dim = x.shape
    t = max(4, int(round(window_s * motion.fps)))
    step = max(1, int(round(step_s * motion.fps)))
    cuts = []
    start = 0
    while start + 2 * t <= n:
        found = _next_cut(x, start, t, step, threshold, tau)
        if found is None:
            break
        cuts.append(found)
        start = found
    return np.asarray(cuts, np.int64)


def mahalanobis_curve(x: np.ndarray, start: int, t: int, step: int, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """``(K (M,), H (M,))``: PPCA fitted to ``x[start:K]`` (running sums, grown by ``step``),
    mean Mahalanobis distance of ``x[K:K+t]``."""
    n, dim = x.shape
    ks = np.arange(start + t, n - t + 1, step)
    s1 = x[start:start + t].sum(0)
    s2 = x[start:start + t].T @ x[start:start + t]
    rank = None
    out = np.empty(ks.size)
    prev = start + t
    for i, k in enumerate(ks):  # one PPCA fit per step of Δ frames
        if k > prev:
            new = x[prev:k]
            s1 += new.sum(0)
            s2 += new.T @ new
            prev = k
        count = k - start
        mean = s1 / count
        cov = s2 / count - np.outer(mean, mean)
        evals, evecs = np.linalg.eigh(cov)                              # ascending
        evals = np.maximum(evals, 1e-12)
        if rank is None:
            rank = min(_rank(evals, tau), dim - 1)
        sigma2 = max(float(evals[: dim - rank].mean()), 1e-12)
        lead_vals, lead_vecs = evals[dim - rank:], evecs[:, dim - rank:]
        centred = x[k:k + t] - mean
        proj = centred @ lead_vecs
        out[i] = ((proj**2 / lead_vals).sum(1) + ((centred**2).sum(1) - (proj**2).sum(1)) / sigma2).mean()
    return ks, out


def _next_cut(x, start, t, step, threshold, tau):
    ks, h = mahalanobis_curve(x, start, t, step, tau)
    d = np.diff(h)
    burn_in = max(2, -(-t // step))  # the first T frames: a Gaussian fitted to too few frames swings wildly
    armed = False
    for i in range(2 * burn_in, d.size):  # the scan of the paper, over a few hundred steps
        if not armed:
            previous = d[burn_in:i]
            armed = d[i] > previous.mean() + threshold * previous.std()
        elif d[i] < 0:
            return int(ks[i])                                           # H peaked at ks[i]
    return None

"""Per-cut detail of kernel change points: confidence, change region, transition merging and the
move to the quietest frame of the region (docs/segment.md, "Confidence and change region per cut").

Sample indices are those of the pooled feature rows ``x (N, D)`` (10 Hz); frames where noted.
"""

from __future__ import annotations

import numpy as np

#: A cut's change region: split positions whose two-segment cost exceeds the cut's by less than this
#: fraction of the penalty; a cut is *low confidence* below ``LOW_CONFIDENCE`` (:func:`cut_confidence`).
REGION_FRACTION = 0.1
LOW_CONFIDENCE = 0.5


def _segment_costs(gram_cumsum: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Kernel cost ``Σ k(x,x) − (1/n) Σ_{u,v} k(x_u, x_v)`` of segments ``[starts, ends)`` from the
    2-D cumulative sum ``(L+1, L+1)`` of a Gaussian Gram matrix (``k(x,x) = 1``)."""
    c = gram_cumsum
    n = (ends - starts).astype(np.float64)
    block = c[ends, ends] - c[starts, ends] - c[ends, starts] + c[starts, starts]
    return n - np.divide(block, n, out=np.zeros_like(n), where=n > 0)


def cut_confidence(x: np.ndarray, cuts: np.ndarray, penalty: float, min_size: int, gamma: float,
                   region_fraction: float = REGION_FRACTION) -> tuple[np.ndarray, np.ndarray]:
    """Confidence and change region of each kernel change point.

    For cut ``s`` between its neighbours ``a < s < b`` (sample indices of ``x (N, D)``), the
    two-segment cost ``G(t) = cost[a, t) + cost[t, b)`` is evaluated at every split ``t``; the cut's
    *gain* is ``cost[a, b) − G(s)`` and its **confidence** ``1 − penalty / gain`` clipped to 0..1
    (0: the cut barely pays for itself; 0.5: it gains twice its penalty). Its **change region** is
    the run of splits around ``s`` with ``G(t) ≤ G(s) + region_fraction · penalty``: where else the
    change could be put at a cost of less than that share of one cut's price (narrow for an abrupt
    change, wide for a gradual one).

    Returns:
        ``(confidence (K,), regions (K, 2))``, regions as inclusive sample indices.
    """
    cuts = np.asarray(cuts, np.int64)
    n = x.shape[0]
    confidence = np.zeros(cuts.size)
    regions = np.stack([cuts, cuts], axis=1) if cuts.size else np.zeros((0, 2), np.int64)
    bounds = np.concatenate([[0], cuts, [n]])
    for k, cut in enumerate(cuts):  # a handful of cuts; each vectorised over its window
        a, b = int(bounds[k]), int(bounds[k + 2])
        w = x[a:b]
        sq = np.sum(w * w, axis=1)
        gram = np.exp(-gamma * np.maximum(sq[:, None] + sq[None, :] - 2.0 * (w @ w.T), 0.0))
        csum = np.zeros((b - a + 1, b - a + 1))
        csum[1:, 1:] = gram.cumsum(0).cumsum(1)
        t = np.arange(1, b - a)
        profile = _segment_costs(csum, np.zeros_like(t), t) + _segment_costs(csum, t, np.full_like(t, b - a))
        whole = _segment_costs(csum, np.array([0]), np.array([b - a]))[0]
        at = int(cut - a - 1)
        gain = whole - profile[at]
        confidence[k] = float(np.clip(1.0 - penalty / gain, 0.0, 1.0)) if gain > 0 else 0.0
        near = profile <= profile[at] + region_fraction * penalty
        t_lo = min(min_size, int(cut - a))  # both sides keep at least min_size samples
        t_hi = max(b - a - min_size, int(cut - a))
        near[: max(t_lo - 1, 0)] = False
        near[t_hi:] = False
        off = np.flatnonzero(~near)
        left = off[off < at]
        right = off[off > at]
        first = left[-1] + 1 if left.size else 0
        last = right[0] - 1 if right.size else near.size - 1
        regions[k] = (a + 1 + first, a + 1 + last)
    return confidence, regions


def merge_transitions(cuts: np.ndarray, n_samples: int, transition_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Replace the two cuts around every inner segment shorter than ``transition_samples`` by
    one cut at its middle (the segment is the passage between two actions, not an action).

    Returns:
        ``(cuts (K',), spans (K', 2))``: spans are the transition segments (inclusive samples;
        ``[c, c]`` for cuts left alone).
    """
    cuts = np.asarray(cuts, np.int64)
    if transition_samples <= 0 or cuts.size < 2:
        return cuts, np.stack([cuts, cuts], axis=1).reshape(-1, 2)
    out, spans, k = [], [], 0
    while k < cuts.size:  # a handful of cuts
        if k + 1 < cuts.size and cuts[k + 1] - cuts[k] < transition_samples:
            out.append((cuts[k] + cuts[k + 1]) // 2)
            spans.append((cuts[k], cuts[k + 1]))
            k += 2
        else:
            out.append(cuts[k])
            spans.append((cuts[k], cuts[k]))
            k += 1
    return np.array(out, np.int64), np.array(spans, np.int64).reshape(-1, 2)


def quietest_in_region(energy: np.ndarray, cuts: np.ndarray, regions: np.ndarray) -> np.ndarray:
    """Move each cut to the frame of least bone energy in its own change region.

    The detector says *which* change happened and, through the region, *where it could be*; within
    that span people cut where the body moves least (Fod, Matarić & Jenkins 2002). Each cut also
    stays short of the midpoint to its neighbours, so cuts keep their order.

    Args:
        energy: ``(F,)`` the bone energy (:func:`bone_energy`).
        cuts: ``(K,)`` sorted frame indices in ``1 .. F-1``.
        regions: ``(K, 2)`` inclusive frame range of each cut's change region (contains the cut).
    Returns:
        ``(K,)`` strictly increasing frame indices in ``1 .. F-1``.
    """
    cuts = np.asarray(cuts, np.int64)
    n = energy.shape[0]
    if cuts.size == 0:
        return cuts
    bounds = np.concatenate([[0], cuts, [n]])
    lows = np.minimum(np.maximum(np.maximum(regions[:, 0], (bounds[:-2] + cuts) // 2 + 1), 1), cuts)
    highs = np.maximum(np.minimum(np.minimum(regions[:, 1], (cuts + bounds[2:] - 1) // 2), n - 1), cuts)
    return np.array([lo + int(np.argmin(energy[lo:hi + 1])) for lo, hi in zip(lows, highs)], np.int64)  # per cut

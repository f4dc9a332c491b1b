"""Scoring detected cuts against labelled ground truth.

Rule (stated once, used everywhere): a labelled cut ``k`` has a *valid region*
``[min(band_start, cut − tol), max(band_end, cut + tol)]`` — its annotated transition band
(when the labels have one) widened to at least ``±tol`` around the annotated cut frame
(default ``tol`` = 0.5 s). A detected cut is a true positive when it is *matched* to a
labelled cut whose region contains it; matching is one-to-one (a maximum bipartite
matching), so two detections in one transition count as one hit and one false alarm.

``precision = TP / detected``, ``recall = TP / labelled``; with nothing detected the
precision is 1 (no false alarm), with nothing labelled the recall is 1. The lenient
``in_region_precision`` (any detection inside any region counts, as a user picking among
candidates would see it) is reported beside it, never instead of it.

Label files (frame numbers as written in the file; ``first_frame`` is the number of
the motion's frame 0, 1 for CMU AMC numbering):

* ``groundtruth86.json`` style: ``{"gt": [trial, ...]}``, trial = rows ``[t0, cut, t1]``;
  the last row closes the take and is no cut; band = ``[min(row), max(row)]``.
* ``*_segments.csv`` with ``raw_cut, transition_start_frame, transition_end_frame``
  (rows with an empty transition are not cuts), or with ``start_frame`` (a cut at each
  segment's first frame, no band).
* ``segments.json`` written by ``usdmotion segment`` (0-based already).
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.errors import InputError
from usdmotion.motion import Motion
from usdmotion.ops.segment.detect import clip
from usdmotion.rotations import quat_slerp

DEFAULT_TOLERANCE_S = 0.5


@dataclass(frozen=True)
class Labels:
    """Labelled cuts, 0-based motion frames: ``cuts (K,)`` and ``bands (K, 2)`` inclusive."""

    cuts: np.ndarray
    bands: np.ndarray
    path: str | None = None


@dataclass(frozen=True)
class Score:
    """One comparison of detected cuts with labels."""

    true_positives: int
    detected: int
    labelled: int
    in_region: int
    pairs: tuple[tuple[int, int], ...]  # (detected frame, labelled cut frame) matched

    @property
    def precision(self) -> float:
        return self.true_positives / self.detected if self.detected else 1.0

    @property
    def recall(self) -> float:
        return self.true_positives / self.labelled if self.labelled else 1.0

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        return 2 * p * r / (p + r) if p + r else 0.0

    @property
    def in_region_precision(self) -> float:
        return self.in_region / self.detected if self.detected else 1.0

    def __add__(self, other: Score) -> Score:
        return Score(self.true_positives + other.true_positives, self.detected + other.detected,
                     self.labelled + other.labelled, self.in_region + other.in_region, self.pairs + other.pairs)

    def to_dict(self) -> dict:
        return {"true_positives": self.true_positives, "detected": self.detected, "labelled": self.labelled,
                "precision": self.precision, "recall": self.recall, "f1": self.f1,
                "in_region_precision": self.in_region_precision, "pairs": [list(p) for p in self.pairs]}


def _labels(cuts, bands, path) -> Labels:
    cuts = np.asarray(cuts, dtype=np.int64).reshape(-1)
    bands = np.asarray(bands, dtype=np.int64).reshape(-1, 2)
    order = np.argsort(cuts, kind="stable")
    return Labels(cuts=cuts[order], bands=bands[order], path=path)


def _from_gt_json(data: dict, trial: int, first_frame: int, path: str) -> Labels:
    key = "gt" if "gt" in data else "gt:"
    trials = data[key]
    if not -len(trials) <= trial < len(trials):
        raise InputError(path, f"trial {trial} not in the file (it has {len(trials)} trials)")
    rows = np.asarray(trials[trial], dtype=np.int64).reshape(-1, 3)[:-1]  # the last row closes the take
    return _labels(rows[:, 1] - first_frame, np.stack([rows.min(1), rows.max(1)], 1) - first_frame, path)


def _from_csv(path: str, first_frame: int) -> Labels:
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise InputError(path, "no label rows")
    cols = set(rows[0])
    if {"raw_cut", "transition_start_frame", "transition_end_frame"} <= cols:
        rows = [r for r in rows if r["transition_start_frame"].strip()]
        cuts = [int(r["raw_cut"]) for r in rows]
        bands = [[int(r["transition_start_frame"]), int(r["transition_end_frame"])] for r in rows]
    elif "start_frame" in cols:
        cuts = [int(r["start_frame"]) for r in rows[1:]]
        bands = [[c, c] for c in cuts]
    else:
        raise InputError(path, "CSV needs columns raw_cut/transition_start_frame/transition_end_frame "
                               f"or start_frame; it has {', '.join(sorted(cols))}")
    return _labels(np.asarray(cuts) - first_frame, np.asarray(bands).reshape(-1, 2) - first_frame, path)


def load_labels(path: str | os.PathLike, trial: int = 0, first_frame: int = 1) -> Labels:
    """Labelled cuts from a label file (formats in the module docstring).

    Raises:
        InputError: unreadable file, unknown format, bad values.
    """
    path = str(Path(path))
    try:
        if path.lower().endswith(".csv"):
            return _from_csv(path, first_frame)
        if path.lower().endswith(".json"):
            from usdmotion.schemas import parse_text

            with open(path, encoding="utf-8") as fh:
                data = parse_text(fh.read(), path)  # NaN, Infinity and absurd nesting refused
            if isinstance(data, dict) and ("gt" in data or "gt:" in data):
                return _from_gt_json(data, trial, first_frame, path)
            if isinstance(data, dict) and "cuts" in data:
                cuts = np.asarray(data["cuts"], dtype=np.int64)
                return _labels(cuts, np.stack([cuts, cuts], 1), path)
            raise InputError(path, "JSON labels need a 'gt' list (groundtruth86 style) or 'cuts' (segments.json)")
        raise InputError(path, "unknown label format (use .json or .csv)")
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, ValueError, KeyError, TypeError, IndexError, OverflowError, json.JSONDecodeError) as exc:
        raise InputError(path, f"cannot read labels: {type(exc).__name__}: {exc}") from None


def valid_regions(labels: Labels, tolerance_frames: int) -> np.ndarray:
    """``(K, 2)`` inclusive frame range in which a detection may match each labelled cut."""
    lo = np.minimum(labels.bands[:, 0], labels.cuts - tolerance_frames)
    hi = np.maximum(labels.bands[:, 1], labels.cuts + tolerance_frames)
    return np.stack([lo, hi], axis=1)


def score_cuts(detected, labels: Labels, tolerance_frames: int) -> Score:
    """One-to-one score of ``detected`` frames against ``labels`` (rule in the module docstring)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    detected = np.sort(np.asarray(detected, dtype=np.int64).reshape(-1))
    regions = valid_regions(labels, tolerance_frames)
    inside = (detected[:, None] >= regions[None, :, 0]) & (detected[:, None] <= regions[None, :, 1])
    pairs: tuple[tuple[int, int], ...] = ()
    if inside.any():
        match = maximum_bipartite_matching(csr_matrix(inside.astype(np.int8)), perm_type="column")
        pairs = tuple((int(detected[i]), int(labels.cuts[k])) for i, k in enumerate(match) if k >= 0)
    return Score(true_positives=len(pairs), detected=int(detected.size), labelled=int(labels.cuts.size),
                 in_region=int(inside.any(axis=1).sum()), pairs=pairs)


@dataclass(frozen=True)
class EditPlan:
    """What a person does to turn detected cuts into labelled ones (the editor's effort).

    ``moved``: ``(detected frame, labelled frame)`` pairs whose frames differ; ``added``: labelled
    cuts no detection was paired with; ``deleted``: detections paired with no labelled cut;
    ``kept``: detections exactly on their labelled cut; ``needed``: moved cuts that were not hits
    already (outside their labelled cut's valid region, :func:`valid_regions`).
    """

    moved: tuple[tuple[int, int], ...]
    added: tuple[int, ...]
    deleted: tuple[int, ...]
    kept: int
    needed: int

    def to_dict(self) -> dict:
        return {"moved": [list(p) for p in self.moved], "added": list(self.added), "deleted": list(self.deleted),
                "kept": self.kept, "needed": self.needed}


def edits_to_labels(detected, labels: Labels, tolerance_frames: int) -> EditPlan:
    """Pair detected cuts with labelled cuts, nearest first, one to one (each detection moves to
    the nearest labelled boundary not taken by a nearer detection), and list the edits.
    """
    detected = np.sort(np.asarray(detected, dtype=np.int64).reshape(-1))
    truth = labels.cuts
    distance = np.abs(detected[:, None] - truth[None, :])
    order = np.argsort(distance, axis=None, kind="stable")
    used_d, used_t, pairs = set(), set(), []
    for flat in order:                       # a few cuts: K detected × L labelled pairs
        i, k = divmod(int(flat), truth.size)
        if i not in used_d and k not in used_t:
            used_d.add(i)
            used_t.add(k)
            pairs.append((i, k))
    regions = valid_regions(labels, tolerance_frames)
    moved = tuple(sorted((int(detected[i]), int(truth[k])) for i, k in pairs if detected[i] != truth[k]))
    needed = sum(1 for i, k in pairs if not regions[k, 0] <= detected[i] <= regions[k, 1])
    return EditPlan(moved=moved, added=tuple(int(truth[k]) for k in range(truth.size) if k not in used_t),
                    deleted=tuple(int(detected[i]) for i in range(detected.size) if i not in used_d),
                    kept=len(pairs) - len(moved), needed=needed)


def synthetic_take(motions: list, blend_s: float = 0.5, source: str | None = None):
    """Concatenate motions of one skeleton into a take whose cuts are known.

    Between consecutive clips, ``round(blend_s · fps)`` frames blend the last pose of one
    into the first pose of the next (slerp with smoothstep weights); each clip's root
    is shifted horizontally to continue where the previous one stopped. The first
    motion's skeleton (offsets) is used throughout.

    Returns:
        ``(motion, labels)``: labels have one cut per junction at the middle of the blend,
        the blend frames as its band.

    Raises:
        InputError: the motions differ in joints, hierarchy or frame rate.
    """
    first: Motion = motions[0]
    for m in motions[1:]:
        if m.joint_names != first.joint_names or not np.array_equal(m.parents, first.parents):
            raise InputError(source, "clips to concatenate must share the skeleton (same joints and hierarchy)")
        if abs(m.fps - first.fps) > 1e-6 * first.fps or (m.joint_translations is None) != (
                first.joint_translations is None):
            raise InputError(source, "clips to concatenate must share the frame rate and channel layout")
    n_blend = max(1, int(round(blend_s * first.fps)))
    horizontal = np.array([1.0, 0.0, 1.0]) if first.up_axis == "Y" else np.array([1.0, 1.0, 0.0])
    weights = np.linspace(0.0, 1.0, n_blend + 2)[1:-1]
    weights = weights * weights * (3.0 - 2.0 * weights)  # smoothstep
    rot, root, jt, cuts, bands = [first.rotations], [first.root_translation], [first.joint_translations], [], []
    frames = first.n_frames
    for m in motions[1:]:
        shift = (root[-1][-1] - m.root_translation[0]) * horizontal
        nxt_root = m.root_translation + shift
        rot.append(quat_slerp(np.broadcast_to(rot[-1][-1], (n_blend,) + rot[-1][-1].shape),
                              np.broadcast_to(m.rotations[0], (n_blend,) + m.rotations[0].shape),
                              np.broadcast_to(weights[:, None], (n_blend, first.n_joints))))
        root.append(root[-1][-1] + weights[:, None] * (nxt_root[0] - root[-1][-1]))
        if first.joint_translations is not None:
            jt.append(jt[-1][-1] + weights[:, None, None] * (m.joint_translations[0] - jt[-1][-1]))
            jt.append(m.joint_translations)
        rot.append(m.rotations)
        root.append(nxt_root)
        bands.append((frames, frames + n_blend - 1))
        cuts.append(frames + n_blend // 2)
        frames += n_blend + m.n_frames
    take = first.with_frames(np.concatenate(rot), np.concatenate(root),
                             None if first.joint_translations is None else np.concatenate(jt))
    return take, _labels(cuts, bands, source)


def activity_ranges(labels: Labels, n_frames: int, margin_frames: int = 0) -> np.ndarray:
    """``(K + 1, 2)`` inclusive frame ranges of the labelled activities: the frames between
    consecutive transition bands, each band widened by ``margin_frames`` on both sides.

    Raises:
        ValueError: a range would be empty (bands overlap, or the margin is too wide).
    """
    starts = np.concatenate([[0], labels.bands[:, 1] + 1 + margin_frames]).astype(np.int64)
    ends = np.concatenate([labels.bands[:, 0] - 1 - margin_frames, [n_frames - 1]]).astype(np.int64)
    if np.any(ends < starts) or starts[-1] > n_frames - 1 or ends[0] < 0:
        raise ValueError(f"an activity between the labelled transitions is empty with a margin of {margin_frames} "
                         "frames")
    return np.stack([starts, ends], axis=1)


def reordered_take(motion, labels: Labels, order, margin_frames: int = 0, blend_s: float = 0.5,
                   source: str | None = None):
    """``motion``'s labelled activities (:func:`activity_ranges`) re-joined in ``order`` by
    :func:`synthetic_take`: a take of real activities whose junctions are known exactly.

    Args:
        order: indices into the activities, e.g. ``[2, 0, 1]``; an activity may be left out or repeated.
        margin_frames: frames dropped beside each labelled transition band, so the natural
            transitions (whose cut is a matter of convention) are not in the new take.

    Returns:
        ``(take, labels)`` as :func:`synthetic_take`.
    """
    ranges = activity_ranges(labels, motion.n_frames, margin_frames)
    order = [int(i) for i in order]
    if len(order) < 2 or not all(0 <= i < len(ranges) for i in order):
        raise ValueError(f"order needs at least two indices within 0..{len(ranges) - 1}, got {order}")
    return synthetic_take([clip(motion, *(int(v) for v in ranges[i])) for i in order], blend_s=blend_s, source=source)

"""Segmentation of long captures into primitive actions (ALGORITHMS.md §3).

Feature (the paper's): for each frame, the angles between the eight limb bones (upper
arm, forearm, thigh, shank; left and right) and the centre bone Root → Chest,
``θ_k = arccos(B_k·B_c / (‖B_k‖‖B_c‖))``, and the 1-D signal ``Q = ‖θ‖``.

Two detectors:

* ``"heuristic"`` — the paper's candidate cuts, implemented per its evident intent:
  low-pass ``Q`` (zero-phase Butterworth), find the local extrema (alternating maxima and
  minima), and keep an extremum when the swings to its two neighbouring extrema differ
  strongly, ``min(s1, s2) <= param · max(s1, s2)``. (The published pseudocode compares the
  extremum *flags* instead of signal values and returns an undefined variable.)
* ``"kcpd"`` — kernel change-point detection (Harchaoui & Cappé 2007; Arlot, Celisse &
  Harchaoui, JMLR 2019) on the 8-D bone angles plus their absolute angular speeds,
  averaged to 10 Hz: a Gaussian-kernel cost (median-heuristic bandwidth) and a linear
  penalty per cut, solved exactly by PELT (``ruptures.KernelCPD``). It finds changes in
  the *distribution* of poses and speeds, so the oscillation inside a cyclic action
  (walking, jumping jacks) does not trigger cuts.

Frames are 0-based indices; a *cut* ``c`` starts a new segment at frame ``c``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from usdmotion.errors import InputError
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.ops.segment.cuts import (LOW_CONFIDENCE, cut_confidence, merge_transitions,  # noqa: F401
                                        quietest_in_region)
from usdmotion.ops.segment.roles import LIMB_BONES, find_roles

METHODS = ("kcpd", "heuristic")
DEFAULT_METHOD = "kcpd"
#: The paper's swing-ratio threshold (0 <= param <= 1).
DEFAULT_PARAM = 0.5
#: Low-pass cut-off of the norm signal (Hz) for the heuristic and the plot.
DEFAULT_CUTOFF_HZ = 2.0
#: Lowest low-pass cut-off of ``Q`` (Hz): below it the curve is flat (and at 1e-12 Hz scipy's
#: filter design failed with "Singular matrix").
MIN_CUTOFF_HZ = 0.1
#: Kernel change-point defaults: penalty per cut = ``DEFAULT_PENALTY_SCALE · ln N`` (``N`` samples at
#: ``KCPD_RATE_HZ``; a label-free rule from the take's length), speed weight (s), minimum segment (s),
#: rate (Hz), feature set, and the longest segment treated as a transition between two actions (s).
DEFAULT_PENALTY_SCALE = 1.0
DEFAULT_SPEED_WEIGHT = 0.5
DEFAULT_MIN_LENGTH_S = 1.0
KCPD_RATE_HZ = 10.0
FEATURE_SETS = ("paper", "extended")
DEFAULT_FEATURES = "extended"
DEFAULT_TRANSITION_S = 1.5
DEFAULT_MIN_CONFIDENCE = 0.0
#: Cut refinement: moving average (s) of the bone energy, farthest move (s) to its local minimum.
DEFAULT_REST_SMOOTH_S = 0.1
DEFAULT_REST_REACH_S = 0.5
#: Shortest motion accepted, in seconds and frames.
MIN_DURATION_S = 1.0
MIN_FRAMES = 16
_GAMMA_SAMPLE = 2000  # samples used for the median-heuristic bandwidth


@dataclass(frozen=True)
class Segmentation:
    """Cuts of one motion and the signals they were found on.

    Attributes:
        cuts: ``(K,)`` sorted frame indices in ``1 .. n_frames-1``; cut ``c`` starts a segment.
        n_frames: frames of the motion.
        fps: frames per second.
        method: ``"kcpd"`` or ``"heuristic"``.
        params: the detector's parameters (JSON-ready).
        angles: ``(F, 8)`` bone angles θ in radians, order of :data:`~usdmotion.ops.segment.roles.LIMB_BONES`.
        signal: ``(F,)`` the norm signal ``Q = ‖θ‖``.
        filtered: ``(F,)`` ``Q`` after the low-pass filter.
        candidates: ``(C,)`` the paper's candidate cuts on ``filtered`` (for the plot).
        energy: ``(F,)`` bone energy, rad²/s² (:func:`bone_energy`; kcpd cuts move to its minima).
        roles: ``{role: joint name}`` used for the feature.
        confidence: ``(K,)`` kcpd: confidence of each cut, 0..1 (:func:`cut_confidence`); ``None``
            for the heuristic.
        regions: ``(K, 2)`` kcpd: inclusive frame range of each cut's change region (the
            refinement never leaves it); ``None`` for the heuristic.
        edited: the cuts were placed or moved by a person (:func:`~usdmotion.ops.segment.files.edited`),
            not the detector's as found; ``method`` and ``params`` name the run the edit started from.
    """

    cuts: np.ndarray
    n_frames: int
    fps: float
    method: str
    params: dict = field(default_factory=dict)
    angles: np.ndarray | None = field(default=None, repr=False)
    signal: np.ndarray | None = field(default=None, repr=False)
    filtered: np.ndarray | None = field(default=None, repr=False)
    candidates: np.ndarray | None = field(default=None, repr=False)
    energy: np.ndarray | None = field(default=None, repr=False)
    roles: dict = field(default_factory=dict)
    confidence: np.ndarray | None = field(default=None, repr=False)
    regions: np.ndarray | None = field(default=None, repr=False)
    edited: bool = False

    def bounds(self) -> np.ndarray:
        """``(S, 2)`` first and last frame (inclusive) of every segment."""
        starts = np.concatenate([[0], self.cuts]).astype(np.int64)
        ends = np.concatenate([self.cuts - 1, [self.n_frames - 1]]).astype(np.int64)
        return np.stack([starts, ends], axis=1)

    def segment_at(self, frame: int, source: str | None = None) -> int:
        """Index of the segment containing ``frame``; ``InputError`` (naming ``source``) if outside."""
        if not 0 <= frame < self.n_frames:
            raise InputError(source, f"--at {frame}: frame is outside 0..{self.n_frames - 1}")
        return int(np.searchsorted(self.cuts, frame, side="right"))

    def to_dict(self) -> dict:
        """JSON-ready description (``schemas/segments.schema.json``)."""
        segments = [
            {"index": i, "start_frame": int(a), "end_frame": int(b), "frames": int(b - a + 1),
             "start_time": round(a / self.fps, 6), "end_time": round(b / self.fps, 6)}
            for i, (a, b) in enumerate(self.bounds())
        ]
        doc = {"method": self.method, "params": dict(self.params), "fps": self.fps, "frames": self.n_frames,
               "roles": dict(self.roles), "cuts": [int(c) for c in self.cuts], "segments": segments}
        if self.edited:
            doc["edited"] = True
        if self.confidence is not None:
            doc["cut_details"] = [
                {"frame": int(c), "confidence": round(float(p), 4), "low_confidence": bool(p < LOW_CONFIDENCE),
                 "region": [int(lo), int(hi)]}
                for c, p, (lo, hi) in zip(self.cuts, self.confidence, self.regions)]
        return doc


# --------------------------------------------------------------------------- feature


def _needed_joints(parents: np.ndarray, joints: list[int]) -> np.ndarray:
    keep = np.zeros(len(parents), bool)
    for j in joints:
        while j >= 0 and not keep[j]:
            keep[j] = True
            j = int(parents[j])
    return np.flatnonzero(keep)


def role_positions(motion: Motion, roles: Mapping[str, int]) -> dict[str, np.ndarray]:
    """World positions ``(F, 3)`` of every role joint, by forward kinematics restricted to
    the joints on their paths to the root."""
    keep = _needed_joints(motion.parents, list(roles.values()))
    remap = np.full(motion.n_joints, -1)
    remap[keep] = np.arange(keep.size)
    sub_parents = np.where(motion.parents[keep] >= 0, remap[motion.parents[keep]], -1)
    if motion.joint_translations is None:  # only the kept joints' translations, not all J
        translations = np.broadcast_to(motion.offsets[keep], (motion.n_frames, keep.size, 3)).copy()
        translations[:, 0] = motion.root_translation                     # keep[0] is the root
    else:
        translations = local_translations(motion)[:, keep]
    _, world = fk_arrays(motion.rotations[:, keep], translations, sub_parents)
    return {role: world[:, remap[j]] for role, j in roles.items()}


def angles_from_positions(positions: Mapping[str, np.ndarray]) -> np.ndarray:
    """``(F, 8)`` angles (radians) between the limb bones and the centre bone Root → Chest.

    A zero-length bone (coincident joints) gives angle π/2 rather than NaN.
    """
    centre = positions["chest"] - positions["root"]
    bones = np.stack([positions[b] - positions[a] for _, a, b in LIMB_BONES], axis=1)
    dots = np.einsum("fkd,fd->fk", bones, centre)
    norms = np.linalg.norm(bones, axis=-1) * np.linalg.norm(centre, axis=-1)[:, None]
    cos = np.divide(dots, norms, out=np.zeros_like(dots), where=norms > 0)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def bone_angles(motion: Motion, roles: Mapping[str, int] | None = None, source: str | None = None) -> np.ndarray:
    """The paper's 8-D bone-angle feature ``(F, 8)`` in radians."""
    roles = find_roles(motion, source=source) if roles is None else roles
    return angles_from_positions(role_positions(motion, roles))


def norm_signal(angles: np.ndarray) -> np.ndarray:
    """``Q_i = ‖θ_i‖`` ``(F,)``."""
    return np.linalg.norm(angles, axis=-1)


def lowpass(x: np.ndarray, fps: float, cutoff_hz: float = DEFAULT_CUTOFF_HZ, order: int = 2) -> np.ndarray:
    """Zero-phase Butterworth low-pass of ``x`` along axis 0 (no lag, so extrema stay put)."""
    from scipy import signal

    if not MIN_CUTOFF_HZ <= cutoff_hz < fps / 2:  # 1e-12 Hz: scipy's "Singular matrix"
        raise ValueError(f"--cutoff {cutoff_hz:g} Hz must be at least {MIN_CUTOFF_HZ:g} Hz and below half the frame "
                         f"rate ({fps / 2:g} Hz)")
    sos = signal.butter(order, cutoff_hz, fs=fps, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


# --------------------------------------------------------------------------- paper heuristic


def local_extrema(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(index, is_max)`` of the strict local extrema of ``y``, alternating max/min.

    Flat runs count once (at their first sample), so maxima and minima always alternate.
    """
    slope = np.sign(np.diff(y))
    n = slope.size
    after = np.minimum.accumulate(np.where(slope != 0, np.arange(n), n)[::-1])[::-1]
    slope = np.where(after < n, slope[np.minimum(after, n - 1)], 0)  # flat steps take the next slope
    turn = np.flatnonzero((slope[1:] != slope[:-1]) & (slope[:-1] != 0) & (slope[1:] != 0)) + 1
    return turn, slope[turn - 1] > 0


def swing_candidates(y: np.ndarray, param: float = DEFAULT_PARAM) -> np.ndarray:
    """The paper's candidate cuts: extrema whose two swings differ by more than ``param``.

    For extremum ``e`` with neighbouring opposite extrema ``l`` and ``r``:
    ``s1 = |y[l] − y[e]|``, ``s2 = |y[r] − y[e]|``; ``e`` is a candidate when
    ``min(s1, s2) <= param · max(s1, s2)``. The first and last extrema have one
    neighbour only and are skipped.
    """
    if not 0.0 <= param <= 1.0:
        raise ValueError(f"param must be within 0..1, got {param}")
    idx, _ = local_extrema(y)
    if idx.size < 3:
        return np.zeros(0, np.int64)
    v = y[idx]
    s1 = np.abs(v[1:-1] - v[:-2])
    s2 = np.abs(v[1:-1] - v[2:])
    keep = np.minimum(s1, s2) <= param * np.maximum(s1, s2)
    return idx[1:-1][keep].astype(np.int64)


# --------------------------------------------------------------------------- kernel change points


def angular_speed(angles: np.ndarray, fps: float) -> np.ndarray:
    """``(F, B)`` absolute angular speeds ``|dθ/dt|`` (rad/s) of ``(F, B)`` angles in radians."""
    return np.abs(np.gradient(angles, axis=0)) * fps


def pooled_features(angles: np.ndarray, fps: float, speed_weight: float = DEFAULT_SPEED_WEIGHT,
                    rate_hz: float = KCPD_RATE_HZ) -> tuple[np.ndarray, int]:
    """``(X (N, 16), pool)``: angles and ``speed_weight``·|dθ/dt| averaged over blocks of
    ``pool`` frames (``pool ≈ fps / rate_hz``)."""
    pool = max(1, int(round(fps / rate_hz)))
    feats = np.concatenate([angles, angular_speed(angles, fps) * speed_weight], axis=1)
    n = feats.shape[0] // pool
    return feats[: n * pool].reshape(n, pool, -1).mean(axis=1), pool


def median_gamma(x: np.ndarray, limit: int = _GAMMA_SAMPLE) -> float:
    """``1 / median squared distance`` of the rows of ``x`` (a strided sample of at most ``limit``)."""
    from scipy.spatial.distance import pdist

    step = max(1, math.ceil(x.shape[0] / limit))
    d2 = pdist(x[::step], "sqeuclidean")
    med = float(np.median(d2)) if d2.size else 0.0
    return 1.0 / med if med > 0 else 1.0


def penalty_for_length(n_samples: int, scale: float = DEFAULT_PENALTY_SCALE) -> float:
    """Label-free penalty per cut, ``scale · ln(n_samples)`` (BIC-like: grows with the take's length)."""
    return float(scale * math.log(max(n_samples, 2)))


def kernel_change_points(x: np.ndarray, penalty: float | None = None, min_size: int = 10,
                         gamma: float | None = None) -> np.ndarray:
    """Change points of the rows of ``x`` (Gaussian-kernel cost, PELT); sample indices."""
    import ruptures

    if x.shape[0] < 2 * min_size:
        return np.zeros(0, np.int64)
    gamma = median_gamma(x) if gamma is None else gamma
    penalty = penalty_for_length(x.shape[0]) if penalty is None else penalty
    algo = ruptures.KernelCPD(kernel="rbf", min_size=min_size, params={"gamma": gamma}).fit(x)
    return np.asarray(algo.predict(pen=penalty)[:-1], dtype=np.int64)


def body_axis_angles(positions: Mapping[str, np.ndarray]) -> np.ndarray:
    """``(F, 10)`` angles (radians) that tell *where* the limbs point, not only how far from the
    spine: each limb bone against the hip line (right hip → left hip; 8 angles), the shoulder line
    against the hip line seen along the spine (torso twist) and the spine against the vertical
    axis of the pelvis frame's mean (lean). Like the paper's angles they do not depend on the
    rig's units, rest pose, position or heading."""
    centre = positions["chest"] - positions["root"]
    side = positions["left_hip"] - positions["right_hip"]
    shoulders = positions["left_shoulder"] - positions["right_shoulder"]

    def angle(u, v):
        dots = np.einsum("fd,fd->f", u, v)
        norms = np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1)
        return np.arccos(np.clip(np.divide(dots, norms, out=np.zeros_like(dots), where=norms > 0), -1.0, 1.0))

    bones = [angle(positions[b] - positions[a], side) for _, a, b in LIMB_BONES]
    unit = centre / np.maximum(np.linalg.norm(centre, axis=-1, keepdims=True), 1e-12)

    def across(v):
        return v - np.einsum("fd,fd->f", v, unit)[:, None] * unit

    up = np.broadcast_to(np.mean(unit, axis=0), unit.shape)
    return np.stack(bones + [angle(across(shoulders), across(side)), angle(centre, up)], axis=1)


def bone_energy(speed: np.ndarray, fps: float, smooth_s: float = DEFAULT_REST_SMOOTH_S) -> np.ndarray:
    """``(F,)`` mean squared angular speed of the bones (rad²/s²), ``smooth_s`` moving average.

    Args:
        speed: ``(F, B)`` absolute angular speeds ``|dθ/dt|`` in rad/s.
    """
    from scipy.ndimage import uniform_filter1d

    return uniform_filter1d(np.mean(speed**2, axis=1), max(1, int(round(smooth_s * fps))), mode="nearest")


def refine_to_rest(energy: np.ndarray, cuts: np.ndarray, fps: float,
                   reach_s: float = DEFAULT_REST_REACH_S, regions: np.ndarray | None = None) -> np.ndarray:
    """Move each cut downhill on :func:`bone_energy` to the nearest local minimum.

    A change-point detector knows *which* change happened to within its pooling, not
    *where* the body passed between the two actions; people (and clip libraries) cut where
    the body moves least (the zero-velocity boundaries of Fod, Matarić & Jenkins 2002).
    Each cut follows the steeper downhill side until the energy rises again, at most
    ``reach_s`` seconds, never past the midpoint to a neighbouring cut and, with ``regions``,
    never out of the cut's own change region.

    Args:
        energy: ``(F,)`` the bone energy (:func:`bone_energy`).
        cuts: ``(K,)`` sorted frame indices in ``1 .. F-1``.
        regions: ``(K, 2)`` inclusive frame range each cut must stay in, or ``None``.
    Returns:
        ``(K,)`` frame indices in ``1 .. F-1``, in the order of ``cuts`` and still strictly
        increasing (no cut passes the midpoint to its neighbour).
    """
    cuts = np.asarray(cuts, np.int64)
    n = energy.shape[0]
    if cuts.size == 0 or n < 3:
        return cuts
    reach = max(0, int(round(reach_s * fps)))
    bounds = np.concatenate([[0], cuts, [n]])
    lows = np.maximum(np.maximum(cuts - reach, (bounds[:-2] + cuts) // 2 + 1), 1)
    highs = np.minimum(np.minimum(cuts + reach, (cuts + bounds[2:] - 1) // 2), n - 1)
    if regions is not None:
        lows = np.minimum(np.maximum(lows, regions[:, 0]), cuts)
        highs = np.maximum(np.minimum(highs, regions[:, 1]), cuts)
    out = np.empty_like(cuts)
    for k, (c, lo, hi) in enumerate(zip(cuts, lows, highs)):   # a handful of cuts, not frames
        left = energy[lo:c + 1][::-1]                           # c, c-1, ..., lo
        right = energy[c:hi + 1]                                # c, c+1, ..., hi
        go_left = left.size > 1 and (right.size < 2 or left[1] < right[1])
        path = left if go_left else right
        rising = np.flatnonzero(np.diff(path) >= 0)
        steps = int(rising[0]) if rising.size else path.size - 1
        out[k] = c - steps if go_left else c + steps
    return out


# --------------------------------------------------------------------------- driver


def check_length(motion: Motion, source: str | None = None) -> None:
    """``InputError`` when ``motion`` is too short to segment."""
    need = max(MIN_FRAMES, math.ceil(MIN_DURATION_S * motion.fps))
    if motion.n_frames < need:
        raise InputError(source, f"motion too short to segment: {motion.n_frames} frames "
                                 f"({motion.duration:.2f} s), need at least {need} ({MIN_DURATION_S:g} s)")


def segment(motion: Motion, method: str = DEFAULT_METHOD, param: float = DEFAULT_PARAM,
            cutoff_hz: float = DEFAULT_CUTOFF_HZ, penalty: float | None = None,
            min_length_s: float = DEFAULT_MIN_LENGTH_S, speed_weight: float = DEFAULT_SPEED_WEIGHT,
            refine: bool = True, roles: Mapping[str, str] | None = None, preset: str | None = None,
            source: str | None = None, penalty_scale: float = DEFAULT_PENALTY_SCALE,
            features: str = DEFAULT_FEATURES, transition_s: float = DEFAULT_TRANSITION_S,
            min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> Segmentation:
    """Cut ``motion`` into primitive actions.

    Args:
        method: ``"kcpd"`` (kernel change points, default) or ``"heuristic"`` (the paper's).
        param: the heuristic's swing-ratio threshold, 0..1.
        cutoff_hz: low-pass cut-off of ``Q`` (heuristic, plot).
        penalty: kcpd cost per cut (larger: fewer cuts); ``None``: ``penalty_scale · ln N``
            (:func:`penalty_for_length`, ``N`` = samples at 10 Hz).
        min_length_s: kcpd shortest segment, seconds.
        speed_weight: kcpd weight (seconds) of the angular speeds against the angles.
        refine: kcpd: move each cut to the quietest frame (least bone energy) of its own
            change region (:func:`quietest_in_region`).
        roles: ``{role: joint name}`` overrides for the role map.
        preset: force a role preset (:data:`~usdmotion.ops.segment.roles.PRESET_NAMES`).
        source: file name for messages.
        penalty_scale: kcpd: the factor of ``ln N`` when ``penalty`` is ``None``.
        features: kcpd: ``"paper"`` (the 8 bone angles) or ``"extended"`` (plus
            :func:`body_axis_angles`), each with its angular speeds.
        transition_s: kcpd: an inner segment shorter than this is a transition and its two
            cuts become one at its middle (:func:`merge_transitions`); 0 = off.
        min_confidence: kcpd: drop cuts whose confidence (:func:`cut_confidence`) is below
            this, then recompute the others' (0 = keep all; low ones are only marked).
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r} (use {', '.join(METHODS)})")
    if features not in FEATURE_SETS:
        raise ValueError(f"unknown feature set {features!r} (use {', '.join(FEATURE_SETS)})")
    for name, value, least in (("--penalty", penalty, 0.0), ("penalty scale", penalty_scale, 0.0),
                               ("--min-length", min_length_s, 0.0), ("speed weight", speed_weight, None),
                               ("transition", transition_s, None), ("--param", param, None)):
        if value is None and name == "--penalty":
            continue
        # NaN and inf passed the comparisons here before (ruptures' AssertionError, an OverflowError)
        if not (isinstance(value, (int, float)) and math.isfinite(value)
                and (value > least if least is not None else value >= 0)):
            kind = "positive" if least is not None else "non-negative"
            raise ValueError(f"{name} must be a {kind} number, got {value!r}")
    check_length(motion, source)
    role_index = find_roles(motion, overrides=roles, preset=preset, source=source)
    positions = role_positions(motion, role_index)
    angles = angles_from_positions(positions)
    q = norm_signal(angles)
    filtered = lowpass(q, motion.fps, min(cutoff_hz, 0.45 * motion.fps))
    candidates = swing_candidates(filtered, param)
    energy = bone_energy(angular_speed(angles, motion.fps), motion.fps)
    confidence = regions = None
    if method == "heuristic":
        cuts = candidates
        params = {"param": param, "cutoff_hz": cutoff_hz}
    else:
        feature = angles if features == "paper" else np.concatenate([angles, body_axis_angles(positions)], axis=1)
        x, pool = pooled_features(feature, motion.fps, speed_weight)
        min_size = max(2, math.ceil(min_length_s * motion.fps / pool))
        pen = penalty_for_length(x.shape[0], penalty_scale) if penalty is None else penalty
        gamma = median_gamma(x)
        samples = kernel_change_points(x, pen, min_size, gamma)
        samples, spans = merge_transitions(samples, x.shape[0], int(round(transition_s * motion.fps / pool)))
        confidence, regions = cut_confidence(x, samples, pen, min_size, gamma)
        if min_confidence > 0 and np.any(confidence < min_confidence):
            sure = confidence >= min_confidence
            samples, spans = samples[sure], spans[sure]
            confidence, regions = cut_confidence(x, samples, pen, min_size, gamma)
        regions = np.stack([np.minimum(regions[:, 0], spans[:, 0]), np.maximum(regions[:, 1], spans[:, 1])], 1)
        cuts, regions = samples * pool, regions * pool
        params = {"penalty": pen, "penalty_scale": penalty_scale if penalty is None else None,
                  "min_length_s": min_length_s, "speed_weight": speed_weight, "rate_hz": motion.fps / pool,
                  "features": features, "transition_s": transition_s, "min_confidence": min_confidence,
                  "refine": refine}
        params = {k: v for k, v in params.items() if v is not None}
        if refine:
            params |= {"rest_smooth_s": DEFAULT_REST_SMOOTH_S}
    keep = (cuts > 0) & (cuts < motion.n_frames)
    cuts, first = np.unique(cuts[keep], return_index=True)
    if confidence is not None:
        confidence = confidence[keep][first]
        regions = np.clip(regions[keep][first], 1, motion.n_frames - 1)
        if refine:
            cuts = quietest_in_region(energy, cuts, regions)
    names = {r: motion.joint_names[j] for r, j in role_index.items()}
    return Segmentation(cuts=cuts, n_frames=motion.n_frames, fps=motion.fps, method=method, params=params,
                        angles=angles, signal=q, filtered=filtered, candidates=candidates,
                        energy=energy, roles=names, confidence=confidence, regions=regions)


def clip(motion: Motion, first: int, last: int) -> Motion:
    """Frames ``first..last`` (inclusive) of ``motion`` as a new motion.

    Keeps the BVH channel values of those frames (``source_channels``), so a clip written
    as BVH repeats the input's numbers.
    """
    if not 0 <= first <= last < motion.n_frames:
        raise ValueError(f"clip {first}..{last} is outside 0..{motion.n_frames - 1}")
    return motion.sliced(first, last + 1)

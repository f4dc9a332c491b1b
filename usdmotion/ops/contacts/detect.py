"""Foot contacts: which frames each heel/ankle and toe joint is planted on the floor.

A joint is planted when it is low and slow. Its **height** is measured above its own
planted level: ``floor + clearance[c]``, where ``floor`` (m, along the up axis) is the
ground plane and ``clearance[c]`` how high that joint sits above the ground when the foot
is flat (an ankle ~7–9 cm, a toe joint ~2–4 cm). Both come from the motion unless given:

* ``floor``: the ``floor_percentile`` (default 2 %) of the per-frame lowest contact-joint
  height — robust against a few frames of noise or a foot through the floor;
* ``clearance[c]``: the same percentile of joint ``c``'s own height, minus ``floor``
  (never below 0).

**Speed** is the joint's 3-D speed (m/s), central differences over the frames.

**Hysteresis**: a frame meets the *enter* thresholds when its height is below
``height_enter`` and its speed below ``speed_enter``, the *exit* thresholds when below
``height_exit`` / ``speed_exit`` (looser). A contact is a maximal run of frames meeting
the exit thresholds that contains at least one frame meeting the enter thresholds
(applied forwards and backwards in time: the detector sees the whole take). Then gaps
shorter than ``min_gap`` seconds between two contacts are filled, and contacts shorter
than ``min_duration`` seconds are dropped.

**Heel-off**: a heel or ankle contact ends where that joint has risen more than
:data:`HEEL_RISE_M` above its level in that contact (the run's median height) while the
toe of the same side stays planted — from there the foot rolls over its toe, which is the
only joint still planted (and symmetrically a toe-first landing starts the heel's contact
once it is down). Without it, a heel contact went on while the source's heel rose up to
4.8 cm (CMU walk), and a retargeted flat foot held there needed a longer leg than it had.
A contact it leaves shorter than ``min_duration`` is dropped too.

Everything is vectorised over frames and contact joints (run lengths by ``cumsum``/``diff``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdmotion.errors import InputError
from usdmotion.kinematics import joint_positions
from usdmotion.motion import Motion

#: Index of each up axis in a position vector.
UP_INDEX = {"Y": 1, "Z": 2}
#: Heel-off: a heel/ankle contact ends where the joint is this many metres above its level
#: in the contact while the toe of its side is still planted (see the module docstring).
HEEL_RISE_M = 0.005


@dataclass(frozen=True)
class ContactThresholds:
    """Detector thresholds (heights in m above the joint's planted level, speeds in m/s, times in s).

    Defaults were chosen on the CMU 12_01 walk (120 fps) and the Bandai walk and run (30 fps):
    there a planted ankle's median speed is 0.03–0.09 m/s (95th percentile about 0.3 m/s),
    a swinging foot passes 1 m/s; tighter speeds lose the 3–4-frame stances of the run.
    """

    height_enter: float = 0.03
    height_exit: float = 0.05
    speed_enter: float = 0.25
    speed_exit: float = 0.45
    min_duration: float = 0.05
    min_gap: float = 0.04
    floor_percentile: float = 2.0

    def __post_init__(self) -> None:
        values = {k: getattr(self, k) for k in self.__dataclass_fields__}
        bad = [k for k, v in values.items() if not np.isfinite(v) or v < 0]
        if bad:
            raise ValueError(f"contact threshold {bad[0]} must be a finite number >= 0, got {values[bad[0]]!r}")
        if self.height_exit < self.height_enter or self.speed_exit < self.speed_enter:
            raise ValueError("the exit thresholds must be at least the enter thresholds "
                             f"(height {self.height_enter} / {self.height_exit} m, "
                             f"speed {self.speed_enter} / {self.speed_exit} m/s)")
        if self.floor_percentile > 100:
            raise ValueError(f"floor_percentile must be within 0..100, got {self.floor_percentile}")

    def as_dict(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in self.__dataclass_fields__}


@dataclass(frozen=True, eq=False)
class FootContacts:
    """Contact frames of a motion's heel/ankle and toe joints.

    Attributes:
        joints: ``C`` joint names.
        indices: ``(C,)`` int, their indices in the motion's joints.
        parts: ``C`` body parts, ``"left_heel"``, ``"left_ankle"``, ``"left_toe"``, ``"right_..."``.
        contact: ``(F, C)`` bool, ``True`` where the joint is planted.
        floor: ground height along ``up`` (m).
        clearance: ``(C,)`` height of each joint above the floor when planted (m).
        up: up axis, ``"Y"`` or ``"Z"``.
        fps: frames per second.
        thresholds: what detected them (``None`` for contacts read from a file made elsewhere).
    """

    joints: tuple[str, ...]
    indices: np.ndarray
    parts: tuple[str, ...]
    contact: np.ndarray
    floor: float
    clearance: np.ndarray
    up: str
    fps: float
    thresholds: ContactThresholds | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        for name in ("indices", "contact", "clearance"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        c = len(self.joints)
        if self.indices.shape != (c,) or self.clearance.shape != (c,) or len(self.parts) != c:
            raise ValueError(f"FootContacts: {c} joints but indices {self.indices.shape}, "
                             f"clearance {self.clearance.shape}, {len(self.parts)} parts")
        if self.contact.ndim != 2 or self.contact.shape[1] != c or self.contact.dtype != bool:
            raise ValueError(f"FootContacts: contact must be (F, {c}) bool, got {self.contact.shape} "
                             f"{self.contact.dtype}")
        if self.up not in UP_INDEX:
            raise ValueError(f"FootContacts: up must be 'Y' or 'Z', got {self.up!r}")

    @property
    def n_frames(self) -> int:
        return int(self.contact.shape[0])

    def intervals(self, c: int) -> np.ndarray:
        """``(N, 2)`` int ``[start, stop)`` frame ranges of joint ``c``'s contacts."""
        return runs(self.contact[:, c])


# ------------------------------------------------------------------------ run lengths


def runs(mask: np.ndarray) -> np.ndarray:
    """``(N, 2)`` ``[start, stop)`` of the runs of ``True`` in a 1-D bool array."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask, np.int8), [0]]))
    return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)], axis=1)


def _run_ids(mask: np.ndarray) -> np.ndarray:
    """``(F, C)`` int: per column, 1-based id of the run of ``True`` each frame is in (0 outside)."""
    starts = mask & ~np.vstack([np.zeros((1, mask.shape[1]), bool), mask[:-1]])
    ids = np.cumsum(starts, axis=0)
    return np.where(mask, ids, 0)


def _run_lengths(mask: np.ndarray) -> np.ndarray:
    """``(F, C)`` int: length of the run of equal values each frame belongs to, per column."""
    f, c = mask.shape
    change = np.vstack([np.ones((1, c), bool), mask[1:] != mask[:-1]])
    ids = np.cumsum(change, axis=0) - 1 + (np.arange(c) * f)[None, :]  # global run id, column-major blocks
    counts = np.bincount(ids.ravel(), minlength=f * c)
    return counts[ids]


def hysteresis(enter: np.ndarray, stay: np.ndarray) -> np.ndarray:
    """``(F, C)`` bool: runs of ``stay`` that contain at least one ``enter`` frame.

    ``enter`` frames outside ``stay`` are treated as ``stay`` frames too.
    """
    stay = stay | enter
    ids = _run_ids(stay)
    f, c = stay.shape
    offset = (np.arange(c) * (f + 1))[None, :]
    hit = np.zeros(c * (f + 1), bool)
    hit[(ids + offset)[enter]] = True
    hit[offset[0]] = False  # id 0 is "outside any run"
    return hit[ids + offset]


def clean_runs(contact: np.ndarray, min_frames: int, min_gap_frames: int) -> np.ndarray:
    """Fill gaps shorter than ``min_gap_frames`` between contacts, then drop contacts
    shorter than ``min_frames``; ``contact`` ``(F, C)`` bool."""
    contact = np.asarray(contact, bool)
    if contact.size == 0:
        return contact.copy()
    lengths = _run_lengths(contact)
    inside = np.maximum.accumulate(contact, axis=0) & np.maximum.accumulate(contact[::-1], axis=0)[::-1]
    filled = contact | (~contact & inside & (lengths < min_gap_frames))
    return filled & (_run_lengths(filled) >= min_frames)


# ---------------------------------------------------------------------- which joints

#: Contact parts in output order, per side; the canonical rig-profile point of each.
CONTACT_POINTS = (("heel", "heel"), ("ankle", "foot"), ("toe", "toe"))


def contact_joints(motion: Motion, source: str | None = None) -> tuple[tuple[str, ...], np.ndarray]:
    """``(parts, indices (C,))`` of the contact joints: per side the heel (where the rig has
    one), the ankle, and the toe (the toe joint, else the toe tip).

    Found through the rig profile the skeleton fits (:mod:`usdmotion.skeleton_names`), else
    through the segmentation roles (the ankles) and the hierarchy (the toe is the next
    joint down from the ankle, through zero-length links, with the longest bone).

    Raises:
        InputError: no ankles could be found (``source`` names the file).
    """
    from usdmotion.skeleton_names import SIDES, detect_profile, profile_joints, rig_profiles

    index = {n: j for j, n in enumerate(motion.joint_names)}
    profile = detect_profile(motion.joint_names)
    points = {} if profile is None else profile_joints(rig_profiles()[profile], motion.joint_names)
    if not all(f"{s[0]}_foot" in points for s in SIDES):
        points = _feet_from_roles(motion, source)
    parts, indices = [], []
    for side in SIDES:
        for part, point in CONTACT_POINTS:
            name = points.get(f"{side[0]}_{point}") or (points.get(f"{side[0]}_toe_tip") if part == "toe" else None)
            if name is not None:
                parts.append(f"{side}_{part}")
                indices.append(index[name])
    return tuple(parts), np.asarray(indices, np.int64)


def _feet_from_roles(motion: Motion, source: str | None) -> dict[str, str]:
    """``{"l_foot": ankle, "l_toe": next joint down, ...}`` from the segmentation roles."""
    from usdmotion.kinematics import rest_positions
    from usdmotion.ops.segment.roles import find_roles
    from usdmotion.skeleton_names import SIDES, children_map, distal_joint, rest_tolerance

    try:
        roles = find_roles(motion, source=source)
    except InputError as exc:
        raise InputError(source, f"cannot find the feet for contacts: {exc.message}") from None
    rest = rest_positions(motion)
    kids, eps = children_map(motion.parents), rest_tolerance(rest)
    points = {}
    for side in SIDES:
        ankle = roles[f"{side}_ankle"]
        points[f"{side[0]}_foot"] = motion.joint_names[ankle]
        toe = distal_joint(kids, rest, ankle, eps)
        if toe is not None:
            points[f"{side[0]}_toe"] = motion.joint_names[toe]
    return points


# ------------------------------------------------------------------------- detection


def contact_signals(positions: np.ndarray, fps: float, up: str) -> tuple[np.ndarray, np.ndarray]:
    """``(heights (F, C) m, speeds (F, C) m/s)`` of contact-joint positions ``(F, C, 3)`` in metres.

    Speeds are central differences (one-sided at the ends); a single frame has speed 0.
    """
    positions = np.asarray(positions, float)
    heights = positions[..., UP_INDEX[up]]
    if positions.shape[0] < 2:
        return heights, np.zeros(heights.shape)
    velocity = np.gradient(positions, axis=0) * fps
    return heights, np.linalg.norm(velocity, axis=-1)


def estimate_floor(heights: np.ndarray, percentile: float = 2.0) -> float:
    """Ground height (m): the ``percentile`` of the per-frame lowest of ``heights`` ``(F, C)``."""
    return float(np.percentile(np.min(heights, axis=1), percentile))


def planted_clearance(heights: np.ndarray, floor: float, percentile: float = 2.0) -> np.ndarray:
    """``(C,)`` each joint's height above ``floor`` when planted (m): its ``percentile`` height
    minus the floor, at least 0."""
    return np.maximum(np.percentile(heights, percentile, axis=0) - floor, 0.0)


def detect_in_signals(heights: np.ndarray, speeds: np.ndarray, fps: float, thresholds: ContactThresholds,
                      floor: float, clearance: np.ndarray) -> np.ndarray:
    """``(F, C)`` bool contacts from heights (m) and speeds (m/s) ``(F, C)`` (see the module docstring)."""
    above = heights - floor - clearance[None, :]
    enter = (above < thresholds.height_enter) & (speeds < thresholds.speed_enter)
    stay = (above < thresholds.height_exit) & (speeds < thresholds.speed_exit)
    contact = hysteresis(enter, stay)
    min_gap = int(np.ceil(thresholds.min_gap * fps - 1e-9))
    return clean_runs(contact, min_contact_frames(thresholds, fps), min_gap)


def min_contact_frames(thresholds: ContactThresholds, fps: float) -> int:
    """Frames of the shortest contact kept: ``min_duration`` at ``fps``, at least 1."""
    return max(int(np.ceil(thresholds.min_duration * fps - 1e-9)), 1)


def heel_off(contact: np.ndarray, heights: np.ndarray, parts: tuple[str, ...],
             rise: float = HEEL_RISE_M, min_frames: int = 1) -> np.ndarray:
    """``contact (F, C)`` with every heel/ankle contact ended at heel-off (and begun at
    heel-down): the frames at the end (start) of a contact where the joint is more than
    ``rise`` metres above its median height over that contact while the toe of the same
    side (``parts``: ``"left_toe"``...) is planted. ``heights (F, C)`` in metres.

    A contact trimmed below ``min_frames`` frames is dropped, as :func:`clean_runs` drops
    short contacts (the rest of that heel's stance is the toe's alone)."""
    contact = np.array(contact, bool)
    index = {p: c for c, p in enumerate(parts)}
    for c, part in enumerate(parts):
        side, _, kind = part.partition("_")
        toe = index.get(f"{side}_toe")
        if kind not in ("heel", "ankle") or toe is None:
            continue
        for a, b in runs(contact[:, c]):
            up = (heights[a:b, c] - np.median(heights[a:b, c]) > rise) & contact[a:b, toe]
            lead = int(np.argmin(up)) if not up.all() else b - a  # leading frames up (toe-first landing)
            trail = int(np.argmin(up[::-1])) if not up.all() else b - a  # trailing frames up (heel-off)
            contact[a:a + lead, c] = False
            contact[max(a + lead, b - trail):b, c] = False
    return contact & (_run_lengths(contact) >= min_frames)


def check_floor_below_feet(heights: np.ndarray, floor: float, up_axis: str, source: str | None,
                           what: str = "floor height") -> None:
    """Refuse a floor (m) above the contact joints in every frame: the whole take would stand in
    it (``--floor 1e20`` counted every frame as penetrating, exit 0). One below them is fine:
    the planted clearance takes it up. ``heights``: ``(F, C)`` m (:func:`contact_signals`)."""
    lowest_at_most = float(heights.min(axis=1).max())
    if floor > lowest_at_most:
        raise InputError(source, f"{what} {floor:g} m is above the feet in every frame (their lowest point "
                                 f"reaches at most {lowest_at_most:.3f} m, up axis {up_axis})")


def detect_contacts(motion: Motion, *, floor: float | None = None, thresholds: ContactThresholds | None = None,
                    joints: tuple[str, ...] | None = None, source: str | None = None) -> FootContacts:
    """Foot contacts of ``motion`` (see the module docstring for the rule).

    Args:
        motion: any rig whose feet can be found (:func:`contact_joints`).
        floor: ground height along the motion's up axis in metres (default: estimated).
        thresholds: detector thresholds (default :class:`ContactThresholds()`).
        joints: contact joint names instead of the recognised ones (parts ``"joint"``).
        source: file name for error messages.

    Raises:
        InputError: no feet found, an unknown joint in ``joints``, a non-finite ``floor``.
    """
    thresholds = thresholds or ContactThresholds()
    if joints is not None:
        missing = [n for n in joints if n not in motion.joint_names]
        if missing or not joints:
            raise InputError(source, f"contact joints: no joint named {missing[0]!r}" if missing
                             else "contact joints: none given")
        parts, indices = tuple("joint" for _ in joints), np.array([motion.joint_index(n) for n in joints])
    else:
        parts, indices = contact_joints(motion, source)
    if floor is not None and not np.isfinite(floor):
        raise InputError(source, f"floor height must be a finite number of metres, got {floor!r}")
    positions = joint_positions(motion)[:, indices] * motion.meters_per_unit
    heights, speeds = contact_signals(positions, motion.fps, motion.up_axis)
    if floor is not None:
        check_floor_below_feet(heights, floor, motion.up_axis, source)
    floor = estimate_floor(heights, thresholds.floor_percentile) if floor is None else float(floor)
    clearance = planted_clearance(heights, floor, thresholds.floor_percentile)
    contact = detect_in_signals(heights, speeds, motion.fps, thresholds, floor, clearance)
    contact = heel_off(contact, heights, parts, min_frames=min_contact_frames(thresholds, motion.fps))
    return FootContacts(tuple(motion.joint_names[i] for i in indices), indices, parts, contact, floor, clearance,
                        motion.up_axis, float(motion.fps), thresholds)


def contacts_on_rig(contacts: FootContacts, motion: Motion, *, floor: float | None = None,
                    clearance: str | np.ndarray = "rest", source: str | None = None) -> FootContacts:
    """The same contact frames on another rig's heel/ankle/toe joints (e.g. a retargeting target),
    matched by part (``left_ankle``...); parts the other rig lacks are dropped.

    Args:
        contacts: contacts of the source motion (same frames as ``motion``'s).
        motion: the other rig (its animation is used only by ``clearance="motion"``).
        floor: its floor height in metres (default: ``contacts.floor``).
        clearance: planted clearances (m) of the kept parts: ``"rest"`` (default) from the
            rig's rest pose, which must stand upright on flat feet: each contact joint's rest
            height above the lowest of them, plus the source's smallest clearance;
            ``"motion"``: estimated from ``motion``'s own animation like :func:`detect_contacts`
            does (its percentile height above ``floor``; a result that floats throughout
            then looks planted); or an array ``(C',)``.

    Raises:
        InputError: no part in common, or a wrong number of clearances.
    """
    from usdmotion.kinematics import rest_positions

    parts, indices = contact_joints(motion, source)
    where = {p: k for k, p in enumerate(parts)}
    keep = [c for c, p in enumerate(contacts.parts) if p in where]
    if not keep:
        raise InputError(source, f"no contact joint in common (source {', '.join(contacts.parts)}; "
                                 f"target {', '.join(parts)})")
    target = np.array([indices[where[contacts.parts[c]]] for c in keep], np.int64)
    floor = contacts.floor if floor is None else float(floor)
    if isinstance(clearance, str) and clearance == "rest":
        heights = rest_positions(motion)[target, UP_INDEX[motion.up_axis]] * motion.meters_per_unit
        clearance = heights - heights.min() + float(contacts.clearance.min(initial=0.0))
    elif isinstance(clearance, str) and clearance == "motion":
        heights = joint_positions(motion)[:, target, UP_INDEX[motion.up_axis]] * motion.meters_per_unit
        clearance = planted_clearance(heights, floor, (contacts.thresholds or ContactThresholds()).floor_percentile)
    elif isinstance(clearance, str):
        raise ValueError(f"clearance must be 'rest', 'motion' or an array, got {clearance!r}")
    clearance = np.asarray(clearance, float)
    if clearance.shape != (len(keep),):
        raise InputError(source, f"{len(keep)} contact joints in common but {clearance.size} clearances given")
    return FootContacts(tuple(motion.joint_names[i] for i in target), target, tuple(contacts.parts[c] for c in keep),
                        contacts.contact[:, keep], floor, clearance,
                        motion.up_axis, contacts.fps, contacts.thresholds)

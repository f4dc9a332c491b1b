"""Foot contacts in the retargeting solve: which target joints are held, where and when.

From the source's :class:`~usdmotion.ops.contacts.FootContacts` (metres, source frame)
to arrays in the target's frame and units (the solver's, before centring):

* each source contact joint → the target joint mapped to it (contacts of source joints
  that no target joint follows are dropped);
* the **leg-length ratio** ``k`` = target / source length of the chains from the top
  mapped joint (the hips) down to the contact joints (target bone lengths after step 1;
  source bones scaled to target units);
* with ``root_scale="legs"`` the root trajectory is scaled by ``k`` about the hips'
  ground point in the first frame (height above the floor scaled too) and every other
  target moves with it, so strides fit the target's legs; the targets of the **legs**
  (mapped joints on the chains from the hips to the contact joints, and below those)
  are also scaled by ``k`` about the hips, so a planted foot's own target lies on its
  fixed point instead of ``(k − 1)`` times the hip height above the floor (the two
  terms then pull the foot apart and the stance foot drifts between them);
* during every contact interval the target contact joint is pulled to one fixed point:
  horizontally the mean of the source joint's position over the interval (scaled about
  the same ground point when the root is), vertically its planted level
  ``floor + k · clearance`` (never below :data:`ABOVE_FLOOR_M`), the clearance being the
  source joint's median height over its contact frames (:func:`stance_clearance`); a toe's
  fixed point is then moved to a foot's length from its ankle's (:func:`foot_length_apart`);
  once the plain solve is there, an ankle's level becomes its median stance height in that
  solve (:func:`solved_ankle_levels`: how high an ankle stands over its toe is the target
  foot's), its toe's fixed point moved again;
* the legs then meet these points analytically (:mod:`usdmotion.ops.retarget.leg_ik`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from usdmotion.kinematics import rest_arrays
from usdmotion.ops.contacts.detect import UP_INDEX, FootContacts, runs
from usdmotion.ops.retarget.hierarchy import ancestor_matrix

ROOT_SCALES = ("off", "legs")
#: Smallest height (m) above the floor at which a contact joint is planted.
ABOVE_FLOOR_M = 0.001


@dataclass(frozen=True, eq=False)
class ContactTerms:
    """Contact data of one retargeting, in target units and frame (not centred).

    Attributes:
        joints: ``(C,)`` target contact joints.
        planted: ``(F, C, 3)`` the fixed point of each contact interval on its frames (the
            root-scaled source elsewhere).
        level: ``(C,)`` planted level of each contact joint on the up axis (target units).
        floor: floor height on the target's up axis (target units): the contacts' floor, or
            lower where the source's toe tips go lower (:func:`tips_floor`).
        up: index of the up axis.
        leg_ratio: ``k``, target / source leg length.
        shift: ``(F, J, 3)`` translation added to each target joint's source position (root
            and leg scaling; zeros when off).
        root_shift: ``(F, 3)`` the root's part of it (what the anchor's translation moves by).
        target_contacts: the contacts restated for the target rig (indices, floor in metres,
            clearances ``k`` times the source's) — what the metrics of the result use.
        dropped: source contact joints no target joint follows.
    """

    joints: np.ndarray
    planted: np.ndarray
    level: np.ndarray
    floor: float
    up: int
    leg_ratio: float
    shift: np.ndarray
    root_shift: np.ndarray
    target_contacts: FootContacts
    dropped: tuple[str, ...]


def _chain_length(parents: np.ndarray, lengths: np.ndarray, joint: int, top: int) -> float | None:
    """Summed bone lengths from ``joint`` up to (not including) its ancestor ``top``; None if not below it."""
    total, j = 0.0, int(joint)
    while j != top:
        if j < 0:
            return None
        total += float(lengths[j])
        j = int(parents[j])
    return total


def leg_ratio(setup, source, s: float, contact_sources: np.ndarray, contact_targets: np.ndarray) -> float:
    """Target / source summed length of the chains from the top mapped joint to the contact joints."""
    top = setup.top
    src_top = int(setup.source_of[top]) if setup.source_of[top] >= 0 else -1
    target_len = np.linalg.norm(setup.offsets, axis=1)
    source_len = np.linalg.norm(source.offsets, axis=1) * s
    if source.joint_translations is not None:
        source_len = np.linalg.norm(source.joint_translations, axis=-1).mean(axis=0) * s
    t_sum = s_sum = 0.0
    for js, jt in zip(contact_sources, contact_targets):
        lt = _chain_length(setup.rig.parents, target_len, jt, top)
        ls = _chain_length(source.parents, source_len, js, src_top) if src_top >= 0 else None
        if lt and ls:
            t_sum, s_sum = t_sum + lt, s_sum + ls
    return t_sum / s_sum if s_sum > 0 else 1.0


def contact_terms(setup, source, contacts: FootContacts, root_scale: str = "off") -> ContactTerms | None:
    """The contact arrays of ``setup`` (a :class:`~usdmotion.ops.retarget.pipeline.Setup`)
    for the source's ``contacts``; ``None`` when no contact joint is followed by the target."""
    if root_scale not in ROOT_SCALES:
        raise ValueError(f"root_scale must be one of {ROOT_SCALES}, got {root_scale!r}")
    rig = setup.rig
    up = UP_INDEX[rig.up_axis]
    s = setup.scale
    to_target = {int(o): j for j, o in enumerate(setup.source_of) if o >= 0 and setup.weights[j] > 0}
    keep = [c for c, idx in enumerate(contacts.indices) if int(idx) in to_target]
    dropped = tuple(contacts.joints[c] for c in range(len(contacts.joints)) if c not in keep)
    if not keep:
        return None
    src_idx = np.asarray(contacts.indices)[keep]
    joints = np.array([to_target[int(i)] for i in src_idx], np.int64)
    floor = contacts.floor / source.meters_per_unit * s  # the up coordinate survives the Y/Z-up turn
    k = leg_ratio(setup, source, s, src_idx, joints)
    n_frames = setup.targets.shape[0]
    # source positions of the contact joints, target frame and units
    src_pos = _source_positions(setup, source, src_idx)
    root_shift = np.zeros((n_frames, 3))
    shift = np.zeros((n_frames, setup.rig.n_joints, 3))
    centre = _root_ground(setup, floor, up)
    kh = 1.0
    if root_scale == "legs":
        kh = k
        root_shift = (k - 1.0) * (centre - centre[0] * _horizontal(up))
        shift[:] = root_shift[:, None]
        legs = leg_joints(setup, joints)
        hips = centre.copy()
        hips[:, up] += floor
        shift[:, legs] += (k - 1.0) * (setup.targets[:, legs] - hips[:, None])
    contact = np.asarray(contacts.contact)[:, keep]
    clearance = np.asarray(contacts.clearance)[keep] / source.meters_per_unit * s
    clearance = np.maximum(clearance, stance_clearance(src_pos[..., up] - floor, contact))
    # (C,) planted level of each target contact joint; a joint planted on the floor itself (the
    # lowest one, clearance 0) is held a hair above it
    level = np.maximum(floor + k * clearance, floor + ABOVE_FLOOR_M / rig.meters_per_unit)
    origin = centre[0] * _horizontal(up)
    scaled = origin + kh * (src_pos - origin)  # (F, C, 3) the source joints, root-scaled
    scaled[..., up] = floor + k * (src_pos[..., up] - floor)
    planted = scaled.copy()  # during contact: the interval's mean horizontally, its level vertically
    for c in range(len(keep)):
        for a, b in runs(contact[:, c]):
            planted[a:b, c] = scaled[a:b, c].mean(axis=0)
    planted[..., up] = np.where(contact, level[None], planted[..., up])
    planted = foot_length_apart(setup, joints, contact, planted, up)
    lowest = min(floor, tips_floor(setup, joints, floor, k, up))
    restated = replace(contacts, joints=tuple(rig.joint_names[j] for j in joints), indices=joints,
                       parts=tuple(contacts.parts[c] for c in keep), contact=np.asarray(contacts.contact)[:, keep],
                       floor=float(lowest * rig.meters_per_unit), clearance=(level - lowest) * rig.meters_per_unit,
                       up=rig.up_axis)
    return ContactTerms(joints, planted, level, float(lowest), up, float(k), shift, root_shift,
                        restated, dropped)




def stance_clearance(heights: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """``(C,)`` each joint's median height above the floor over its contact frames
    (``heights (F, C)``, ``contact (F, C)``; 0 for a joint without contacts)."""
    return np.array([np.median(heights[contact[:, c], c]) if contact[:, c].any() else 0.0
                     for c in range(heights.shape[1])])


def solved_ankle_levels(setup, terms: ContactTerms, world: np.ndarray) -> ContactTerms:
    """``terms`` with every ankle's planted level (a contact joint with another contact joint
    below it: its toe) at its median height over its contact frames in ``world`` ``(F, J, 3)``,
    the plain solve's joint positions (never below the floor's :data:`ABOVE_FLOOR_M`), and
    its toes' fixed points moved to a foot's length from it again (:func:`foot_length_apart`).

    How high an ankle stands over a planted toe is a property of the target's foot (its
    bones and their rest directions), not of the source's: ``k`` times the source's stance
    height put Mixamo's ankles 1.1 cm below where the plain solve stands them, and the legs
    bent their knees by that much.

    An ankle without a toe (no contact joint below it) is planted no lower than the joints
    below it (its foot's End Site, a forefoot) reach beyond it along its shin in the target's
    rest pose (how far they hang under it when the shin stands upright): the Biovision example
    rig's End Site is a sole point 8.8 cm straight under the ankle, and at the CMU walk's
    3.6 cm ankle height it lay under the floor, where the foot was turned to lift it about an
    axis that its near-vertical bone did not fix (foot steps of 100°/frame)."""
    anc = ancestor_matrix(setup.rig.parents)
    contact = np.asarray(terms.target_contacts.contact, bool)
    ankles = [c for c, j in enumerate(terms.joints) if anc[j, terms.joints].any()]
    toeless = [c for c, (j, part) in enumerate(zip(terms.joints, terms.target_contacts.parts))
               if part.endswith("_ankle") and c not in ankles and anc[j].any() and contact[:, c].any()]
    if not ankles and not toeless:
        return terms
    level = terms.level.copy()
    heights = world[:, terms.joints, terms.up]
    floor_min = terms.floor + ABOVE_FLOOR_M / setup.rig.meters_per_unit
    solved = stance_clearance(heights, contact)
    for c in ankles:
        if contact[:, c].any():
            level[c] = max(solved[c], floor_min)
    if toeless:
        rest = rest_arrays(setup.offsets, setup.rig.parents)[1]
        for c in toeless:
            j = terms.joints[c]
            shin = rest[j] - rest[setup.rig.parents[j]]
            reach = (rest[anc[j]] - rest[j]) @ (shin / max(np.linalg.norm(shin), 1e-300))
            level[c] = max(level[c], floor_min + float(reach.max()))
    planted = terms.planted.copy()
    planted[..., terms.up] = np.where(contact, level[None], planted[..., terms.up])
    planted = foot_length_apart(setup, terms.joints, contact, planted, terms.up)
    restated = replace(terms.target_contacts,
                       clearance=(level - terms.floor) * setup.rig.meters_per_unit)
    return replace(terms, planted=planted, level=level, target_contacts=restated)


def foot_length_apart(setup, joints: np.ndarray, contact: np.ndarray, planted: np.ndarray, up: int) -> np.ndarray:
    """``planted (F, C, 3)`` with every toe contact's fixed point moved along the line from
    its ankle's fixed point (horizontally) to the distance the target's foot allows
    between their planted levels.

    Each fixed point is the mean of its own contact, and the toe's contact starts and ends
    later than the ankle's, so the two means are rarely a foot's length apart (3–4 mm off
    on the CMU walk): both held, the foot cannot lie on both and the stance foot drifts
    between them. The ankle's point is kept; the toe's follows it."""
    anc = ancestor_matrix(setup.rig.parents)
    rest = rest_arrays(setup.offsets, setup.rig.parents)[1]
    planted = planted.copy()
    for t, toe in enumerate(joints):
        ankles = [a for a, j in enumerate(joints) if anc[j, toe]]
        if not ankles:
            continue
        a = ankles[-1]  # the nearest contact joint above the toe
        length = np.linalg.norm(rest[toe] - rest[joints[a]])
        for start, stop in runs(contact[:, t]):
            both = np.flatnonzero(contact[start:stop, a]) + start
            if not both.size:
                continue
            ankle = planted[both[len(both) // 2], a]
            apart = planted[start, t] - ankle
            apart[up] = 0.0
            rise = planted[start, t, up] - ankle[up]
            norm = np.linalg.norm(apart)
            if norm > 0 and length > abs(rise):
                point = ankle + apart * (np.sqrt(length ** 2 - rise ** 2) / norm)
                point[up] = planted[start, t, up]
                planted[start:stop, t] = point
    return planted




def tips_floor(setup, contact_joints: np.ndarray, floor: float, k: float, up: int, percentile: float = 2.0) -> float:
    """The floor as the mapped joints below the contact joints (toe tips) see it: the
    ``percentile`` of their per-frame lowest source height (target units; heights above
    ``floor`` scaled by ``k`` like the fixed points), or ``floor`` without such joints.

    The contacts' floor is estimated from the heel/ankle/toe joints; a source's toe tips go
    lower (up to 0.6 units on the CMU walk, 6.5 cm on 86_01), and a floor above them made
    the result turn every toe up where its tip was "below" it (flips of the toes)."""
    below = ancestor_matrix(setup.rig.parents)[contact_joints].any(axis=0)
    tips = np.intersect1d(np.flatnonzero(below), setup.mapped)
    if tips.size == 0:
        return floor
    lowest = np.percentile(setup.targets[:, tips, up].min(axis=1), percentile)
    return float(floor + k * (lowest - floor))


def leg_joints(setup, contact_joints: np.ndarray) -> np.ndarray:
    """Mapped joints below the top mapped joint that are ancestors-or-self of a contact
    joint or descendants of one (hip, knee, ankle, toe and their End Sites)."""
    anc = ancestor_matrix(setup.rig.parents)
    on_chain = (anc | np.eye(setup.rig.n_joints, dtype=bool))[:, contact_joints].any(axis=1)
    below = anc[contact_joints].any(axis=0)
    legs = (on_chain | below) & anc[setup.top]
    return np.intersect1d(np.flatnonzero(legs), setup.mapped)


def _horizontal(up: int) -> np.ndarray:
    h = np.ones(3)
    h[up] = 0.0
    return h


def _root_ground(setup, floor: float, up: int) -> np.ndarray:
    """``(F, 3)`` the hips' (top mapped joint's) source position with its height taken above the floor."""
    top = setup.top
    mapped = setup.mapped
    centre = setup.targets[:, top] if top in set(mapped.tolist()) else setup.targets[:, mapped].mean(axis=1)
    centre = centre.copy()
    centre[:, up] -= floor
    return centre


def _source_positions(setup, source, indices: np.ndarray) -> np.ndarray:
    """``(F, C, 3)`` source joint positions in the target's frame and units (as the targets)."""
    out = np.zeros((setup.targets.shape[0], len(indices), 3))
    for c, idx in enumerate(indices):
        j = int(np.flatnonzero(setup.source_of == idx)[0])
        out[:, c] = setup.targets[:, j]
    return out

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
  target moves with it, so strides fit the target's legs;
* during every contact interval the target contact joint is pulled to one fixed point:
  horizontally the mean of the source joint's position over the interval (scaled about
  the same ground point when the root is), vertically its planted level
  ``floor + k · clearance`` (the target's ankle sits ``k`` times as high as the source's);
* every target joint is kept above the floor (a one-sided term);
* between contacts the contact joint follows its (root-scaled) source position plus an
  offset blended linearly from the end of one contact's fixed point to the start of the
  next (footskate clean-up, Kovar et al. 2002), at :data:`SWING_SHARE` of the weight, so
  it never jumps onto or off a fixed point.

Weights (per unit² of target length; the mapped joints weigh 1): :data:`CONTACT_WEIGHT`
for a planted joint, :data:`FLOOR_WEIGHT` per unit² below the floor.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from usdmotion.ops.contacts.detect import UP_INDEX, FootContacts
from usdmotion.ops.retarget.hierarchy import ancestor_matrix

#: Weight of a planted contact joint's distance to its fixed point (mapped joints: 1).
CONTACT_WEIGHT = 100.0
#: Weight of a joint's depth below the floor (one-sided).
FLOOR_WEIGHT = 1000.0
ROOT_SCALES = ("off", "legs")
#: Between contacts the contact joint follows the source plus an offset blended from the
#: end of one contact to the start of the next, with this share of the contact weight, so
#: a foot never jumps onto or off its fixed point.
SWING_SHARE = 0.1


@dataclass(frozen=True, eq=False)
class ContactTerms:
    """Contact data of one retargeting, in target units and frame (not centred).

    Attributes:
        joints: ``(C,)`` target contact joints.
        weights: ``(F, C)`` weight per frame (:data:`CONTACT_WEIGHT` during contact, else 0).
        targets: ``(F, C, 3)`` fixed point of each contact interval (0 outside contacts).
        floor: floor height on the target's up axis (target units).
        up: index of the up axis.
        leg_ratio: ``k``, target / source leg length.
        shift: ``(F, 3)`` translation added to the source's targets (root scaling; zeros when off).
        target_contacts: the contacts restated for the target rig (indices, floor in metres,
            clearances ``k`` times the source's) — what the metrics of the result use.
        dropped: source contact joints no target joint follows.
    """

    joints: np.ndarray
    weights: np.ndarray
    targets: np.ndarray
    floor: float
    up: int
    leg_ratio: float
    shift: np.ndarray
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


def contact_terms(setup, source, contacts: FootContacts, root_scale: str = "off",
                  contact_weight: float = CONTACT_WEIGHT) -> ContactTerms | None:
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
    shift = np.zeros((n_frames, 3))
    centre = _root_ground(setup, floor, up)
    kh = 1.0
    if root_scale == "legs":
        kh = k
        shift = (k - 1.0) * (centre - centre[0] * _horizontal(up))
    clearance = np.asarray(contacts.clearance)[keep] / source.meters_per_unit * s
    level = floor + k * clearance  # (C,) planted level of each target contact joint
    weights = np.zeros((n_frames, len(keep)))
    targets = np.zeros((n_frames, len(keep), 3))
    origin = centre[0] * _horizontal(up)
    for c, col in enumerate(keep):
        scaled = origin + kh * (src_pos[:, c] - origin)  # the source joint, root-scaled
        scaled[:, up] = floor + k * (src_pos[:, c, up] - floor)
        intervals = contacts.intervals(col)
        if not len(intervals):
            continue
        points = np.array([scaled[a:b].mean(axis=0) for a, b in intervals])
        points[:, up] = level[c]
        # offsets of the fixed points from the source at each contact's first and last frame,
        # blended linearly over the frames between contacts (footskate clean-up)
        keys = np.stack([intervals[:, 0], intervals[:, 1] - 1], axis=1).ravel()
        offs = np.stack([points - scaled[intervals[:, 0]], points - scaled[intervals[:, 1] - 1]], axis=1)
        offs = offs.reshape(-1, 3)
        frames = np.arange(n_frames)
        blended = np.stack([np.interp(frames, keys, offs[:, i]) for i in range(3)], axis=1)
        targets[:, c] = scaled + blended
        weights[:, c] = SWING_SHARE * contact_weight
        for (a, b), point in zip(intervals, points):
            targets[a:b, c] = point
            weights[a:b, c] = contact_weight
    restated = replace(contacts, joints=tuple(rig.joint_names[j] for j in joints), indices=joints,
                       parts=tuple(contacts.parts[c] for c in keep), contact=np.asarray(contacts.contact)[:, keep],
                       floor=float(floor * rig.meters_per_unit), clearance=k * clearance * rig.meters_per_unit,
                       up=rig.up_axis)
    return ContactTerms(joints, weights, targets, float(floor), up, float(k), shift, restated, dropped)


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


def moved_joints(setup) -> np.ndarray:
    """Joints that some optimised rotation or translation moves (the floor term's points)."""
    sub = ancestor_matrix(setup.rig.parents) | np.eye(setup.rig.n_joints, dtype=bool)
    moved = sub[setup.rot_joints].any(axis=0) | sub[setup.trans_joints].any(axis=0)
    return np.flatnonzero(moved)

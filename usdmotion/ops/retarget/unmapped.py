"""Rotations of the target joints that no source joint drives, and continuity over time.

The solver moves only joints that move a mapped joint; the others follow a documented
rule (docs/retarget.md, *Unmapped joints*), applied to the solved local rotations
``(F, J, 4)`` of the target, all frames at once:

* **floor root bone** — an unmapped root above the top mapped joint (Character
  Creator's ``RL_BoneRoot``, Unreal's ``root``): follows the hips' ground projection and
  heading (the twist of the hips' world rotation about the up axis); the joints below
  keep their world transforms;
* **twist bones** — unmapped leaves whose name contains ``twist`` (``CC_Base_L_ForearmTwist01``,
  ``lowerarm_twist_01_l``): take the share ``s`` of the twist, about their parent's bone,
  of the parent's next bone (the forearm twist bones share the hand's twist), ``s`` being
  how far along the parent's bone they sit (0 at its start, 1 at the child);
* **others** keep their rest pose relative to their parent (identity local rotation).

:func:`continuous_hemisphere` flips quaternion signs so consecutive frames of every
joint lie in the same hemisphere (``q`` and ``−q`` are the same rotation; writers and
interpolators see no sign jumps).
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import fk_arrays
from usdmotion.rotations import quat_conjugate, quat_mul, quat_normalize, quat_rotate


def continuous_hemisphere(q: np.ndarray) -> np.ndarray:
    """``(F, J, 4)`` quaternions with ``q(f) · q(f−1) ≥ 0`` for every joint (signs only)."""
    if q.shape[0] < 2:
        return q.copy()
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.concatenate([np.ones((1,) + q.shape[1:-1]), np.where(dots < 0, -1.0, 1.0)], axis=0)
    return q * np.cumprod(flips, axis=0)[..., None]


def twist_about(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Signed twist angles (radians, ``(...)``) of quaternions ``q (..., 4)`` about unit ``axis (3,)``
    (swing-twist decomposition)."""
    along = q[..., 1:] @ axis
    return 2.0 * np.arctan2(along, q[..., 0])


def _children(parents: np.ndarray) -> list[list[int]]:
    kids = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            kids[p].append(j)
    return kids


def twist_bones(names, parents: np.ndarray, offsets: np.ndarray, driven: np.ndarray,
                end_sites: np.ndarray) -> list[tuple[int, int, float, np.ndarray]]:
    """``(twist bone, driver child, share s, unit bone axis)``: unmapped, undriven leaves (or
    chains of such) named ``*twist*`` under a parent with one non-twist child on the body."""
    kids = _children(parents)
    out = []
    for j, name in enumerate(names):
        if "twist" not in name.lower() or driven[j] or end_sites[j] or parents[j] < 0:
            continue
        p = parents[j]
        others = [c for c in kids[p] if "twist" not in names[c].lower() and not end_sites[c]
                  and np.linalg.norm(offsets[c]) > 1e-9]
        if len(others) != 1:
            continue
        child = others[0]
        length = np.linalg.norm(offsets[child])
        axis = offsets[child] / length
        share = float(np.clip(offsets[j] @ axis / length, 0.0, 1.0))
        out.append((j, child, share, axis))
    return out


def distribute_twist(q: np.ndarray, rows) -> np.ndarray:
    """Local rotations with every twist bone of ``rows`` (:func:`twist_bones`) turned by its
    share of its driver's twist about the parent's bone axis."""
    q = q.copy()
    for j, child, share, axis in rows:
        angle = share * twist_about(q[:, child], axis)
        q[:, j] = np.concatenate([np.cos(angle / 2)[:, None], np.sin(angle / 2)[:, None] * axis[None]], axis=1)
    return q


def heading(world_q: np.ndarray, up: int) -> np.ndarray:
    """``(F, 4)`` rotations about the up axis: the twist of ``world_q (F, 4)`` about it."""
    h = np.zeros(world_q.shape)
    h[:, 0] = world_q[:, 0]
    h[:, 1 + up] = world_q[:, 1 + up]
    norm = np.linalg.norm(h, axis=-1, keepdims=True)
    return np.where(norm > 1e-9, h / np.maximum(norm, 1e-300), np.array([1.0, 0, 0, 0]))


def floor_root(q: np.ndarray, t: np.ndarray, parents: np.ndarray, top: int, floor: float, up: int,
               top_translates: bool) -> tuple[np.ndarray, np.ndarray]:
    """Put an unmapped root bone (joint 0, above ``top``) under the hips: rotated by the
    hips' heading, at their ground projection (``floor`` height) when ``top`` has its own
    translation, else wherever keeps the hips in place. Every joint below keeps its world
    transform. ``q (F, J, 4)`` local rotations, ``t (F, J, 3)`` local translations (root: world)."""
    q, t = q.copy(), t.copy()
    world_q, world_p = fk_arrays(q, t, parents)
    h = continuous_hemisphere(heading(world_q[:, top], up)[:, None])[:, 0]
    chain = [top]
    while parents[chain[-1]] > 0:
        chain.append(int(parents[chain[-1]]))
    # joints between the root and top stay unrotated: the top's parent frame is the root's
    q[:, 0] = h
    q[:, top] = quat_normalize(quat_mul(quat_conjugate(h), world_q[:, top]))
    if top_translates:
        ground = world_p[:, top].copy()
        ground[:, up] = floor
        t[:, 0] = ground
        above = np.zeros_like(ground)  # world offset root -> top's parent (identity rotations between)
        for j in chain[1:]:
            above += t[:, j]
        t[:, top] = quat_rotate(quat_conjugate(h), world_p[:, top] - ground) - above
    else:
        offset = sum(t[:, j] for j in chain)  # root -> top, in the root's frame
        t[:, 0] = world_p[:, top] - quat_rotate(h, offset)
    return q, t


def unmapped_rules(setup, q: np.ndarray, t: np.ndarray, floor: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The rules above on a solved target (``setup``: a pipeline ``Setup``; ``floor`` in target
    units, default: the 2nd percentile of the lowest joint per frame)."""
    rig = setup.rig
    if setup.mode != "target":
        return q, t
    driven = np.zeros(rig.n_joints, bool)
    driven[setup.mapped] = True
    driven[setup.rot_joints] = True
    q = distribute_twist(q, twist_bones(rig.joint_names, rig.parents, setup.offsets, driven, rig.end_sites))
    if setup.top != 0 and setup.source_of[0] < 0 and 0 not in set(setup.rot_joints.tolist()):
        up = 1 if rig.up_axis == "Y" else 2
        if floor is None:  # the 2nd percentile of the lowest joint per frame
            floor = float(np.percentile(fk_arrays(q, t, rig.parents)[1][..., up].min(axis=1), 2.0))
        q, t = floor_root(q, t, rig.parents, setup.top, floor, up, setup.anchor == setup.top)
    return q, t

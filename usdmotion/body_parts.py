"""What of a skeleton is body: the parts a generated body is meshed in, the joints that get no
flesh, and where the head goes (used by :mod:`usdmotion.skin` and the renderer's stick figure).

* :func:`body_groups`: trunk (0), one group per limb (the subtree above each knee and
  elbow, by name), ``NO_BODY`` (-1) for joints above the pelvis (a floor root, a static
  origin joint) and for helper joints (:data:`NOT_BODY`: twist, IK, props).
* :func:`head_joint`: the joint the head hangs on, also for rigs without a head joint.
* :func:`facing`: the front of a pose, from its left and right limbs.

Topology-sized loops only (over joints, never frames).
"""

from __future__ import annotations

import re

import numpy as np

from usdmotion.motion import Motion, subtree_indices
from usdmotion.skeleton_names import ELBOW_WORDS, KNEE_WORDS, common_ancestor, parse_side


#: Joints that are not body segments (twist and roll bones, IK targets and poles, helpers,
#: props): pattern on the lower-cased name without ``prefix:``. Such a joint gets no
#: capsule when nothing but other such joints (or end sites) hangs below it.
NOT_BODY = re.compile(r"twist|roll|(^|[_.\- ])ik|ik($|[_.\- ])|[a-z]ik$|helper|pole|target|prop|weapon|sword|"
                      r"gun|null|dummy|ctrl|control|socket|attach|nub$")

#: Radius (fraction of ``H``) the trunk's capsules taper to where they end at the neck
#: or at a sided joint (collar, shoulder, hip): shoulders and neck base, not a dome.
TRUNK_END_RADIUS = 0.045

#: Groups of :func:`body_groups`: no surface (above the pelvis, helpers), trunk and head.
NO_BODY, TRUNK = -1, 0


def body_groups(motion: Motion) -> np.ndarray:
    """Body part of every joint ``(J,)`` int: which surface the bones it drives join.

    * ``TRUNK`` (0): pelvis, spine, neck, head, collar bones;
    * ``1, 2, …``: one per limb: the subtree of the joint above each knee or elbow
      (``LeftUpLeg``, ``lfemur``, ``LeftArm``, ``rShldr``…; names read by
      :func:`usdmotion.skeleton_names.parse_side`), so a limb is meshed on its own
      and never webbed to the other leg or to the trunk;
    * ``NO_BODY`` (-1): the joints strictly above the pelvis (the common ancestor of the
      legs: a root bone at the floor, a static origin joint) and helper joints
      (:data:`NOT_BODY`) with only helpers or end sites below them.
    """
    parents = motion.parents
    n = motion.n_joints
    groups = np.zeros(n, np.int64)
    limb_roots, legs = [], []
    for j, name in enumerate(motion.joint_names):  # topology-sized
        side, base = parse_side(name)
        p = int(parents[j])
        if side is None or p < 0 or motion.end_sites[j]:
            continue
        if base in KNEE_WORDS or base in ELBOW_WORDS:
            if parse_side(motion.joint_names[p])[0] == side and p not in limb_roots:
                limb_roots.append(p)
                if base in KNEE_WORDS:
                    legs.append(p)
    for k, root in enumerate(sorted(limb_roots)):
        groups[subtree_indices(parents, root)] = k + 1
    if len(legs) >= 2:
        pelvis = common_ancestor(parents, legs[0], legs[1])
        above = parents[pelvis]
        while above >= 0:
            groups[above] = NO_BODY
            above = parents[above]
    helper = np.array([bool(NOT_BODY.search(name.rsplit(":", 1)[-1].lower())) for name in motion.joint_names])
    only_helpers = helper | motion.end_sites
    for j in range(n - 1, 0, -1):  # children after parents: one backward pass
        if not only_helpers[j] and parents[j] >= 0:
            only_helpers[parents[j]] = False
    groups[helper & only_helpers] = NO_BODY
    return groups


#: Head of :func:`usdmotion.skin.bone_capsules`, fractions of the skeleton size ``H``: radius, default
#: height above the head joint (skull base to crown) and the accepted range of heights
#: read from the rig's own head-top joint or End Site.
HEAD_RADIUS, HEAD_HEIGHT, HEAD_HEIGHT_RANGE = 0.05, 0.12, (0.07, 0.2)


def head_joint(motion: Motion, groups: np.ndarray | None = None) -> int | None:
    """The joint the head hangs on: the shallowest trunk joint named ``head`` (not a head
    top or end), else the deepest side-less trunk joint with no trunk joint below it (the
    top of the neck of a rig without a head, ASF ``Neck``, if the rig has limbs); else None."""
    groups = body_groups(motion) if groups is None else groups
    parents = motion.parents
    depth = np.zeros(motion.n_joints, int)
    for j in range(1, motion.n_joints):  # topology-sized
        depth[j] = depth[parents[j]] + 1 if parents[j] >= 0 else 0
    trunk = (groups == TRUNK) & ~motion.end_sites
    named = [j for j in np.flatnonzero(trunk) if re.search(r"head(?!.*(top|end|nub))",
                                                            motion.joint_names[j].rsplit(":", 1)[-1].lower())]
    if named:
        return int(min(named, key=lambda j: depth[j]))
    if groups.max(initial=0) < 2:  # no limbs: no body to put a head on
        return None
    has_trunk_child = np.zeros(motion.n_joints, bool)
    has_trunk_child[parents[np.flatnonzero(trunk)[1:]]] = True
    tops = [j for j in np.flatnonzero(trunk & ~has_trunk_child) if parse_side(motion.joint_names[j])[0] is None
            and parents[j] >= 0]
    return int(max(tops, key=lambda j: depth[j])) if tops else None


def facing(motion: Motion, rest: np.ndarray, groups: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """Unit front direction ``(3,)`` of the bind pose (``left × up``), from the left and
    right limb roots; None when the rig has no sided limbs."""
    sides = {"left": [], "right": []}
    for g in range(1, int(groups.max(initial=0)) + 1):
        root = int(np.flatnonzero(groups == g)[0])
        side = parse_side(motion.joint_names[root])[0]
        if side in sides:
            sides[side].append(rest[root])
    if not sides["left"] or not sides["right"]:
        return None
    left = np.mean(sides["left"], axis=0) - np.mean(sides["right"], axis=0)
    front = np.cross(left, up)
    n = float(np.linalg.norm(front))
    return front / n if n > 0 else None


def tree_distance(parents: np.ndarray) -> np.ndarray:
    """Number of edges between every pair of joints ``(J, J)`` (topology only)."""
    n = len(parents)
    depth = np.zeros(n, int)
    ancestors = np.eye(n, dtype=bool)
    for j in range(1, n):  # topology, O(J²) booleans
        depth[j] = depth[parents[j]] + 1
        ancestors[j] = ancestors[parents[j]]
        ancestors[j, j] = True
    common = (ancestors[:, None, :] & ancestors[None, :, :])
    lca_depth = np.where(common, depth[None, None, :], -1).max(axis=-1)
    return depth[:, None] + depth[None, :] - 2 * lca_depth

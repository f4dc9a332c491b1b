"""Volumetric skinned bodies for any skeleton, and linear blend skinning.

A body is the zero level set of a smooth union of tapered capsules, one per bone,
meshed with marching cubes in the rest pose:

* **Bones.** Every joint ``j`` with a parent ``p`` and a rest bone ``p → j`` of
  positive length gives a capsule driven by ``p`` (the joint whose rotation swings
  it). Bones whose child translates during the motion (a "root" joint carrying the
  world trajectory, Bandai's ``joint_Root → Hips``: moving by more than half the
  bone's length) are not rigid and are skipped.
  Joints that drive no bone of positive length but have children (CMU ``Hips``,
  ``Spine1``) get a *weight-only* sphere so they still move the skin around them;
  leaf joints without an End Site (rigs without End Sites) get a sphere in the
  surface too, so heads and hands are not lost.
* **Radii** come from :data:`PART_RADII`, a body-proportion table in fractions of the
  skeleton's size ``H`` (largest extent of the rest pose), chosen by the *driving*
  joint's name (``LeftUpLeg`` drives the thigh, ``LeftLeg`` the shank; DAZ, Mixamo,
  Bandai, ASF and 3ds Max names are known). Unknown names get a radius from the
  bone's length. Radii never drop below one voxel, so the surface stays closed.
* **Body parts.** :func:`body_groups` splits the skeleton into the trunk (pelvis,
  spine, neck, head) and one group per limb (the subtree above each knee and elbow).
  Joints above the pelvis (a floor root, a static origin joint) and helper joints
  (twist, IK, props: :data:`usdmotion.body_parts.NOT_BODY`) get no capsule. The trunk tapers to
  :data:`TRUNK_END_RADIUS` at the neck, collars and hips; whatever the rig hangs on
  its head joint is replaced by one head (:data:`HEAD_RADIUS`) with a small nose that
  shows the facing direction.
* **Surface.** Per body part, ``f(x) = -k log Σ_b exp(-d_b(x)/k)`` (log-sum-exp smooth
  minimum of the capsule distances ``d_b``), sampled on a grid of ``resolution`` cells
  along ``H`` and meshed by ``skimage.measure.marching_cubes``; each part is a closed
  (watertight) surface of its own, so legs never web together.
* **Weights.** Each vertex takes the signed distance to every joint's capsules of its part;
  ``w ∝ exp(-d/τ)`` keeps the ``INFLUENCES`` largest, normalised to 1.
* **Skinning.** ``v_f = Σ_k w_k · (T_world_j(f) · B_j⁻¹) · v`` with ``B_j`` the rest
  (bind) world transform of joint ``j``: UsdSkel's linear blend skinning, so
  ``UsdSkel.SkinningQuery.ComputeSkinnedPoints`` reproduces it.

Everything is in the motion's file units and axes (the skeleton space of its USD).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.kinematics import compose_transforms, fk_arrays, local_translations, rest_pose
from usdmotion.motion import Motion, subtree_indices
from usdmotion.skeleton_names import parse_side
from usdmotion.body_parts import (HEAD_HEIGHT, HEAD_HEIGHT_RANGE, HEAD_RADIUS, NO_BODY, TRUNK, TRUNK_END_RADIUS,
                                  tree_distance, body_groups, facing, head_joint)

#: Influences (joints) per vertex; UsdSkel's ``elementSize`` of the skinning primvars.
INFLUENCES = 4

#: Body-proportion table: (pattern on the driving joint's lower-cased name without any
#: ``prefix:``, radius at the bone's start, radius at its end), radii in fractions of
#: the skeleton size ``H``. First match wins. Shaped after adult anthropometric
#: circumferences (thigh ≈ 0.30 H, waist ≈ 0.45 H, upper arm ≈ 0.17 H) and rounded.
PART_RADII: tuple[tuple[str, float, float], ...] = (
    (r"eye|jaw|tongue|teeth", 0.0, 0.0),              # inside the head: no volume of their own
    (r"thumb|index|middle|ring|pinky|little|finger(?!base)|carpal", 0.008, 0.007),
    (r"hipjoint|buttock", 0.055, 0.048),              # pelvis: centre → hip joint
    (r"^(hips?|pelvis|root)$|^joint_root$", 0.07, 0.065),
    (r"head", 0.058, 0.05),
    (r"neck", 0.03, 0.028),
    (r"collar|clavicle|shoulder", 0.042, 0.036),
    (r"forearm|lowerarm|radius|elbow", 0.025, 0.019),
    (r"shldr|uparm|upperarm|humerus|arm$|arm_[lr]$|^[lr]arm", 0.031, 0.026),
    (r"hand|wrist|palm|fingerbase", 0.018, 0.014),
    (r"upleg|upperleg|thigh|femur|hip", 0.052, 0.036),
    (r"toe", 0.021, 0.017),
    (r"foot|ankle", 0.025, 0.021),
    (r"leg|shin|knee|calf|tibia", 0.036, 0.025),
    (r"spine|chest|back|abdomen|torso|thorax|waist|belly", 0.075, 0.075),
)

#: Radius of a bone with an unknown name: this fraction of its length, clipped to
#: ``[0.012 H, 0.05 H]``.
DEFAULT_RADIUS_PER_LENGTH = 0.2


@dataclass(frozen=True)
class Capsules:
    """Tapered capsules ``(B,)``: segment ``start → end`` with radii ``r0 → r1``.

    ``joint`` is the driving joint of each capsule; ``solid`` marks those that are part
    of the surface (the others only attract skin weights); ``group`` is the body part
    (:func:`body_groups`: 0 trunk and head, then one per limb) whose surface it joins.
    """

    start: np.ndarray
    end: np.ndarray
    r0: np.ndarray
    r1: np.ndarray
    joint: np.ndarray
    solid: np.ndarray
    group: np.ndarray

    def subset(self, keep: np.ndarray) -> Capsules:
        """The capsules selected by the boolean or index array ``keep``."""
        return Capsules(*(getattr(self, f)[keep] for f in ("start", "end", "r0", "r1", "joint", "solid", "group")))


@dataclass(frozen=True)
class Body:
    """A closed triangle mesh skinned to a skeleton, in the rest (bind) pose.

    Attributes:
        vertices: ``(V, 3)`` rest-pose positions, file units (skeleton space).
        faces: ``(T, 3)`` int32 vertex indices, counter-clockwise seen from outside.
        normals: ``(V, 3)`` unit vertex normals, pointing out.
        joint_indices: ``(V, INFLUENCES)`` int32 joints influencing each vertex.
        joint_weights: ``(V, INFLUENCES)`` weights, each row sums to 1.
        bind_transforms: ``(J, 4, 4)`` rest world transforms ``B_j`` (column vectors).
        size: the skeleton size ``H`` (file units) the radii were scaled by.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    joint_indices: np.ndarray
    joint_weights: np.ndarray
    bind_transforms: np.ndarray
    size: float

    @property
    def n_joints(self) -> int:
        return int(self.bind_transforms.shape[0])

    def weight_matrix(self) -> np.ndarray:
        """Dense ``(V, J)`` weights (zero where a joint does not influence a vertex)."""
        w = np.zeros((len(self.vertices), self.n_joints))
        np.add.at(w, (np.arange(len(self.vertices))[:, None], self.joint_indices), self.joint_weights)
        return w


def _part(name: str) -> int | None:
    key = name.rsplit(":", 1)[-1].lower()
    for k, (pattern, _, _) in enumerate(PART_RADII):
        if re.search(pattern, key):
            return k
    return None


_CLAVICLE = next(k for k, p in enumerate(PART_RADII) if p[0].startswith("collar"))
_UPPER_ARM = next(k for k, p in enumerate(PART_RADII) if p[0].startswith("shldr"))


def _part_radii(name: str, parent_name: str | None = None) -> tuple[float, float] | None:
    """``(r0, r1)`` fractions of ``H`` for the bone driven by joint ``name`` (None: unknown).

    A "shoulder" below a collar is the upper arm (3ds Max CMU: LeftCollar → LeftShoulder).
    """
    k = _part(name)
    if k is None:
        return None
    if k == _CLAVICLE and parent_name is not None and _part(parent_name) == _CLAVICLE:
        k = _UPPER_ARM
    return PART_RADII[k][1], PART_RADII[k][2]


rest_world = rest_pose  # ``(rotations (J,4), positions (J,3))`` of the rest (bind) pose


def bind_transforms(motion: Motion) -> np.ndarray:
    """Rest world transforms ``(J, 4, 4)``: the Skeleton's ``bindTransforms`` in USD."""
    return compose_transforms(*rest_world(motion))


def body_size(motion: Motion) -> float:
    """Skeleton size ``H``: the largest extent of the rest pose (file units)."""
    extent = float(np.ptp(rest_world(motion)[1], axis=0).max(initial=0.0))
    return extent if extent > 0 else 1.0


def bone_capsules(motion: Motion, thickness: float = 1.0, positions: np.ndarray | None = None) -> Capsules:
    """The capsules of :func:`build_body` (see the module notes), radii × ``thickness``.

    ``positions (J, 3)``: world joint positions of the pose to build around (default: rest).
    """
    rest = rest_world(motion)[1] if positions is None else positions
    size = body_size(motion)
    parents = motion.parents
    groups = body_groups(motion)
    child = np.arange(1, motion.n_joints)
    parent = parents[child]
    length = np.linalg.norm(rest[child] - rest[parent], axis=1)
    moving = np.ptp(local_translations(motion)[:, child], axis=0).max(axis=1) if motion.n_frames else 0 * length
    rigid = moving <= 0.5 * np.maximum(length, 0.05 * size)  # stretching marker-driven bones stay
    body = (groups[parent] != NO_BODY) & (groups[child] != NO_BODY)
    bone = (length > 1e-6 * size) & rigid & body
    names = motion.joint_names
    table = [_part_radii(names[p], names[parents[p]] if p > 0 else None) for p in parent]
    default = np.clip(DEFAULT_RADIUS_PER_LENGTH * length / size, 0.012, 0.05)
    r0 = np.array([t[0] if t else d for t, d in zip(table, default)]) * size * thickness
    r1 = np.array([t[1] if t else d for t, d in zip(table, default)]) * size * thickness
    # the trunk narrows to the neck and to the shoulder and hip joints (no dome over them)

    to_limb = np.array([groups[p] == TRUNK and (parse_side(names[c])[0] is not None
                                                or "neck" in names[c].rsplit(":", 1)[-1].lower())
                        for p, c in zip(parent, child)], bool)
    r1 = np.where(to_limb, np.minimum(r1, TRUNK_END_RADIUS * size * thickness), r1)
    drives = np.zeros(motion.n_joints, bool)
    drives[parent[bone]] = True  # zero-radius parts (eyes, jaw) drive nothing visible and get no sphere
    has_children = np.zeros(motion.n_joints, bool)
    has_children[parent] = True
    rigid_child = np.zeros(motion.n_joints, bool)
    rigid_child[parent[rigid & body]] = True
    no_volume = np.array([(_part_radii(n) or (1.0,))[0] == 0 for n in names])
    # a sphere for every joint that drives no bone of positive length but moves rigid children
    # (CMU Hips, Spine1; Bandai Head with a zero-length End Site) or is a leaf without End Site
    point = np.flatnonzero(~drives & ~no_volume & ~motion.end_sites & (rigid_child | ~has_children)
                           & (groups != NO_BODY))
    leaf = np.ones(len(point), bool)
    point_r = _point_radii(motion, point, leaf, rest, bone, child, parent, r0, r1, size * thickness)
    keep = bone & (r0 > 0)
    caps = Capsules(
        start=np.concatenate([rest[parent[keep]], rest[point]]),
        end=np.concatenate([rest[child[keep]], rest[point]]),
        r0=np.concatenate([r0[keep], point_r]),
        r1=np.concatenate([r1[keep], point_r]),
        joint=np.concatenate([parent[keep], point]).astype(np.int32),
        solid=np.concatenate([np.ones(int(keep.sum()), bool), leaf & (point_r > 0)]),
        group=np.concatenate([groups[parent[keep]], groups[point]]).astype(np.int32),
    )
    return _with_head(motion, caps, rest, groups, size * thickness)


def _with_head(motion: Motion, caps: Capsules, rest: np.ndarray, groups: np.ndarray, scale: float) -> Capsules:
    """Replace whatever the rig hangs on its head joint (head-top joints, eyes, jaw, a
    zero-length End Site's sphere) by one head: a capsule of :data:`HEAD_RADIUS` along the
    neck's direction from the head joint to the crown, and a small nose in front of it so
    the picture shows which way the body faces (front: ``left × up`` of the bind pose)."""
    head = head_joint(motion, groups)
    if head is None or motion.parents[head] < 0:
        return caps
    below = subtree_indices(motion.parents, head)
    up = rest[head] - rest[motion.parents[head]]
    if np.linalg.norm(up) < 1e-9 * scale:
        return caps
    up = up / np.linalg.norm(up)
    reach = ((rest[below] - rest[head]) @ up).max()
    lo, hi = HEAD_HEIGHT_RANGE
    height = reach if lo * scale <= reach <= hi * scale else HEAD_HEIGHT * scale
    radius = HEAD_RADIUS * scale
    keep = ~np.isin(caps.joint, below)
    start = rest[head] + up * min(radius, 0.5 * height)
    end = rest[head] + up * max(height - radius, 0.5 * height)
    parts = [caps.subset(keep)]
    nose = facing(motion, rest, groups, up)
    extra_start, extra_end, extra_r = [start], [end], [radius]
    if nose is not None:
        centre = 0.5 * (start + end)
        extra_start.append(centre + nose * 0.85 * radius - up * 0.15 * radius)
        extra_end.append(centre + nose * 0.85 * radius - up * 0.15 * radius)
        extra_r.append(0.3 * radius)
    k = len(extra_r)
    parts.append(Capsules(np.array(extra_start), np.array(extra_end), np.array(extra_r), np.array(extra_r),
                          np.full(k, head, np.int32), np.ones(k, bool), np.full(k, TRUNK, np.int32)))
    return Capsules(*(np.concatenate([getattr(c, f) for c in parts])
                      for f in ("start", "end", "r0", "r1", "joint", "solid", "group")))


def _point_radii(motion, point, leaf, rest, bone, child, parent, r0, r1, scale) -> np.ndarray:
    """Radius of the sphere at each joint in ``point``: the largest bone radius touching it
    (or, for leaves, the name table's start radius)."""
    ends = np.concatenate([rest[parent[bone]], rest[child[bone]]])
    radii = np.concatenate([r0[bone], r1[bone]])
    near = np.linalg.norm(rest[point][:, None] - ends[None], axis=-1) < 1e-3 * scale
    touching = np.where(near, radii[None], 0.0).max(axis=1, initial=0.0)
    named = np.array([(_part_radii(motion.joint_names[j]) or (0.02, 0.02))[0] for j in point]) * scale
    return np.where(leaf, np.maximum(named, touching), np.where(touching > 0, touching, 0.03 * scale))


def bind_pose(motion: Motion, candidates: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """``(world_rotations (J,4), world_positions (J,3))`` of the pose to build the body in
    (:func:`bind_frame`: the rest pose or one frame of the motion)."""
    frame = bind_frame(motion, candidates)
    if frame is None:
        return rest_world(motion)
    world_q, world_p = fk_arrays(motion.rotations[[frame]], local_translations(motion)[[frame]], motion.parents)
    return world_q[0], world_p[0]


def bind_frame(motion: Motion, candidates: int = 16) -> int | None:
    """The frame to build the body in, or None for the rest pose.

    The rest pose, unless limbs overlap in it (Bandai's rest pose lies along +X with the
    arms through the torso): then the frame, among the rest pose and ``candidates``
    evenly spaced frames, whose capsules of bones far apart in the tree (≥ 3 joints)
    come closest (with a clearance of 0.04 H). Sampled along each capsule axis (8 points) — a pose choice, not a
    precise distance.
    """
    rest_q, rest_p = rest_world(motion)
    if motion.n_frames == 0:
        return None
    frames = np.unique(np.linspace(0, motion.n_frames - 1, min(candidates, motion.n_frames)).astype(int))
    world_q, world_p = fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)
    poses_q = np.concatenate([rest_q[None], world_q])
    poses_p = np.concatenate([rest_p[None], world_p])
    caps = bone_capsules(motion)
    size = body_size(motion)
    on_joint = np.linalg.norm(caps.end[:, None] - rest_p[None], axis=-1).min(axis=1) < 1e-6 * size
    keep = caps.solid & (np.linalg.norm(caps.end - caps.start, axis=1) > 0) & on_joint  # bones, not the head
    joint = caps.joint[keep]
    # the child joint of each bone: the joint at its end in the rest pose
    child = np.argmin(np.linalg.norm(caps.end[keep][:, None] - rest_p[None], axis=-1), axis=1)
    far = tree_distance(motion.parents)[joint[:, None], joint[None]] >= 3
    clearance = 0.04 * size  # limbs closer than this get bridged by the smooth union
    t = np.linspace(0.0, 1.0, 8)
    samples = poses_p[:, joint, None] + t[None, None, :, None] * (poses_p[:, child] - poses_p[:, joint])[:, :, None]
    radius = caps.r0[keep][:, None] + t[None] * (caps.r1[keep] - caps.r0[keep])[:, None]  # (B, 8)
    scores = []
    for pts in samples:  # one pose at a time: (B, 8, 3)
        d = np.linalg.norm(pts[:, None, :, None] - pts[None, :, None], axis=-1)  # (B, B, 8, 8)
        overlap = np.maximum(radius[:, None, :, None] + radius[None, :, None] + clearance - d, 0.0).max(axis=(2, 3))
        scores.append(float(np.where(far, overlap, 0.0).sum()))
    scores = np.asarray(scores)
    best = 0 if scores[0] <= scores.min() + 0.05 * size else int(np.argmin(scores))
    return None if best == 0 else int(frames[best - 1])


def capsule_distance(points: np.ndarray, caps: Capsules) -> np.ndarray:
    """Signed distance-like value ``(N, B)`` of points to each tapered capsule (< 0 inside).

    The radius is interpolated at the closest point of the axis, a close and smooth
    approximation of the exact round-cone distance for the gentle tapers used here.
    """
    axis = caps.end - caps.start
    length2 = np.maximum(np.einsum("bi,bi->b", axis, axis), 1e-30)
    rel = points[:, None, :] - caps.start[None]
    t = np.clip(np.einsum("nbi,bi->nb", rel, axis) / length2, 0.0, 1.0)
    closest = rel - t[..., None] * axis[None]
    return np.linalg.norm(closest, axis=-1) - (caps.r0 + t * (caps.r1 - caps.r0))


def _smooth_field(points: np.ndarray, caps: Capsules, k: float, chunk: int = 65536) -> np.ndarray:
    """Log-sum-exp smooth minimum of the solid capsules' distances at ``points (N, 3)``."""
    solid = caps.subset(caps.solid)
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):  # memory: chunk × B floats at a time
        d = capsule_distance(points[s:s + chunk], solid)
        dmin = d.min(axis=1)
        out[s:s + chunk] = dmin - k * np.log(np.exp(-(d - dmin[:, None]) / k).sum(axis=1))
    return out


def build_body(motion: Motion, resolution: int = 96, thickness: float = 1.0,
               blend: float = 0.012) -> Body:
    """Mesh and skin a volumetric body around ``motion``'s rest pose.

    Args:
        motion: any skeleton (its frames only tell which joints translate).
        resolution: grid cells along the skeleton size ``H`` (detail of the surface).
        thickness: scale of every radius.
        blend: smoothing radius of the union, fraction of ``H``.

    Raises:
        InputError: the skeleton has no bone of positive length to put a body around.
    """
    pose_q, pose_p = bind_pose(motion)
    caps = bone_capsules(motion, thickness, pose_p)
    if not caps.solid.any():
        raise UsdMotionError("the skeleton has no bone of positive length to build a body around "
                             "(render it with --style stick)")
    size = body_size(motion)
    parts = []
    for group in np.unique(caps.group[caps.solid]):  # trunk, then each limb: meshed on its own
        own = caps.subset(caps.group == group)
        v, f, n = _mesh_surface(own, size, resolution, blend)
        parts.append((v, f, n, *skin_weights(v, own, motion.parents, size)))
    offsets = np.cumsum([0] + [len(p[0]) for p in parts])
    vertices, normals, indices, weights = (np.concatenate([p[k] for p in parts]) for k in (0, 2, 3, 4))
    faces = np.concatenate([p[1] + o for p, o in zip(parts, offsets)]).astype(np.int32)
    return Body(vertices=vertices, faces=faces, normals=normals, joint_indices=indices,
                joint_weights=weights, bind_transforms=compose_transforms(pose_q, pose_p), size=size)


def _mesh_surface(caps: Capsules, size: float, resolution: int, blend: float):
    from skimage.measure import marching_cubes

    voxel = size / max(int(resolution), 8)
    caps = Capsules(caps.start, caps.end, np.maximum(caps.r0, 0.8 * voxel), np.maximum(caps.r1, 0.8 * voxel),
                    caps.joint, caps.solid, caps.group)
    solid = caps.solid
    r = np.maximum(caps.r0, caps.r1)[solid][:, None]
    pad = 3 * voxel + blend * size
    lo = np.minimum(caps.start[solid] - r, caps.end[solid] - r).min(axis=0) - pad
    hi = np.maximum(caps.start[solid] + r, caps.end[solid] + r).max(axis=0) + pad
    shape = np.ceil((hi - lo) / voxel).astype(int) + 1
    axes = [lo[i] + voxel * np.arange(shape[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    field = _smooth_field(grid, caps, blend * size).reshape(shape)
    verts, faces, _, _ = marching_cubes(field.astype(np.float32), level=0.0, spacing=(voxel,) * 3,
                                        gradient_direction="ascent")
    return _clean_mesh(verts.astype(np.float64) + lo, faces)


def _clean_mesh(vertices: np.ndarray, faces: np.ndarray):
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=True)
    mesh.remove_unreferenced_vertices()
    if mesh.volume < 0:  # marching cubes winding depends on the gradient direction: make normals point out
        mesh.invert()
    return (np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32),
            np.asarray(mesh.vertex_normals, np.float64))


def skin_weights(vertices: np.ndarray, caps: Capsules, parents: np.ndarray, size: float,
                 falloff: float = 0.012) -> tuple[np.ndarray, np.ndarray]:
    """``(joint_indices (V, 4), joint_weights (V, 4))`` from capsule distances.

    ``d_j``: signed distance of a vertex to joint ``j``'s nearest capsule. Weights
    ``∝ exp(-(d_j - min d) / (falloff · H))`` over the joints at most two edges away in
    the tree from the nearest one (so a hanging arm never pulls the hip skin along); the
    four largest are kept and normalised.
    """
    n_joints = len(parents)
    near_in_tree = tree_distance(parents) <= 2
    idx = np.zeros((len(vertices), INFLUENCES), np.int64)
    top = np.zeros((len(vertices), INFLUENCES))
    k = min(INFLUENCES, n_joints)
    for s in range(0, len(vertices), 16384):  # memory: chunk × capsules floats
        per_capsule = capsule_distance(vertices[s:s + 16384], caps)
        d = np.full((per_capsule.shape[0], n_joints), np.inf)
        np.minimum.at(d.T, caps.joint, per_capsule.T)  # min over each joint's capsules
        nearest = np.argmin(d, axis=1)
        d = np.where(near_in_tree[nearest], d - d.min(axis=1, keepdims=True), np.inf)
        w = np.exp(-d / (falloff * size))
        i = np.argsort(-w, axis=1, kind="stable")[:, :k]
        idx[s:s + 16384, :k] = i
        top[s:s + 16384, :k] = np.take_along_axis(w, i, axis=1)
    top = np.where(top < 1e-4 * top[:, :1], 0.0, top)
    idx = np.where(top > 0, idx, idx[:, :1])  # unused slots repeat the main joint, with weight 0
    return idx.astype(np.int32), top / top.sum(axis=1, keepdims=True)


# ----------------------------------------------------------------------- skinning


def skinning_matrices(world_rotations: np.ndarray, world_positions: np.ndarray,
                      bind: np.ndarray) -> np.ndarray:
    """``T_world_joint · B⁻¹`` as ``(..., J, 3, 4)`` (the last row is always 0 0 0 1)."""
    world = compose_transforms(world_rotations, world_positions)
    return (world @ np.linalg.inv(bind))[..., :3, :]


def lbs(vertices: np.ndarray, weights: np.ndarray, matrices: np.ndarray,
        normals: np.ndarray | None = None):
    """Linear blend skinning of all frames at once.

    Args:
        vertices: ``(V, 3)`` rest positions, or ``(F, V, 3)``: one set per frame (blend shapes applied).
        weights: ``(V, J)`` dense weights (:meth:`Body.weight_matrix`).
        matrices: ``(F, J, 3, 4)`` skinning matrices (:func:`skinning_matrices`).
        normals: optional ``(V, 3)`` rest normals, skinned by the blended linear part.

    Returns: ``(F, V, 3)`` positions, or ``(positions, normals)`` when normals are given.
    """
    n_frames, n_joints = matrices.shape[:2]
    per_joint = np.moveaxis(matrices.reshape(n_frames, n_joints, 12), 1, 0).reshape(n_joints, -1)
    blended = (weights @ per_joint).reshape(len(weights), n_frames, 3, 4)  # one BLAS call
    rest = "vj" if vertices.ndim == 2 else "fvj"  # (F, V, 3): per-frame rest points
    positions = np.einsum(f"vfij,{rest}->fvi", blended[..., :3], vertices) + np.moveaxis(blended[..., 3], 1, 0)
    if normals is None:
        return positions
    skinned = np.einsum("vfij,vj->fvi", blended[..., :3], normals)
    skinned /= np.maximum(np.linalg.norm(skinned, axis=-1, keepdims=True), 1e-12)
    return positions, skinned


def skin_frames(body: Body, motion: Motion, frames: np.ndarray | None = None) -> np.ndarray:
    """Skinned vertex positions ``(F, V, 3)`` of ``body`` at ``frames`` of ``motion``."""
    local_t = local_translations(motion)
    rotations = motion.rotations
    if frames is not None:
        local_t, rotations = local_t[frames], rotations[frames]
    world_q, world_p = fk_arrays(rotations, local_t, motion.parents)
    return lbs(body.vertices, body.weight_matrix(), skinning_matrices(world_q, world_p, body.bind_transforms))


def centre_of_mass(motion: Motion, body: Body, frames: np.ndarray) -> np.ndarray:
    """Centre of the body's volume ``(F, 3)`` at ``frames`` (file units), uniform density.

    Approximated by the volume-weighted centres of the solid capsules the body was
    built from, each moving with its driving joint.
    """
    caps = bone_capsules(motion, positions=body.bind_transforms[:, :3, 3])
    solid = caps.solid
    length = np.linalg.norm(caps.end - caps.start, axis=1)[solid]
    r0, r1 = caps.r0[solid], caps.r1[solid]
    volume = np.pi / 3 * length * (r0 ** 2 + r0 * r1 + r1 ** 2) + np.pi * 2 / 3 * (r0 ** 3 + r1 ** 3)
    centre = np.c_[0.5 * (caps.start + caps.end)[solid], np.ones(int(solid.sum()))]  # homogeneous
    world_q, world_p = fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)
    matrices = skinning_matrices(world_q, world_p, body.bind_transforms)[:, caps.joint[solid]]  # (F, B, 3, 4)
    moved = np.einsum("fbij,bj->fbi", matrices, centre)
    return np.einsum("fbi,b->fi", moved, volume) / volume.sum()

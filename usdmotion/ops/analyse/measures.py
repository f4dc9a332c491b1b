"""Biomechanical kinematics of a motion: joints, segments and the centre of mass.

``analyse(motion)`` returns a :class:`Kinematics` of plain arrays over frames ``F`` and
joints ``J`` (all joints, end sites included), computed for all frames at once.

Conventions (see ``docs/analyze.md``):

* **Lengths** in metres when ``si=True`` (``motion.meters_per_unit`` converts), else in
  file units; time in seconds; angles in degrees.
* **Positions** are the raw world positions (forward kinematics of the file); velocities
  and accelerations are time derivatives of the *filtered* positions
  (:mod:`usdmotion.ops.analyse.smoothing`).
* **Joint angles** (``euler``): the joint's rotation relative to its parent, zero in the
  file's rest pose (OFFSETs, no rotation), decomposed as intrinsic Euler angles in the
  joint's own BVH channel order (or one ``euler_order`` for all). Angles are continuous
  over time (no ±180° wrap) and equal the file's channel values for a BVH. ``bend`` is
  the angle between the bone into the joint (from its nearest distinct ancestor) and the
  bone out of it (to its single distinct child): 0° = straight, e.g. knee flexion;
  undefined (NaN) at the root, leaves and branching joints.
* **Segment orientation**: the joint's world rotation (wxyz quaternion) = orientation of
  the segment (bone) that the joint drives.
* **Angular velocity** from quaternions, never from differentiated Euler angles:
  ``omega_rel`` = of the joint relative to its parent, expressed in the joint's own
  frame (``2 q_local* q̇_local``, the convention of pybvh's ``angular_velocities``);
  local quaternion components are made continuous (no sign flips) and filtered like
  positions; ``alpha_rel`` is the time derivative of ``omega_rel``. ``omega``/``alpha``
  = angular velocity/acceleration of the segment in the world frame, composed exactly
  from the relative rates down the hierarchy (:func:`world_rates`).
* **Centre of mass** from a body-segment model (:mod:`usdmotion.anthropometry`):
  whole-body ``com`` and ``segment_com``; ``momentum`` = body mass × COM velocity (kg·m/s,
  lengths always metres) when a mass is given.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.anthropometry import BodyModel
from usdmotion.errors import InputError
from usdmotion.channels import default_channels, rotation_order
from usdmotion.kinematics import depth_levels, rest_positions, world_rotations_positions
from usdmotion.motion import ROTATION_CHANNELS, Motion
from usdmotion.ops.analyse.smoothing import FilterSpec, smooth_derivatives
from usdmotion.rotations import check_euler_order, closest_equivalent_euler
from usdmotion.skeleton_names import children_map, distal_joints, marked_joints, proximal_joint, rest_tolerance

AXES = ("x", "y", "z")
#: Body masses ``--mass`` accepts (kg): a small child to the heaviest athletes, with margin; a
#: mass outside it is a typo (1e30 kg gave momenta of 2e30 kg m/s, exit 0).
MASS_RANGE_KG = (1.0, 1000.0)


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Kinematics of every joint at every analysed frame (see the module docstring).

    Shapes: ``F`` frames, ``J`` joints, ``S`` body segments. Degrees for angles.
    """

    joint_names: tuple[str, ...]
    end_sites: np.ndarray            # (J,) bool
    fps: float
    first_frame: int                 # index in the source motion of row 0
    length_unit: str                 # "m" or "file units"
    meters_per_unit: float           # of the source file
    up_axis: str
    filter: FilterSpec
    time: np.ndarray                 # (F,) seconds from the source's frame 0
    positions: np.ndarray            # (F, J, 3)
    velocities: np.ndarray           # (F, J, 3)
    accelerations: np.ndarray        # (F, J, 3)
    orientations: np.ndarray         # (F, J, 4) world wxyz
    euler: np.ndarray                # (F, J, 3) deg, columns = X, Y, Z angles
    euler_orders: tuple[str, ...]    # (J,) intrinsic order of each joint's decomposition
    bend: np.ndarray                 # (F, J) deg, NaN where undefined
    omega: np.ndarray                # (F, J, 3) deg/s, world frame
    alpha: np.ndarray                # (F, J, 3) deg/s^2, world frame
    omega_rel: np.ndarray            # (F, J, 3) deg/s, joint frame, relative to parent
    alpha_rel: np.ndarray            # (F, J, 3) deg/s^2
    body: BodyModel | None = None
    com: np.ndarray | None = None            # (F, 3)
    com_velocity: np.ndarray | None = None   # (F, 3)
    com_acceleration: np.ndarray | None = None
    segment_com: np.ndarray | None = None    # (F, S, 3)
    mass: float | None = None                # kg
    momentum: np.ndarray | None = None       # (F, 3) kg m/s
    notes: tuple[str, ...] = field(default=())

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def frames(self) -> np.ndarray:
        """Source frame index of every row ``(F,)``."""
        return self.first_frame + np.arange(self.n_frames)

    @property
    def up_index(self) -> int:
        return 1 if self.up_axis == "Y" else 2


def slice_frames(motion: Motion, start: int = 0, stop: int | None = None) -> Motion:
    """Frames ``start:stop`` of a motion, keeping ``source_channels`` (the Euler hint)."""
    return motion.sliced(start, stop)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cross product of component-first vectors ``(3, ...)``."""
    return np.stack([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]])


def angular_rates(q: np.ndarray, q_dot: np.ndarray, q_ddot: np.ndarray,
                  body: bool) -> tuple[np.ndarray, np.ndarray]:
    """Angular velocity and acceleration (rad/s, rad/s²) from a smooth quaternion path.

    Arrays are component-first: ``q (4, ...)`` wxyz and its time derivatives; results
    ``(3, ...)``. ``q`` need not be unit (a filtered path is not): with ``n = |q|²``,
    world ``ω = 2 vec(q̇ q*)/n``, body ``ω = 2 vec(q* q̇)/n``, and
    ``α = 2 vec(q̈ q*)/n − ω · 2(q·q̇)/n`` (body: ``q* q̈``), the exact derivative of ``ω``
    (``vec(q̇ q̇*) = 0``).
    """
    n = np.sum(q * q, axis=0)
    w, v = q[0], q[1:]
    sign = -1.0 if body else 1.0

    def rate(d: np.ndarray) -> np.ndarray:
        return 2.0 * (w * d[1:] - d[0] * v + sign * _cross(v, d[1:])) / n

    omega = rate(q_dot)
    alpha = rate(q_ddot) - omega * (2.0 * np.sum(q * q_dot, axis=0) / n)
    return omega, alpha


def _rotate_cf(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate component-first vectors ``v (3, ...)`` by unit wxyz ``q (4, ...)``:
    ``v + 2w (u × v) + 2 u × (u × v)`` with ``u`` the vector part."""
    w, u = q[0], q[1:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def world_rates(world_q: np.ndarray, omega_rel: np.ndarray, alpha_rel: np.ndarray,
                parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World angular velocity and acceleration of every segment from the relative rates
    (each in its joint's own frame), summed down the tree:

    ``ω_j = ω_parent + R_j ω_rel,j`` and ``α_j = α_parent + ω_j × (R_j ω_rel,j) + R_j α_rel,j``
    (``R_j`` = world rotation of joint ``j``; ``d/dt (R_j v) = ω_j × R_j v + R_j v̇``).

    Component-first arrays: ``world_q (4, J, F)``, rates ``(3, J, F)``; returns two
    ``(3, J, F)``. One step per depth level, all frames at once.
    """
    u = _rotate_cf(world_q, omega_rel)
    w = _rotate_cf(world_q, alpha_rel)
    levels = depth_levels(parents)
    omega = np.empty_like(u)
    for idx, _ in levels:
        parent = parents[idx]
        omega[:, idx] = u[:, idx] if parent[0] < 0 else omega[:, parent] + u[:, idx]
    w += _cross(omega, u)
    alpha = np.empty_like(w)
    for idx, _ in levels:
        parent = parents[idx]
        alpha[:, idx] = w[:, idx] if parent[0] < 0 else alpha[:, parent] + w[:, idx]
    return omega, alpha


_EVEN_ORDERS = ("XYZ", "YZX", "ZXY")


def quat_to_euler_fast(q: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic Euler angles ``(..., 3)`` radians of unit wxyz quaternions ``(..., 4)``.

    Closed form on the five rotation-matrix entries needed (``R = R_i(a) R_j(b) R_k(c)``:
    ``b = asin(s R[i,k])``, ``a = atan2(−s R[j,k], R[k,k])``, ``c = atan2(−s R[i,j], R[i,i])``,
    ``s = ±1`` for even/odd orders); several times faster than SciPy's general method.
    """
    i, j, k = ("XYZ".index(a) for a in order)
    s = 1.0 if order in _EVEN_ORDERS else -1.0
    w, x, y, z = (q[..., n] for n in range(4))

    def entry(r: int, c: int) -> np.ndarray:
        v = (w, x, y, z)
        if r == c:
            others = [1 + m for m in range(3) if m != r]
            return 1.0 - 2.0 * (v[others[0]] ** 2 + v[others[1]] ** 2)
        third = 3 - r - c
        cyclic = (c - r) % 3 == 1
        return 2.0 * (v[1 + r] * v[1 + c] + (-1.0 if cyclic else 1.0) * v[0] * v[1 + third])

    b = np.arcsin(np.clip(s * entry(i, k), -1.0, 1.0))
    a = np.arctan2(-s * entry(j, k), entry(k, k))
    c = np.arctan2(-s * entry(i, j), entry(i, i))
    return np.stack([a, b, c], axis=-1)


def euler_angles(motion: Motion, order: str | None = None) -> tuple[np.ndarray, tuple[str, ...]]:
    """Joint angles ``(F, J, 3)`` degrees (columns X, Y, Z) and each joint's Euler order.

    ``order=None``: each joint's BVH channel order (``ZXY`` where the motion has no
    channel layout); the equivalent triple closest to the file's channel values is
    chosen, so a BVH's angles come back exactly. Otherwise one intrinsic order for all
    joints. Without file values, angles are unwrapped over time (continuous, may pass
    ±180°). End sites get zeros and order ``""``.
    """
    layout = motion.channels or default_channels(motion)
    file_layout = motion.channels
    if order is not None:
        order = check_euler_order(order)
    starts = np.cumsum([0] + [len(c) for c in layout])
    orders, groups = [], {}
    for j, names in enumerate(layout):
        rotates = any(n in ROTATION_CHANNELS for n in names) or (order is not None and not motion.end_sites[j])
        joint_order = (order or rotation_order(names)) if rotates else ""
        orders.append(joint_order)
        if joint_order:
            groups.setdefault(joint_order, []).append(j)
    out = np.zeros((motion.n_frames, motion.n_joints, 3))
    source = motion.source_channels
    for group_order, joints in groups.items():
        angles = quat_to_euler_fast(motion.rotations[:, joints], group_order)  # (F, G, 3)
        reference = None
        if source is not None and file_layout is not None and source.shape[1] == starts[-1]:
            cols = np.array([[starts[j] + layout[j].index(f"{a}rotation") if f"{a}rotation" in layout[j] else -1
                              for a in group_order] for j in joints])  # (G, 3)
            if order is None or all(rotation_order(layout[j]) == group_order for j in joints):
                reference = np.deg2rad(np.where(cols >= 0, source[:, np.maximum(cols, 0)], 0.0))
        if reference is not None:
            angles = closest_equivalent_euler(angles, reference)
        else:
            angles = np.unwrap(angles, axis=0)
        axis_of = ["XYZ".index(a) for a in group_order]
        out[:, np.asarray(joints)[:, None], np.asarray(axis_of)[None, :]] = np.degrees(angles)
    return out, tuple(orders)


def _body_distal(kids: dict, rest: np.ndarray, joint: int, eps: float, marked: dict[int, str]) -> list[int]:
    """:func:`distal_joints` without marked bones, through twist segments in the chain
    (Rigify's ``DEF-shin.L`` → ``DEF-shin.L.001`` → ``DEF-foot.L``)."""
    out = []
    for k in distal_joints(kids, rest, joint, eps):
        if k not in marked:
            out.append(k)
        elif marked[k] == "twist":
            out += _body_distal(kids, rest, k, eps, marked)
    return out


def bend_triples(motion: Motion) -> np.ndarray:
    """``(K, 3)`` rows ``(joint, proximal, distal)`` for joints with a defined bend angle.

    The twist, root and helper bones that a recognised rig's profile marks are left out,
    as joints and as distal candidates (a knee with calf-twist children still has a bend).
    """
    rest = rest_positions(motion)
    eps = rest_tolerance(rest)
    kids = children_map(motion.parents)
    marked = marked_joints(motion.joint_names)  # twist, root and helper bones of a recognised rig
    rows = []
    for j in range(motion.n_joints):  # topology only, O(J)
        if motion.end_sites[j] or j in marked:
            continue
        before = proximal_joint(motion.parents, rest, j, eps)
        after = _body_distal(kids, rest, j, eps, marked)
        if before is not None and len(after) == 1:
            rows.append((j, before, after[0]))
    return np.asarray(rows, dtype=np.int64).reshape(-1, 3)


def bend_angles(positions: np.ndarray, triples: np.ndarray, n_joints: int) -> np.ndarray:
    """Bend angles ``(F, J)`` in degrees (NaN where undefined) from world positions."""
    out = np.full(positions.shape[:1] + (n_joints,), np.nan)
    if len(triples):
        j, a, b = triples.T
        into = positions[:, j] - positions[:, a]
        out_of = positions[:, b] - positions[:, j]
        cos = np.sum(into * out_of, axis=-1) / np.maximum(
            np.linalg.norm(into, axis=-1) * np.linalg.norm(out_of, axis=-1), 1e-300)
        out[:, j] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def _check_finite(motion: Motion, source: str | None) -> None:
    for name in ("rotations", "root_translation", "joint_translations", "offsets"):
        a = getattr(motion, name)
        if a is not None and not np.all(np.isfinite(a)):
            bad = np.argwhere(~np.isfinite(a))[0]
            where = f"frame {bad[0]}" if name != "offsets" else f"joint {motion.joint_names[bad[0]]}"
            raise InputError(source, f"non-finite value (NaN or inf) in {name.replace('_', ' ')} at {where}")


def analyse(motion: Motion, filter: FilterSpec = FilterSpec(), euler_order: str | None = None,
            body: BodyModel | None = None, mass: float | None = None, si: bool = True,
            first_frame: int = 0, source: str | None = None) -> Kinematics:
    """Kinematics of ``motion`` (see the module docstring for every convention).

    Args:
        motion: the motion (all its frames are analysed; slice first with
            :func:`slice_frames`, passing the slice start as ``first_frame``).
        filter: smoothing used for every time derivative.
        euler_order: one intrinsic Euler order for all joint angles, or ``None`` for each
            joint's own channel order.
        body: a body-segment model (:func:`usdmotion.anthropometry.body_model`) for the
            centre of mass; ``None`` skips it.
        mass: body mass in kg, for the linear momentum.
        si: lengths in metres (else file units).
        source: file name for error messages.

    Raises:
        InputError: non-finite values in the motion, fewer than 2 frames, or a bad mass.
        ValueError: bad filter options.
    """
    _check_finite(motion, source)
    if motion.n_frames < 2:
        raise InputError(source, f"{motion.n_frames} frame(s): velocities need at least 2")
    if mass is not None and not (np.isfinite(mass) and MASS_RANGE_KG[0] <= mass <= MASS_RANGE_KG[1]):
        raise InputError(source, f"--mass must be a body mass between {MASS_RANGE_KG[0]:g} and {MASS_RANGE_KG[1]:g} kg, "
                                 f"got {mass:g}")
    fps = motion.fps
    filter.check(fps)
    world_q, world_p = world_rotations_positions(motion)
    positions = world_p * (motion.meters_per_unit if si else 1.0)
    n_frames, n_joints = positions.shape[:2]
    rot = np.flatnonzero(~np.asarray(motion.end_sites))  # end sites have no rotation of their own
    # every signal as one (channels, frames) array, time last: positions and local quaternions
    stacked = np.concatenate([
        np.moveaxis(positions, 0, -1).reshape(-1, n_frames),
        # (4, F, R) sign-continuous in time -> (R, 4, F)
        np.transpose(Q.align_signs(Q.gather_c(motion.rotations, rot), axis=1), (2, 0, 1)).reshape(-1, n_frames),
    ])
    smooth, d1, d2 = smooth_derivatives(stacked, fps, filter, axis=-1)
    n_pos = 3 * n_joints
    rates = _rates(smooth[n_pos:], d1[n_pos:], d2[n_pos:], world_q, rot, motion.parents)

    def per_joint(a: np.ndarray) -> np.ndarray:  # (3J, F) -> (F, J, 3), a view
        return np.moveaxis(a[:n_pos].reshape(n_joints, 3, n_frames), -1, 0)

    euler, orders = euler_angles(motion, euler_order)
    kin = Kinematics(
        joint_names=motion.joint_names, end_sites=np.asarray(motion.end_sites), fps=fps, first_frame=first_frame,
        length_unit="m" if si else "file units", meters_per_unit=motion.meters_per_unit, up_axis=motion.up_axis,
        filter=filter, time=(first_frame + np.arange(n_frames)) / fps,
        positions=positions, velocities=per_joint(d1), accelerations=per_joint(d2), orientations=world_q,
        euler=euler, euler_orders=orders, bend=bend_angles(positions, bend_triples(motion), n_joints), **rates)
    if body is not None:
        kin = _with_com(kin, body, mass, motion.meters_per_unit if not si else 1.0)
    return kin


def _rates(quat: np.ndarray, quat_dot: np.ndarray, quat_ddot: np.ndarray, world_q: np.ndarray, rot: np.ndarray,
           parents: np.ndarray) -> dict[str, np.ndarray]:
    """Relative and world angular velocity/acceleration, deg/s and deg/s², ``(F, J, 3)``.

    ``quat*``: the filtered local quaternions of the rotating joints ``rot`` and their
    derivatives, ``(4R, F)`` (joint-major, time last).
    """
    n_frames, n_joints = world_q.shape[:2]

    def component_first(a: np.ndarray) -> np.ndarray:  # (4R, F) -> (4, R, F)
        return np.moveaxis(a.reshape(len(rot), 4, n_frames), 1, 0)

    def all_joints(a: np.ndarray) -> np.ndarray:  # (3, R, F) -> (3, J, F), zero for end sites
        out = np.zeros((3, n_joints, n_frames))
        out[:, rot] = a
        return out

    omega_rel, alpha_rel = (all_joints(a) for a in angular_rates(
        component_first(quat), component_first(quat_dot), component_first(quat_ddot), body=True))
    world_cf = np.ascontiguousarray(np.moveaxis(world_q, (0, 1, 2), (2, 1, 0)))  # (4, J, F)
    omega, alpha = world_rates(world_cf, omega_rel, alpha_rel, parents)

    def frames_first(a: np.ndarray) -> np.ndarray:  # (3, J, F) -> (F, J, 3) degrees, a view
        return np.moveaxis(np.degrees(a, out=a), (0, 1, 2), (2, 1, 0))

    return {"omega": frames_first(omega), "alpha": frames_first(alpha), "omega_rel": frames_first(omega_rel),
            "alpha_rel": frames_first(alpha_rel)}


def _with_com(kin: Kinematics, body: BodyModel, mass: float | None, to_metres: float) -> Kinematics:
    """Add COM, segment COMs and momentum (linear maps of the joint arrays)."""
    com_v = body.com(kin.velocities)
    momentum = None if mass is None else mass * com_v * to_metres
    return dataclasses.replace(kin, body=body, com=body.com(kin.positions), com_velocity=com_v,
                               com_acceleration=body.com(kin.accelerations),
                               segment_com=body.segment_coms(kin.positions), mass=mass, momentum=momentum,
                               notes=kin.notes + body.notes)


def select_joints(kin: Kinematics, joints: list[str] | None, source: str | None = None) -> list[int]:
    """Indices of ``joints`` (all joints when ``None``); unknown names raise ``InputError``."""
    if not joints:
        return list(range(len(kin.joint_names)))
    index = []
    for name in joints:
        if name not in kin.joint_names:
            import difflib

            close = difflib.get_close_matches(name, kin.joint_names, n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise InputError(source, f"no joint named {name!r}{hint}")
        index.append(kin.joint_names.index(name))
    return index

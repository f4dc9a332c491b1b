"""Planted feet by analytic leg IK: the last step of the contact-aware solve.

The position-matching solve (LM, all frames) gives a body whose stance feet slide; this
module makes each leg meet its contacts exactly, as production retargeters do, over all
frames at once in float64 NumPy (no per-frame loop):

1. **Where each foot must be** (:func:`foot_targets`), per leg (hip → knee → ankle → toe):
   during an ankle contact the ankle sits on the contact's fixed point
   (:class:`~usdmotion.ops.retarget.contact_terms.ContactTerms` ``planted``); during a
   toe-only contact (after heel-off) the foot pivots about the toe's fixed point with the
   solved foot's direction, corrected towards the flat foot's at the heel's side and
   blended out by the contact's other end (so the ankle never jumps); between contacts
   the joint follows the solve plus an offset blended linearly from one contact to the next
   (footskate clean-up, Kovar et al. 2002), faded out over :data:`FADE_S` from the nearer
   contact. No target lies below the joint's planted level.
2. **Reach**: where a foot planted flat (ankle and toe down) lies beyond the leg's length
   from the solved hip, the root comes down (:func:`~usdmotion.ops.retarget.leg_reach.root_drop`)
   by the least amount that reaches it, smoothed over ``leg_reach.DROP_WINDOW_S`` (a running
   maximum, then a moving mean of it: never less than needed, never a step). A held ankle
   target still out of reach from the lowered hip is raised (only the ankle down: straight
   up; with the toe down: by turning the foot about the toe's point — the heel lifts).
3. **Two-bone IK** (:func:`place_legs`): the knee stays in the plane of the solved leg (its
   bend direction, plus a little of the knee's hinge, which decides where the solved leg
   is nearly straight: :func:`knee_hinge_bend`), the hip
   and knee turn by the shortest rotations that put knee and ankle where the triangle
   says; the foot keeps its solved world rotation turned by the shortest rotation that
   aims it at the toe's target. Every other joint keeps the solve's rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.kinematics import fk_arrays
from usdmotion.ops.contacts.detect import runs
from usdmotion.ops.retarget.hierarchy import ancestor_matrix, restricted_parents, with_ancestors
from usdmotion.ops.retarget.leg_reach import REACH, leg_reach, lower_root, root_drop, with_hip_spikes
from usdmotion.rotations import cross, quat_conjugate, quat_mul, quat_normalize, quat_rotate
from usdmotion.skeleton_names import descendants

#: Weight of the foot's heading (per unit of bone length) in the direction a toe End Site
#: below the floor is lifted in (see :func:`toes_above_floor`).
HEADING_SHARE = 0.02
#: Seconds over which a contact's offset fades out into the swing (see :func:`_follow`).
FADE_S = 0.2
#: Moving a contact's fixed point (:func:`within_reach`): the joints it moves per frame of
#: the contact (ankle, knee, toe and the blends around the contact), the farthest move as a
#: share of the leg's reach, and the grid's steps on each side.
SHIFT_WEIGHT = 4.0
SHIFT_REACH = 0.05
SHIFT_STEPS = 20
#: Weight of the knee's hinge (per unit of thigh length) in its bend direction: it decides
#: only where the solved leg is nearly straight (see :func:`knee_hinge_bend`).
HINGE_SHARE = 0.1


@dataclass(frozen=True)
class Leg:
    """One leg of the target rig: joints and the columns of its contact joints.

    Attributes:
        hip, knee, ankle: target joints (the ankle's parent and grandparent above it).
        toe: target joint below the ankle with a toe contact, or -1.
        ankle_c, toe_c: their columns in the contact arrays (``toe_c`` -1 without a toe).
    """

    hip: int
    knee: int
    ankle: int
    toe: int
    ankle_c: int
    toe_c: int


def legs_of(parents: np.ndarray, joints: np.ndarray, parts, offsets: np.ndarray, top: int) -> list[Leg]:
    """The legs whose ankle contact joint has a parent and grandparent below ``top`` with
    bones of non-zero length (others are left to the solve)."""
    index = {p: c for c, p in enumerate(parts)}
    legs = []
    for c, part in enumerate(parts):
        side, _, kind = part.partition("_")
        if kind != "ankle":
            continue
        ankle = int(joints[c])
        knee = int(parents[ankle])
        hip = int(parents[knee]) if knee >= 0 else -1
        if hip < 0 or hip not in descendants(parents, top) or min(np.linalg.norm(offsets[[ankle, knee]], axis=1)) <= 0:
            continue
        toe_c = index.get(f"{side}_toe", -1)
        toe = int(joints[toe_c]) if toe_c >= 0 else -1
        if toe >= 0 and toe not in descendants(parents, ankle):
            toe, toe_c = -1, -1
        legs.append(Leg(hip, knee, ankle, toe, c, toe_c))
    return legs


def _interp_rows(frames: np.ndarray, known: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``(F, 3)`` linear interpolation over frames of ``values (K, 3)`` known at ``known (K,)``
    (held constant beyond the ends; zeros when nothing is known)."""
    if known.size == 0:
        return np.zeros((frames.size, 3))
    return np.stack([np.interp(frames, known, values[:, i]) for i in range(3)], axis=1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def foot_targets(world_p: np.ndarray, leg: Leg, planted: np.ndarray, contact: np.ndarray, level: np.ndarray,
                 up: int, reach: float, fade: float = 0.0) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``(ankle target (F, 3), toe target (F, 3) or None, held (F,))`` of one leg (see the
    module docstring); ``held``: the frames on which the ankle target is a contact's.

    Where a held ankle target lies beyond the leg's reach from the solved hip, it is raised:
    with only the ankle planted straight up (the horizontal position holds), with the toe
    planted too by turning the foot about the toe's point (the heel lifts: the ankle then
    moves horizontally by about ``rise² / (2 L)``, 0.3 mm for a rise of 1 cm on a 15 cm
    foot), during a toe-only contact likewise (the heel rises further).

    Args:
        world_p: ``(F, J, 3)`` world positions of the solve.
        planted: ``(F, C, 3)`` each contact's fixed point (valid on contact frames).
        contact: ``(F, C)`` bool.
        level: ``(C,)`` planted level of each contact joint on the up axis.
        reach: hip-to-ankle length of the leg (target units).
    """
    frames = np.arange(world_p.shape[0])
    ankle, hip, limit = world_p[:, leg.ankle], world_p[:, leg.hip], REACH * reach
    on_a = contact[:, leg.ankle_c]
    on_t = contact[:, leg.toe_c] if leg.toe >= 0 else np.zeros_like(on_a)
    point = planted[:, leg.ankle_c]
    lifted = _lift_to_reach(point, hip, limit, up)
    if leg.toe >= 0:  # a flat foot turns about its toe: the ankle moves by rise²/(2 L) horizontally
        lifted = np.where(on_t[:, None], _turn_to_reach(point, planted[:, leg.toe_c], hip, limit), lifted)
    desired = np.where(on_a[:, None], lifted, ankle)
    held = on_a.copy()
    toe_target = None
    if leg.toe >= 0:
        toe = world_p[:, leg.toe]
        foot = ankle - toe  # (F, 3) the solved foot, toe → ankle; its length is the rig's
        # toe-only frames: the foot pivots about the toe's point; its direction is the solve's
        # plus a correction known on frames with both contacts (the flat foot's) and 0 at a toe
        # contact's ends without the ankle, interpolated in between
        both = on_a & on_t
        edges = np.zeros_like(on_t)
        edges[1:] |= on_t[1:] & ~on_t[:-1]
        edges[:-1] |= on_t[:-1] & ~on_t[1:]
        edges[[0, -1]] |= on_t[[0, -1]]
        edges &= ~on_a
        known = np.flatnonzero(both | edges)
        flat = lifted - planted[:, leg.toe_c]
        correction = np.where(both[:, None], flat - foot, 0.0)[known]
        pivot = _unit(foot + _interp_rows(frames, known, correction)) * np.linalg.norm(foot, axis=-1, keepdims=True)
        only_toe = on_t & ~on_a
        pivoted = _turn_to_reach(planted[:, leg.toe_c] + pivot, planted[:, leg.toe_c], hip, limit)
        pivoted = up_to_level(pivoted, planted[:, leg.toe_c], level[leg.ankle_c], up)
        desired = np.where(only_toe[:, None], pivoted, desired)
        held |= only_toe
        toe_target = _follow(frames, toe, np.where(on_t[:, None], planted[:, leg.toe_c], toe), on_t, fade)
        toe_target[:, up] = np.maximum(toe_target[:, up], level[leg.toe_c])
    ankle_target = _follow(frames, ankle, desired, held, fade)
    ankle_target[:, up] = np.maximum(ankle_target[:, up], level[leg.ankle_c])
    return ankle_target, toe_target, held


def _lift_to_reach(point: np.ndarray, hip: np.ndarray, limit: float, up: int) -> np.ndarray:
    """``point (F, 3)`` raised along the up axis onto the ball of radius ``limit`` about
    ``hip (F, 3)`` where it lies outside it (and horizontally within reach)."""
    gap = point - hip
    horizontal2 = np.sum(gap ** 2, axis=-1) - gap[:, up] ** 2
    lift = np.where((np.sum(gap ** 2, axis=-1) > limit ** 2) & (horizontal2 < limit ** 2) & (gap[:, up] < 0),
                    -np.sqrt(np.maximum(limit ** 2 - horizontal2, 0.0)) - gap[:, up], 0.0)
    out = point.copy()
    out[:, up] += np.maximum(lift, 0.0)
    return out


def up_to_level(point: np.ndarray, pivot: np.ndarray, level: float, up: int) -> np.ndarray:
    """``point (F, 3)`` turned about ``pivot (F, 3)`` (radius and horizontal direction kept) up
    onto ``level`` where it lies below it: a foot pivoting about its planted toe never puts its
    ankle below the ankle's planted level (the heel through the floor); lifted straight up
    instead, the foot no longer reached its toe, which moved."""
    gap = point - pivot
    radius = np.linalg.norm(gap, axis=-1)
    rise = level - pivot[:, up]
    across = gap.copy()
    across[:, up] = 0.0
    span = np.linalg.norm(across, axis=-1)
    turn = (point[:, up] < level) & (radius > np.abs(rise)) & (span > 0)
    out = point.copy()
    scale = np.sqrt(np.maximum(radius ** 2 - rise ** 2, 0.0)) / np.where(span > 0, span, 1.0)
    turned = pivot + across * scale[:, None]
    turned[:, up] = level
    out[turn] = turned[turn]
    return out


def _turn_to_reach(point: np.ndarray, pivot: np.ndarray, hip: np.ndarray, limit: float) -> np.ndarray:
    """``point (F, 3)``, turned about ``pivot (F, 3)`` (radius kept) onto the ball of radius
    ``limit`` about ``hip`` where it lies outside it: the nearest point of the circle where
    the two spheres meet (towards the hip where they do not)."""
    radius = np.linalg.norm(point - pivot, axis=-1, keepdims=True)
    axis = hip - pivot
    dist = np.linalg.norm(axis, axis=-1, keepdims=True)
    n = _unit(axis)
    along = np.clip((radius ** 2 - limit ** 2 + dist ** 2) / (2 * np.maximum(dist, 1e-300)), -radius, radius)
    centre = pivot + along * n
    off = (point - centre) - np.sum((point - centre) * n, -1, keepdims=True) * n
    ring = centre + _unit(off) * np.sqrt(np.maximum(radius ** 2 - along ** 2, 0.0))
    outside = np.linalg.norm(point - hip, axis=-1) > limit
    return np.where(outside[:, None], ring, point)


def _follow(frames: np.ndarray, solved: np.ndarray, desired: np.ndarray, held: np.ndarray,
            fade: float) -> np.ndarray:
    """``desired`` on ``held`` frames, elsewhere ``solved`` plus the offset blended linearly
    between the nearest held frames, faded out (smoothstep) over ``fade`` frames from the
    nearer of them: away from the contacts the joint follows the solve."""
    known = np.flatnonzero(held)
    offset = _interp_rows(frames, known, (desired - solved)[known])
    if known.size == 0 or fade <= 0:
        return solved + offset
    return solved + offset * nearness(held, fade)[:, None]


def nearness(held: np.ndarray, fade: float) -> np.ndarray:
    """``(F,)`` 1 on ``held (F,)`` frames, falling (smoothstep) to 0 at ``fade`` frames from the nearest."""
    frames = np.arange(held.shape[0])
    before = frames - np.maximum.accumulate(np.where(held, frames, -frames.size - fade))
    after = np.minimum.accumulate(np.where(held, frames, 2 * frames.size + fade)[::-1])[::-1] - frames
    near = np.clip(1.0 - np.minimum(before, after) / fade, 0.0, 1.0)
    return near * near * (3.0 - 2.0 * near)


def within_reach(planted: np.ndarray, contact: np.ndarray, legs: list[Leg], hips: np.ndarray, reach: np.ndarray,
                 up: int, body_weight: float) -> np.ndarray:
    """``planted (F, C, 3)`` with every ankle contact's fixed point moved horizontally (at
    its level) where that saves more than it costs, and the toe's fixed point of the same
    stance moved with it.

    The fixed point is the mean of the sliding source joint over the contact; where the
    source's leg is nearly straight at the contact's ends, the mean lies beyond the target
    leg's reach from the hip there and the root comes down for it (:func:`root_drop`),
    moving every joint above the legs (``body_weight`` of them). Moving the point instead
    costs the joints of the leg (:data:`SHIFT_WEIGHT` of them) on every frame of the
    contact. Per contact the point of least ``SHIFT_WEIGHT · frames · shift² + body_weight
    · Σ drop²`` (drops per flat frame, before smoothing) is picked on a grid of
    ``(2 SHIFT_STEPS + 1)²`` points within ``SHIFT_REACH`` of the leg's reach.

    Args:
        hips: ``(F, L, 3)`` the solved hip of each leg.
        reach: ``(L,)`` hip-to-ankle length of each leg.
    """
    planted = planted.copy()
    horizontal = np.array([i for i in range(3) if i != up])
    steps = np.linspace(-1.0, 1.0, 2 * SHIFT_STEPS + 1)
    for l, leg in enumerate(legs):
        limit = REACH * reach[l]
        flat = contact[:, leg.ankle_c] & (contact[:, leg.toe_c] if leg.toe >= 0 else True)
        shifts = []
        for a, b in runs(contact[:, leg.ankle_c]):
            point = planted[a, leg.ankle_c]
            hip = hips[a:b, l][flat[a:b]]

            def cost(offsets: np.ndarray) -> np.ndarray:  # (G, 2) horizontal shifts -> (G,)
                gap = hip[None, :, horizontal] - (point[horizontal] + offsets)[:, None]  # (G, K, 2)
                horizontal2 = np.sum(gap ** 2, axis=-1)
                height = hip[None, :, up] - point[up]
                need = np.where(horizontal2 < limit ** 2,
                                height - np.sqrt(np.maximum(limit ** 2 - horizontal2, 0.0)), height)
                return (SHIFT_WEIGHT * (b - a) * np.sum(offsets ** 2, axis=-1)
                        + body_weight * np.sum(np.maximum(need, 0.0) ** 2, axis=-1))

            shifts.append((a, b, _grid_minimum(cost, steps * SHIFT_REACH * reach[l])))
            planted[a:b, leg.ankle_c, horizontal] += shifts[-1][2]
        if leg.toe < 0:
            continue
        for a, b in runs(contact[:, leg.toe_c]):  # the toe's point keeps its place beside the ankle's
            both = np.flatnonzero(contact[a:b, leg.ankle_c]) + a
            if both.size:
                middle = both[len(both) // 2]
                shift = next(d for s, e, d in shifts if s <= middle < e)
                planted[a:b, leg.toe_c, horizontal] += shift
    return planted


def _grid_minimum(cost, steps: np.ndarray, coarse: int = 5) -> np.ndarray:
    """The point ``(2,)`` of the grid ``steps × steps`` where ``cost`` (``(G, 2)`` points -> ``(G,)``)
    is least, coarse to fine: every ``coarse``-th point, then the full grid within ``coarse`` of the
    best point, re-centred until the centre is its window's best (the cost of :func:`within_reach`
    is convex where the legs reach). ~1/5 of the 41 × 41 points: the search took 30 of 70 ms."""
    n = len(steps)
    index = lambda i, j: np.stack(np.meshgrid(i, j, indexing="ij"), -1).reshape(-1, 2)  # noqa: E731
    points = index(np.arange(0, n, coarse), np.arange(0, n, coarse))
    best = points[int(np.argmin(cost(steps[points])))]
    for _ in range(n):  # each move lowers the cost
        points = index(*(np.arange(max(c - coarse, 0), min(c + coarse, n - 1) + 1) for c in best))
        found = points[int(np.argmin(cost(steps[points])))]
        if (found == best).all():
            break
        best = found
    return steps[best]


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 4)`` the shortest rotations taking directions ``a`` to ``b`` ``(..., 3)``."""
    a, b = _unit(a), _unit(b)
    q = np.concatenate([1.0 + np.sum(a * b, axis=-1, keepdims=True), cross(a, b)], axis=-1)
    return quat_normalize(q)


def place_legs(q: np.ndarray, t: np.ndarray, parents: np.ndarray, anchor: int, legs: list[Leg],
               planted: np.ndarray, contact: np.ndarray, level: np.ndarray, up: int, fps: float,
               floor: float, body_weight: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, t, drop (F,))``: the solve's local rotations ``q (F, J, 4)`` and translations
    ``t (F, J, 3)`` (anchor: world-placed) with every leg on its :func:`foot_targets`, the root
    lowered by ``drop`` where a leg could not reach, and the joints below each toe (its
    End Site) turned up about the toe onto the ``floor`` where they were below it (see the
    module docstring)."""
    q, t = q.copy(), t.copy()
    if not legs:
        return q, t, np.zeros(q.shape[0])
    chain = chain_joints(parents, legs, anchor)
    world_q, world_p = fk_of(q, t, parents, chain)
    reach = leg_reach(world_p, legs)
    # the root comes down where a foot planted flat (ankle and toe) lies out of the leg's reach;
    # then the targets are found from the lowered hips (heels lifted, feet turned where needed)
    flat = np.stack([contact[:, leg.ankle_c] & (contact[:, leg.toe_c] if leg.toe >= 0 else True) for leg in legs], 1)
    hips = world_p[:, [leg.hip for leg in legs]]
    planted = within_reach(planted, contact, legs, hips, reach, up, body_weight)
    points = planted[:, [leg.ankle_c for leg in legs]]
    drop = root_drop(np.where(flat[..., None], hips, points), reach, points, up, fps)
    drop = with_hip_spikes(drop, hips, up)
    world_p = lower_root(t, world_q, world_p, parents, anchor, drop, up)
    targets = [foot_targets(world_p, leg, planted, contact, level, up, r, FADE_S * fps) for leg, r in zip(legs, reach)]
    for leg, (ankle_target, toe_target, _) in zip(legs, targets):
        q = two_bone(q, world_q, world_p, parents, leg, ankle_target, toe_target, up,
                      level[leg.toe_c] if leg.toe >= 0 else None)
    return toes_above_floor(q, t, parents, legs, floor, up, chain), t, drop


def chain_joints(parents: np.ndarray, legs: list[Leg], anchor: int) -> np.ndarray:
    """``(K,)`` sorted joints the leg IK reads: the legs' joints, the joints below each toe
    (or toeless ankle), ``anchor``, and every ancestor of these (closed under parents)."""
    below_toes = ancestor_matrix(parents)[[leg.toe if leg.toe >= 0 else leg.ankle for leg in legs]].any(axis=0)
    legs_joints = [j for leg in legs for j in (leg.hip, leg.knee, leg.ankle, leg.toe) if j >= 0]
    return with_ancestors(parents, [anchor, *legs_joints, *np.flatnonzero(below_toes)])


def fk_of(q: np.ndarray, t: np.ndarray, parents: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~usdmotion.kinematics.fk_arrays` of ``joints`` only (closed under parents: the same
    numbers as the whole skeleton's), in arrays of every joint (the others identity and 0):
    the leg IK needs the legs and what carries them, ~1/5 of a 70-joint rig."""
    sub_q, sub_p = fk_arrays(q[:, joints], t[:, joints], restricted_parents(parents, joints))
    world_q = np.zeros(q.shape)
    world_q[..., 0] = 1.0
    world_p = np.zeros(t.shape)
    world_q[:, joints], world_p[:, joints] = sub_q, sub_p
    return world_q, world_p


def toes_above_floor(q, t, parents, legs: list[Leg], floor: float, up: int, chain: np.ndarray) -> np.ndarray:
    """``q`` with each toe joint (an ankle without one) turned so that no joint below it is
    under ``floor``: such a joint is put on the floor, turned about the toe in the vertical
    plane of its bone (``chain``: :func:`chain_joints`, the joints whose positions it needs)."""
    world_q, world_p = fk_of(q, t, parents, chain)
    for leg in legs:
        pivot = leg.toe if leg.toe >= 0 else leg.ankle  # without a toe: the foot's own End Site
        for d in descendants(parents, pivot):
            bone = world_p[:, d] - world_p[:, pivot]
            length = np.linalg.norm(bone, axis=-1)
            low = (world_p[:, d, up] < floor) & (length > 0)
            if not low.any():
                continue
            heading = world_p[:, leg.toe] - world_p[:, leg.ankle] if leg.toe >= 0 else bone.copy()
            heading[:, up] = 0.0
            flat = bone.copy()  # the bone's own heading, and a little of the foot's where it points down
            flat[:, up] = 0.0
            flat = flat + HEADING_SHARE * length[:, None] * _unit(heading)
            sin = np.clip((floor - world_p[:, pivot, up]) / np.maximum(length, 1e-300), -1.0, 1.0)
            lifted = _unit(flat) * np.sqrt(1.0 - sin ** 2)[:, None] * length[:, None]
            lifted[:, up] = sin * length
            turn = np.where(low[:, None], _swing(bone, lifted), [1.0, 0.0, 0.0, 0.0])
            w_pivot = quat_mul(turn, world_q[:, pivot])
            q[:, pivot] = quat_mul(quat_conjugate(world_q[:, parents[pivot]]), w_pivot)
            world_q, world_p = fk_of(q, t, parents, chain)
    return q


def knee_hinge_bend(world_q: np.ndarray, world_p: np.ndarray, leg: Leg, u: np.ndarray) -> np.ndarray:
    """``(F, 3)`` unit direction, across ``u (F, 3)`` (hip → ankle target), towards which the
    knee bends about its hinge: the take's mean hinge axis of the solved leg in the thigh's
    frame (``(knee − hip) × (ankle − knee)`` weighted by how far the leg bends), carried by
    each frame's solved thigh rotation ``world_q[:, hip]``.

    Where the solved leg is nearly straight, its knee's offset from the hip → ankle line is
    float noise whose direction swings between frames; a knee the IK must bend further (the
    root came down) then turned with it (walk → legs 0.8× frame 12: hip 7.7°, knee 13.3°
    in one frame where the source's largest steps are 3.8° and 6.3°)."""
    hip, knee, ankle = world_p[:, leg.hip], world_p[:, leg.knee], world_p[:, leg.ankle]
    thigh = world_q[:, leg.hip]
    normal = cross(knee - hip, ankle - knee)  # (F, 3), length ∝ sin(bend)
    axis = _unit(quat_rotate(quat_conjugate(thigh), normal).sum(axis=0))
    return _unit(cross(u, quat_rotate(thigh, np.broadcast_to(axis, normal.shape))))


def two_bone(q, world_q, world_p, parents, leg: Leg, ankle_target, toe_target, up, toe_level, hinge=HINGE_SHARE):
    """Local rotations of hip, knee and ankle of one leg placed on its targets (see :func:`place_legs`);
    ``hinge``: the share of the knee's hinge in its bend direction (0: the solved knee's own plane)."""
    hip, knee, ankle = world_p[:, leg.hip], world_p[:, leg.knee], world_p[:, leg.ankle]
    a = np.linalg.norm(knee - hip, axis=-1, keepdims=True)
    b = np.linalg.norm(ankle - knee, axis=-1, keepdims=True)
    to_target = ankle_target - hip
    d = np.clip(np.linalg.norm(to_target, axis=-1, keepdims=True), np.abs(a - b) + 1e-9 * (a + b), REACH * (a + b))
    u = _unit(to_target)
    # the knee's bend direction: the solved knee off the hip → ankle line, plus the knee's hinge
    # (decides where the solved leg is nearly straight, see knee_hinge_bend)
    along = _unit(ankle - hip)
    bend = (knee - hip) - np.sum((knee - hip) * along, -1, keepdims=True) * along
    bend = bend + hinge * a * knee_hinge_bend(world_q, world_p, leg, u)
    v = _unit(bend - np.sum(bend * u, -1, keepdims=True) * u)
    cos = np.clip((a ** 2 + d ** 2 - b ** 2) / (2 * a * d), -1.0, 1.0)
    new_knee = hip + a * (cos * u + np.sqrt(1.0 - cos ** 2) * v)
    new_ankle = hip + d * u
    turn_hip = _swing(knee - hip, new_knee - hip)
    w_hip = quat_mul(turn_hip, world_q[:, leg.hip])
    turn_knee = quat_mul(_swing(quat_rotate(turn_hip, ankle - knee), new_ankle - new_knee), turn_hip)
    w_knee = quat_mul(turn_knee, world_q[:, leg.knee])
    w_ankle = world_q[:, leg.ankle]  # the foot keeps its solved world rotation ...
    if toe_target is not None:  # ... turned to aim at the toe's target, the toe not below its level
        foot = world_p[:, leg.toe] - ankle
        length = np.linalg.norm(foot, axis=-1, keepdims=True)
        aim = _unit(toe_target - new_ankle) * length
        rise = np.maximum(aim[:, up], np.maximum(toe_level - new_ankle[:, up], -length[:, 0]))
        flat = aim.copy()
        flat[:, up] = 0.0
        aim = _unit(flat) * np.sqrt(np.maximum(length ** 2 - rise[:, None] ** 2, 0.0))
        aim[:, up] = rise
        w_ankle = quat_mul(_swing(foot, aim), w_ankle)
    parent = parents[leg.hip]
    w_parent = world_q[:, parent] if parent >= 0 else np.broadcast_to([1.0, 0, 0, 0], w_hip.shape)
    q[:, leg.hip] = quat_mul(quat_conjugate(w_parent), w_hip)
    q[:, leg.knee] = quat_mul(quat_conjugate(w_hip), w_knee)
    q[:, leg.ankle] = quat_mul(quat_conjugate(w_knee), w_ankle)
    return q

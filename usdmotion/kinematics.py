"""Forward kinematics over all frames at once, for NumPy and ``jax.numpy`` alike.

The hierarchy is processed one *depth level* at a time (all joints at depth d in one
vectorised step), so the Python loop runs ``depth`` times, never over frames, and
``jax.jit`` unrolls a short, fixed graph.

``T_world_joint = T_world_parent @ T_parent_joint`` with
``T_parent_joint = translate(t_j) @ rotate(q_j)``; positions in file units.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from usdmotion.motion import Motion, joint_depths
from usdmotion.parallel import over_slices
from usdmotion.rotations import array_namespace, hamilton, quat_to_matrix


@lru_cache(maxsize=256)
def _levels_cached(parents_key: tuple[int, ...]) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    parents = np.asarray(parents_key)
    depth = joint_depths(parents)
    levels = []
    previous = None
    for d in range(int(depth.max()) + 1):
        idx = np.flatnonzero(depth == d)
        if previous is None:
            parent_pos = np.full(idx.shape, -1)
        else:
            position_in_previous = {int(j): k for k, j in enumerate(previous)}
            parent_pos = np.array([position_in_previous[int(parents[j])] for j in idx])
        levels.append((idx, parent_pos))
        previous = idx
    return tuple(levels)


def depth_levels(parents: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """Joints grouped by depth: ``((idx, parent_position_in_previous_level), ...)``."""
    return _levels_cached(tuple(int(p) for p in np.asarray(parents)))


def _qrot_planes(q, v):
    """Rotate component-first vectors ``v`` (3 arrays) by quaternions ``q`` (4 arrays)."""
    w, x, y, z = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


def _fk_levels(local_rotations, local_translations, parents: np.ndarray):
    """World rotation and position planes, one depth level at a time.

    Yields ``(idx, q, p)``: the level's joint indices ``(n,)``, its world wxyz rotations
    as 4 planes ``(..., n)`` and its world positions as 3 planes ``(..., n)``.
    """
    xp = array_namespace(local_rotations, local_translations)
    levels = depth_levels(parents)
    if xp is not np:
        # JAX keeps its conversion of a NumPy index array per array object, in the integer width of its first
        # use: cached levels traced without 64-bit mode and then indexed with it (the float64 reference checks)
        # fail in lax.add (int32 + int64). Fresh copies leave the cached ones to NumPy.
        levels = tuple((idx.copy(), pos.copy()) for idx, pos in levels)
    q_local = xp.moveaxis(xp.asarray(local_rotations), -1, 0)  # strided views: a copy costs more than it saves
    t_local = xp.moveaxis(xp.asarray(local_translations), -1, 0)
    root_idx = levels[0][0]
    q_prev = tuple(c[..., root_idx] for c in q_local)
    p_prev = tuple(c[..., root_idx] for c in t_local)
    yield root_idx, q_prev, p_prev
    for idx, parent_pos in levels[1:]:
        q_parent = tuple(c[..., parent_pos] for c in q_prev)
        p_parent = tuple(c[..., parent_pos] for c in p_prev)
        q_prev = hamilton(q_parent, tuple(c[..., idx] for c in q_local))
        offset = _qrot_planes(q_parent, tuple(c[..., idx] for c in t_local))
        p_prev = tuple(a + b for a, b in zip(p_parent, offset))
        yield idx, q_prev, p_prev


def fk_arrays(local_rotations, local_translations, parents: np.ndarray):
    """World rotations and positions from local ones.

    Args:
        local_rotations: ``(..., J, 4)`` wxyz quaternions, joint relative to parent.
        local_translations: ``(..., J, 3)`` joint origin in the parent frame (root: world).
        parents: ``(J,)`` parent indices, parents before children.

    Returns:
        ``(world_rotations (..., J, 4), world_positions (..., J, 3))``, same array kind
        as the inputs (NumPy or JAX).

    Works on per-component planes ``(..., J)`` internally (w, x, y, z as separate arrays),
    one vectorised step per depth level.
    """
    xp = array_namespace(local_rotations, local_translations)
    order, q_parts, p_parts = zip(*_fk_levels(local_rotations, local_translations, parents))
    inverse = np.argsort(np.concatenate(order))
    world_q = xp.stack([xp.concatenate([part[k] for part in q_parts], axis=-1)[..., inverse] for k in range(4)],
                       axis=-1)
    world_p = xp.stack([xp.concatenate([part[k] for part in p_parts], axis=-1)[..., inverse] for k in range(3)],
                       axis=-1)
    return world_q, world_p


def position_bounds(motion: Motion, chunk_frames: int = 2048) -> tuple[np.ndarray, np.ndarray]:
    """``(low (3,), high (3,))``: the box of every joint's world position over every frame
    (file units) of a motion with at least one frame. Equal to the bounds of
    :func:`joint_positions`, without assembling the ``(F, J, 3)`` array: the FK planes
    of ``chunk_frames`` frames at a time (a long take's planes and local translations for
    all frames at once were several times its data, the peak of a 1M-frame convert; small
    chunks reuse the same memory, 4,096 frames at a time cost a fresh page for every temporary),
    the frames split between threads (:func:`usdmotion.parallel.over_slices`; NumPy releases the GIL)."""
    lows, highs = [], []

    def bounds_of(frames: slice) -> None:  # threads take turns over slices of frames (min/max: exact in any order)
        for start in range(frames.start, frames.stop, chunk_frames):
            part = slice(start, min(start + chunk_frames, frames.stop))  # views: no Motion (a copy) per chunk
            planes = [p for _, _, p in _fk_levels(motion.rotations[part], local_translations(motion, part),
                                                  motion.parents)]
            lows.append([min(float(level[k].min()) for level in planes) for k in range(3)])
            highs.append([max(float(level[k].max()) for level in planes) for k in range(3)])

    over_slices(bounds_of, motion.n_frames, min_items=max(1, _THREAD_ITEMS // motion.n_joints))
    return np.min(lows, axis=0), np.max(highs, axis=0)


#: Joint-frames a thread of :func:`position_bounds` takes at least (fewer: one thread does all).
_THREAD_ITEMS = 40_000


def local_translations(motion: Motion, frames: slice = slice(None)) -> np.ndarray:
    """Local translation of every joint at every frame (of ``frames``), ``(F, J, 3)`` file units.

    Root: ``root_translation``; joints with position channels: ``joint_translations``;
    all others: ``offsets``.
    """
    root = motion.root_translation[frames]
    if motion.joint_translations is not None:
        out = np.array(motion.joint_translations[frames])
    else:
        out = np.broadcast_to(motion.offsets, (len(root),) + motion.offsets.shape).copy()
    out[:, 0] = root
    return out


def world_rotations_positions(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """``(world_rotations (F, J, 4) wxyz, world_positions (F, J, 3))`` of a motion."""
    return fk_arrays(motion.rotations, local_translations(motion), motion.parents)


def joint_positions(motion: Motion) -> np.ndarray:
    """World position of every joint at every frame, ``(F, J, 3)`` in file units."""
    return world_rotations_positions(motion)[1]


def first_frame_jumps(motion: Motion, factor: float = 10.0) -> bool:
    """True when the step from frame 0 to 1 is ``factor`` times larger than any later step
    (the largest joint move per step, over the first 600 frames).

    cgspeed's CMU conversions start with a synthetic T-pose frame; derivatives and rotation
    steps across it are meaningless spikes.
    """
    if motion.n_frames < 4:
        return False
    head = joint_positions(motion.sliced(0, min(motion.n_frames, 600)))
    steps = np.linalg.norm(np.diff(head, axis=0), axis=-1).max(axis=1)  # largest joint move per step
    later = float(np.max(steps[1:]))
    return bool(steps[0] > factor * later) if later > 0 else bool(steps[0] > 0)


def fk(motion: Motion) -> np.ndarray:
    """World transforms ``T_world_joint`` ``(F, J, 4, 4)`` (column vectors, file units)."""
    world_q, world_p = world_rotations_positions(motion)
    return compose_transforms(world_q, world_p)


def compose_transforms(rotations, translations):
    """4×4 matrices ``(..., 4, 4)`` from wxyz rotations ``(..., 4)`` and translations ``(..., 3)``."""
    xp = array_namespace(rotations, translations)
    r = quat_to_matrix(rotations)
    top = xp.concatenate([r, translations[..., :, None]], axis=-1)
    bottom = xp.broadcast_to(xp.asarray([0.0, 0.0, 0.0, 1.0], dtype=top.dtype), top.shape[:-2] + (1, 4))
    return xp.concatenate([top, bottom], axis=-2)


def rest_pose(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """``(world_rotations (J, 4), world_positions (J, 3))`` of the rest pose: OFFSETs with
    identity rotations (the BVH rest pose, USD's ``bindTransforms``)."""
    return rest_arrays(motion.offsets, motion.parents)


def rest_arrays(offsets: np.ndarray, parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rest_pose` of ``offsets (J, 3)`` and ``parents (J,)`` (a skeleton that is no Motion)."""
    identity = np.zeros((len(parents), 4))
    identity[:, 0] = 1.0
    return fk_arrays(identity, offsets, parents)


def rest_positions(motion: Motion) -> np.ndarray:
    """World joint positions ``(J, 3)`` of the rest pose (identity rotations, OFFSETs)."""
    return rest_pose(motion)[1]


def skeleton_height(motion: Motion, frame: int | None = None) -> float:
    """Largest extent ``(file units)`` of the joints, at rest or at ``frame``.

    Used to scale tolerances ("1e-4 × the skeleton's height").
    """
    points = rest_positions(motion) if frame is None else joint_positions(motion)[frame]
    extent = float(np.max(np.ptp(points, axis=0)))
    return extent if extent > 0 else 1.0

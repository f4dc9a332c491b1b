"""Change a motion's up axis (``convert --to-up-axis``): the whole take turned rigidly.

Y-up → Z-up is +90° about X (stage +Y → +Z, +Z "front" → −Y, Blender's convention);
Z-up → Y-up the inverse. The turn applies to the root (rotation, translation, OFFSET)
and to carried skinned meshes (points, normals, bind transforms, blend shape offsets),
so every joint and vertex lands at ``R · p``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from usdmotion.constants import UP_AXES
from usdmotion.motion import Motion
from usdmotion.rotations import axis_angle_quat, quat_mul, quat_rotate, quat_to_matrix


def up_axis_turn(source: str, target: str) -> np.ndarray:
    """wxyz quaternion ``(4,)`` turning a ``source``-up world into a ``target``-up one."""
    for axis in (source, target):
        if axis not in UP_AXES:
            raise ValueError(f"up axis must be one of {', '.join(UP_AXES)}, got {axis!r}")
    angle = 0.0 if source == target else (np.pi / 2 if target == "Z" else -np.pi / 2)
    return np.asarray(axis_angle_quat("X", angle), np.float64)


def convert_up_axis(motion: Motion, target: str) -> Motion:
    """``motion`` turned to ``target`` up (``"Y"`` or ``"Z"``); unchanged if it already is."""
    target = str(target).upper()
    turn = up_axis_turn(motion.up_axis, target)
    if motion.up_axis == target:
        return motion
    rotations = np.array(motion.rotations)
    rotations[:, 0] = quat_mul(turn, rotations[:, 0])
    offsets = np.array(motion.offsets)
    offsets[0] = quat_rotate(turn, offsets[0])
    return dataclasses.replace(motion, rotations=rotations, root_translation=quat_rotate(turn, motion.root_translation),
                               offsets=offsets, up_axis=target, source_channels=None,
                               meshes=tuple(_turn_mesh(m, quat_to_matrix(turn), motion.joint_names[0], offsets[0])
                                            for m in motion.meshes))


def _turn_mesh(mesh, rotation: np.ndarray, root: str, root_offset: np.ndarray):
    """A :class:`usdmotion.io.usd_skin.SkinnedMesh` turned by the 3×3 ``rotation`` (its
    record of the root's OFFSET follows the turned root)."""
    turn4 = np.eye(4)
    turn4[:3, :3] = rotation
    shapes = tuple(dataclasses.replace(s, offsets=s.offsets @ rotation.T) for s in mesh.blend_shapes)
    rest = np.array(mesh.rest_offsets)
    rest[[n == root for n in mesh.joint_names]] = root_offset
    return dataclasses.replace(mesh, points=mesh.points @ rotation.T, rest_offsets=rest,
                               normals=None if mesh.normals is None else mesh.normals @ rotation.T,
                               bind_transforms=turn4 @ mesh.bind_transforms, blend_shapes=shapes)

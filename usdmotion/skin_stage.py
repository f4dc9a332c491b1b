"""The input stage's own skinned meshes as one :class:`usdmotion.skin.Body` (``render --body stage``).

The meshes a USD input carries (``Motion.meshes``, :mod:`usdmotion.io.usd_skin`) are
already in the motion's space with bind transforms rebased to its joints, so skinning
them with the motion's forward kinematics (:func:`usdmotion.skin.skin_frames`) is
UsdSkel's linear blend skinning of the input: polygons are fanned into triangles,
vertex normals recomputed (area-weighted), influences padded to a common count. Blend shapes
the motion animates (``Motion.blend_shape_weights``) are added to the points before skinning
(:func:`stage_body_and_shapes`; point offsets only: the normals stay the bind pose's, and
in-between shapes are not read).
"""

from __future__ import annotations

import warnings

import numpy as np

from usdmotion.errors import UsdMotionWarning
from usdmotion.io.usd_skin import usable_meshes
from usdmotion.motion import Motion
from usdmotion.skin import Body, bind_transforms, body_size


def _triangles(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Fan triangulation ``(T, 3)`` of polygons (``faceVertexCounts``, ``faceVertexIndices``)."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    fans = [np.stack([np.full(c - 2, s), s + np.arange(1, c - 1), s + np.arange(2, c)], axis=1)
            for s, c in zip(starts.tolist(), counts.tolist()) if c >= 3]
    return indices[np.concatenate(fans)] if fans else np.zeros((0, 3), np.int64)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)``."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    face_n = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def stage_body(motion: Motion, source=None) -> Body | None:
    """The motion's carried skinned meshes merged into one ``Body``; ``None`` if it has none
    (or none still fits the skeleton: :func:`usdmotion.io.usd_skin.usable_meshes` warns)."""
    merged = stage_body_and_shapes(motion, source)
    return None if merged is None else merged[0]


def stage_body_and_shapes(motion: Motion, source=None) -> tuple[Body, np.ndarray | None] | None:
    """:func:`stage_body` and the blend shapes the motion animates: ``(S, V, 3)`` point offsets in
    the body's numbering for ``motion.blend_shape_names`` (zero where a shape moves no point),
    weighted per frame by ``motion.blend_shape_weights (F, S)`` and added to the bind-pose points
    before skinning, as UsdSkel does; ``None`` when no mesh has one of them. Warns when a mesh's
    blend shapes were animated in its source but the motion no longer carries the weights."""
    meshes = usable_meshes(motion, source or "render", blend_shape_warning=False)
    if not meshes:
        return None
    index = {n: j for j, n in enumerate(motion.joint_names)}
    bind = bind_transforms(motion)
    k = max(m.joint_indices.shape[1] for m in meshes)
    channel = {n: s for s, n in enumerate(motion.blend_shape_names)} if motion.blend_shape_weights is not None else {}
    vertices, faces, joints, weights, base, shapes = [], [], [], [], 0, []
    for mesh in meshes:
        remap = np.array([index[n] for n in mesh.joint_names])
        bind[remap] = mesh.bind_transforms
        pad = k - mesh.joint_indices.shape[1]
        joints.append(np.pad(remap[mesh.joint_indices], ((0, 0), (0, pad))))
        w = np.pad(mesh.joint_weights, ((0, 0), (0, pad)))
        weights.append(w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300))
        faces.append(_triangles(mesh.face_vertex_counts, mesh.face_vertex_indices) + base)
        vertices.append(mesh.points)
        shapes += [(channel[shape.name], base + (np.arange(len(mesh.points)) if shape.point_indices is None
                                                else shape.point_indices), shape.offsets)
                   for shape in mesh.blend_shapes if shape.name in channel]
        if mesh.animated_blend_shapes and mesh.blend_shapes and not channel:
            warnings.warn(f"{source or 'render'}: skinned mesh {mesh.name}: the blend shape weights are not carried "
                          "(an operation could not map them to its frames): drawn without its blend shapes",
                          UsdMotionWarning, stacklevel=2)
        base += len(mesh.points)
    vertices, faces = np.concatenate(vertices), np.concatenate(faces).astype(np.int32)
    offsets = None
    if shapes:
        offsets = np.zeros((len(motion.blend_shape_names), len(vertices), 3))
        for s, points, delta in shapes:
            np.add.at(offsets[s], points, delta)
    body = Body(vertices=vertices, faces=faces, normals=vertex_normals(vertices, faces),
                joint_indices=np.concatenate(joints).astype(np.int32), joint_weights=np.concatenate(weights),
                bind_transforms=bind, size=body_size(motion))
    return body, offsets

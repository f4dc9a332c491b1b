"""The input stage's own skinned meshes as one :class:`usdmotion.skin.Body` (``render --body stage``).

The meshes a USD input carries (``Motion.meshes``, :mod:`usdmotion.io.usd_skin`) are
already in the motion's space with bind transforms rebased to its joints, so skinning
them with the motion's forward kinematics (:func:`usdmotion.skin.skin_frames`) is
UsdSkel's linear blend skinning of the input: polygons are fanned into triangles,
vertex normals recomputed (area-weighted), influences padded to a common count.
"""

from __future__ import annotations

import numpy as np

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
    meshes = usable_meshes(motion, source or "render", blend_shape_warning=False)
    if not meshes:
        return None
    index = {n: j for j, n in enumerate(motion.joint_names)}
    bind = bind_transforms(motion)
    k = max(m.joint_indices.shape[1] for m in meshes)
    vertices, faces, joints, weights, base = [], [], [], [], 0
    for mesh in meshes:
        remap = np.array([index[n] for n in mesh.joint_names])
        bind[remap] = mesh.bind_transforms
        pad = k - mesh.joint_indices.shape[1]
        joints.append(np.pad(remap[mesh.joint_indices], ((0, 0), (0, pad))))
        w = np.pad(mesh.joint_weights, ((0, 0), (0, pad)))
        weights.append(w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300))
        faces.append(_triangles(mesh.face_vertex_counts, mesh.face_vertex_indices) + base)
        vertices.append(mesh.points)
        base += len(mesh.points)
    vertices, faces = np.concatenate(vertices), np.concatenate(faces).astype(np.int32)
    return Body(vertices=vertices, faces=faces, normals=vertex_normals(vertices, faces),
                joint_indices=np.concatenate(joints).astype(np.int32), joint_weights=np.concatenate(weights),
                bind_transforms=bind, size=body_size(motion))

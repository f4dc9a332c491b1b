"""Level of detail: the generated body with fewer triangles when it is drawn small.

On a CPU rasteriser (Mesa llvmpipe) every triangle costs its set-up and at least one 4×4 block
of fragment shading, however few pixels it covers: at 1280×720 the side camera shows the default
body (~20k triangles, marching cubes at resolution 96) about 430 pixels tall, ~2.5 pixels a
triangle, and its triangles cost ~0.4 µs each, a fifth of a frame's CPU. So the body is
decimated for the picture (quadric edge collapses: ``fast-simplification``) to a number of
triangles proportional to its height in pixels squared (a constant density on screen), between
:data:`LEAST` of them and all. Each decimated vertex takes the mean skin weights and normal of the
vertices collapsed into it; every body part stays one closed surface. The skinned body written to
USD (``convert --mesh``) and every analysis keep the full mesh.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from usdmotion.skin import INFLUENCES, Body

#: Body height in pixels at which it is drawn with all its triangles; below, the kept fraction of
#: triangles is ``(height / FULL_DETAIL_PIXELS)²``.
FULL_DETAIL_PIXELS = 750.0

#: The fewest triangles kept, a fraction of the body's.
LEAST = 1 / 3


def pixel_height(size: float, eye_distance: np.ndarray, yfov: float, image_height: int) -> float:
    """The body's height in pixels seen from the nearest 5 % of the camera positions:
    ``size`` metres at ``eye_distance (N,)`` metres, vertical field of view ``yfov`` radians."""
    near = float(np.percentile(eye_distance, 5)) if len(eye_distance) else 1.0
    return size / max(2.0 * near * np.tan(yfov / 2.0), 1e-9) * image_height


def detail(height_pixels: float) -> float:
    """The fraction of the body's triangles to draw at ``height_pixels``: in ``[LEAST, 1]``."""
    return float(np.clip((height_pixels / FULL_DETAIL_PIXELS) ** 2, LEAST, 1.0))


def fewer_triangles(body: Body, keep: float) -> Body:
    """``body`` with about ``keep`` of its triangles (``keep`` ≥ 1: ``body`` itself).

    Positions are the quadric-optimal ones of the collapses; each new vertex's weights (the
    :data:`~usdmotion.skin.INFLUENCES` largest of the summed weights, renormalised: their mean)
    and normal (renormalised sum) come from the original vertices collapsed into it.
    """
    if keep >= 1.0 or len(body.faces) < 64:
        return body
    import fast_simplification

    points, faces, collapses = fast_simplification.simplify(
        body.vertices, body.faces, target_reduction=1.0 - keep, return_collapses=True)
    *_, mapping = fast_simplification.replay_simplification(body.vertices, body.faces, collapses)
    weights = np.zeros((len(points), body.n_joints))
    np.add.at(weights, mapping, body.weight_matrix())
    normals = np.zeros((len(points), 3))
    np.add.at(normals, mapping, body.normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    index = np.argsort(-weights, axis=1, kind="stable")[:, :INFLUENCES]
    top = np.take_along_axis(weights, index, axis=1)
    if index.shape[1] < INFLUENCES:  # fewer joints than influences: unused slots repeat the first, weight 0
        pad = INFLUENCES - index.shape[1]
        index = np.concatenate([index, np.repeat(index[:, :1], pad, axis=1)], axis=1)
        top = np.concatenate([top, np.zeros((len(top), pad))], axis=1)
    return replace(body, vertices=np.asarray(points, np.float64), faces=np.asarray(faces, np.int32),
                   normals=normals, joint_indices=index.astype(np.int32),
                   joint_weights=top / top.sum(axis=1, keepdims=True))

"""Level of detail (usdmotion.render.lod): the decimated body keeps the surface, the skinning and
the picture; it is drawn with fewer triangles only when small on screen."""

from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

from usdmotion.io import read_motion
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.render import RenderOptions, plan_render, render_motion
from usdmotion.render.camera import project_frames
from usdmotion.render.lod import LEAST, detail, fewer_triangles, pixel_height
from usdmotion.skin import build_body, lbs, skinning_matrices
from tests.test_render import read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"


def _distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Distance of ``points`` to the surface ``(vertices, faces)``, from above: to the nearest of
    400,000 points spread over it (trimesh's area-weighted sampling; the exact distance is smaller)."""
    from scipy.spatial import cKDTree

    samples, _ = trimesh.sample.sample_surface(trimesh.Trimesh(vertices, faces, process=False), 400_000, seed=0)
    return cKDTree(np.concatenate([samples, vertices])).query(points)[0]


def test_fewer_triangles_keeps_the_surface_and_the_skinning(shared_file):
    walk = read_motion(shared_file(WALK), units="asf")
    body = build_body(walk, resolution=64)
    lod = fewer_triangles(body, 0.36)
    assert 0.3 * len(body.faces) <= len(lod.faces) <= 0.4 * len(body.faces)
    full_mesh, lod_mesh = (trimesh.Trimesh(b.vertices, b.faces, process=False) for b in (body, lod))
    assert lod_mesh.is_watertight and len(lod_mesh.split(only_watertight=False)) == len(
        full_mesh.split(only_watertight=False))  # every body part one closed surface, none lost
    assert lod_mesh.volume > 0  # still facing out
    assert np.allclose(lod.joint_weights.sum(axis=1), 1.0) and (lod.joint_weights >= 0).all()
    assert np.allclose(np.linalg.norm(lod.normals, axis=1), 1.0)
    # both ways close: the new vertices lie on the old surface, and no part of it was cut away
    assert _distances(lod.vertices, body.vertices, body.faces).max() < 0.004 * body.size
    assert _distances(body.vertices, lod.vertices, lod.faces).max() < 0.005 * body.size
    # skinned in a moving frame (the weights carried over), the surfaces still agree
    frame = [200]
    q, p = fk_arrays(walk.rotations[frame], local_translations(walk)[frame], walk.parents)
    posed = [lbs(b.vertices, b.weight_matrix(), skinning_matrices(q, p, b.bind_transforms))[0] for b in (body, lod)]
    assert _distances(posed[1], posed[0], body.faces).max() < 0.01 * body.size
    normal_agreement = np.einsum("vk,vk->v", lod.normals, lod_mesh.vertex_normals)
    assert np.median(normal_agreement) > 0.98


def test_detail_follows_the_body_height_in_pixels(shared_file):
    assert detail(2000.0) == 1.0 and detail(1.0) == LEAST
    heights = np.linspace(100, 1000, 10)
    assert np.all(np.diff([detail(h) for h in heights]) >= 0)
    # pixel_height agrees with projecting a vertical segment of that height through the camera
    walk = read_motion(shared_file(WALK), units="asf")
    plan = plan_render(walk, RenderOptions(start=100, end=101))
    pose = plan.camera.poses[0]
    target = pose[:3, 3] - 3.0 * pose[:3, 2]  # 3 m in front of the camera
    ends = np.stack([target - [0, 0.9, 0], target + [0, 0.9, 0]])[None]
    projected = project_frames(ends, plan.camera.poses[:1], plan.camera.yfov, 1280, 720)[0]
    expected = abs(projected[1, 1] - projected[0, 1])
    assert abs(pixel_height(1.8, np.array([3.0]), plan.camera.yfov, 720) - expected) < 0.02 * expected


def test_the_picture_with_fewer_triangles_matches_the_full_body(shared_file, tmp_path):
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(start=200, end=201, overlay=False)  # 1280x720, the default look
    images = {}
    for lod in (True, False):
        render_motion(walk, tmp_path / f"{lod}/####.png", dataclasses.replace(options, lod=lod))
        images[lod] = read_image(tmp_path / f"{lod}/0000.png").astype(int)
    difference = np.abs(images[True] - images[False])
    psnr = 10 * np.log10(255 ** 2 / (difference ** 2).mean())
    assert psnr > 45, psnr
    background = images[False][0, 0]
    body = [(np.abs(im - background).sum(-1) > 60) for im in (images[True], images[False])]
    iou = (body[0] & body[1]).sum() / (body[0] | body[1]).sum()
    assert iou > 0.97, iou
    assert (difference.max(-1) > 16).sum() < 0.03 * body[1].sum()  # only outline pixels move

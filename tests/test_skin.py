"""Volumetric body, skin weights and linear blend skinning, checked against usd-core's
own skinning (UsdSkel.SkinningQuery / BakeSkinning) and an independent inside test."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.io import read_motion, write_motion
from usdmotion.io.usd import validate_stage
from usdmotion.kinematics import joint_positions
from usdmotion.skin import INFLUENCES, bone_capsules, build_body, skin_frames

WALK = "cmu/cgspeed_12_01_walk.bvh"


def winding_number(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number of a closed triangle mesh at ``points`` (van Oosterom &
    Strackee solid angles): 1 inside, 0 outside. Independent of trimesh and of our code."""
    a, b, c = (vertices[faces[:, k]][None] - points[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = np.einsum("pti,pti->pt", a, np.cross(b, c))
    div = (la * lb * lc + np.einsum("pti,pti->pt", a, b) * lc + np.einsum("pti,pti->pt", b, c) * la
           + np.einsum("pti,pti->pt", c, a) * lb)
    return 2 * np.arctan2(det, div).sum(axis=1) / (4 * np.pi)


@pytest.fixture(scope="module")
def walk(request):
    from tests.conftest import shared_path

    motion = read_motion(shared_path(WALK), units="asf")
    return motion.with_frames(motion.rotations[:60], motion.root_translation[:60])


@pytest.fixture(scope="module")
def walk_body(walk):
    return build_body(walk, resolution=64)


def test_usd_skinning_equals_ours(walk, walk_body, tmp_path):
    from pxr import Usd, UsdSkel, Vt

    from usdmotion.io.usd_mesh import body_decorator

    path = tmp_path / "walk.usda"
    write_motion(walk, path, decorate=body_decorator(walk_body))
    assert validate_stage(str(path)) == []
    stage = Usd.Stage.Open(str(path))
    root = UsdSkel.Root(stage.GetDefaultPrim())
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.PrimDefaultPredicate)
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(root.GetPath().AppendChild("Skeleton")))
    skel_query = cache.GetSkelQuery(skel)
    targets = cache.ComputeSkelBinding(root, skel, Usd.PrimDefaultPredicate).GetSkinningTargets()
    assert len(targets) == 1
    skinning = targets[0]
    assert skinning.GetNumInfluencesPerComponent() == INFLUENCES
    rest_points = skinning.GetPrim().GetAttribute("points").Get()
    frames = np.array([0, 1, 23, 59])
    ours = skin_frames(walk_body, walk, frames)
    tolerance = 1e-5 * walk_body.size
    for k, frame in enumerate(frames):
        points = Vt.Vec3fArray(rest_points)  # ComputeSkinnedPoints writes in place
        assert skinning.ComputeSkinnedPoints(skel_query.ComputeSkinningTransforms(float(frame)), points, float(frame))
        np.testing.assert_allclose(np.array(points), ours[k], atol=tolerance, rtol=0)
    # the skinned body actually moves: frame 59 is far from the bind pose
    assert np.abs(ours[-1] - walk_body.vertices).max() > 0.1 * walk_body.size


def test_usd_bake_skinning_equals_ours(walk, walk_body, tmp_path):
    from pxr import Gf, Usd, UsdSkel

    from usdmotion.io.usd_mesh import body_decorator

    path = tmp_path / "bake.usda"
    write_motion(walk, path, decorate=body_decorator(walk_body))
    stage = Usd.Stage.Open(str(path))
    assert UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(0, 59))
    mesh = stage.GetDefaultPrim().GetChild("Body")
    frames = np.array([5, 40])
    ours = skin_frames(walk_body, walk, frames)
    for k, frame in enumerate(frames):
        np.testing.assert_allclose(np.array(mesh.GetAttribute("points").Get(float(frame))), ours[k],
                                   atol=1e-5 * walk_body.size, rtol=0)


def test_usd_mesh_follows_the_skel_binding_spec(walk, walk_body, tmp_path):
    from pxr import Usd, UsdGeom, UsdSkel

    from usdmotion.io.usd_mesh import body_decorator

    path = tmp_path / "spec.usdc"
    write_motion(walk, path, decorate=body_decorator(walk_body))
    stage = Usd.Stage.Open(str(path))
    mesh = stage.GetDefaultPrim().GetChild("Body")
    assert mesh.IsA(UsdGeom.Mesh) and mesh.HasAPI(UsdSkel.BindingAPI)
    binding = UsdSkel.BindingAPI(mesh)
    indices, weights = binding.GetJointIndicesPrimvar(), binding.GetJointWeightsPrimvar()
    assert indices.GetElementSize() == INFLUENCES and weights.GetElementSize() == INFLUENCES
    assert indices.GetInterpolation() == UsdGeom.Tokens.vertex
    w = np.array(weights.Get()).reshape(-1, INFLUENCES)
    i = np.array(indices.Get()).reshape(-1, INFLUENCES)
    n_points = len(mesh.GetAttribute("points").Get())
    assert w.shape[0] == n_points and np.all(w >= 0)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    assert i.min() >= 0 and i.max() < walk.n_joints
    assert [str(t) for t in binding.GetSkeletonRel().GetTargets()] == [f"{stage.GetDefaultPrim().GetPath()}/Skeleton"]
    assert np.allclose(np.array(binding.GetGeomBindTransformAttr().Get()), np.eye(4))
    # end sites never influence the skin (they carry no rotation of their own)
    assert not np.isin(i[w > 0], np.flatnonzero(walk.end_sites)).any()


@pytest.mark.parametrize("relative, units, up", [
    ("cmu/cgspeed_12_01_walk.bvh", "asf", "Y"),
    ("bandai1/dataset-1_run_normal_001.bvh", "cm", "Y"),       # rest pose along +X, moving root joint
    ("other_rigs/20tab_test_freebvh_mixamorig.bvh", "cm", "Y"),  # ':' in names, fingers
    ("other_rigs/ad_cartwheel_clean.bvh", "in", "Z"),           # Z-up, no End Sites
    ("edge_cases/bvhanim_test_simple.bvh", "cm", "Y"),          # 2 joints
])
def test_body_is_closed_encloses_its_bones_and_is_normalised(shared_file, relative, units, up):
    motion = read_motion(shared_file(relative), units=units, up_axis=up)
    body = build_body(motion, resolution=48)
    import trimesh

    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    assert mesh.is_watertight and mesh.volume > 0  # closed, normals outwards
    np.testing.assert_allclose(body.joint_weights.sum(axis=1), 1.0, atol=1e-9)
    assert body.joint_indices.shape == (len(body.vertices), INFLUENCES)
    # the midpoints of every solid capsule lie inside the surface (winding number ≈ 1)
    caps = bone_capsules(motion, positions=body.bind_transforms[:, :3, 3])
    mid = 0.5 * (caps.start + caps.end)[caps.solid]
    assert np.all(winding_number(body.vertices, body.faces, mid) > 0.5)
    # and points well outside the body are outside
    far = body.vertices.max(axis=0) + 0.2 * body.size
    assert abs(winding_number(body.vertices, body.faces, far[None])[0]) < 1e-6


def test_bandai_body_is_built_in_an_upright_pose_not_the_lying_rest_pose(shared_file):
    motion = read_motion(shared_file("bandai1/dataset-1_run_normal_001.bvh"))
    body = build_body(motion, resolution=40)
    extent = np.ptp(body.vertices, axis=0)
    assert np.argmax(extent) == 1  # tallest along Y (up): a standing body
    # skinning the bind frame reproduces the bind mesh, and joints stay inside the skin
    positions = joint_positions(motion)
    frame = int(np.argmin(np.abs(positions[:, 1, 0] - body.bind_transforms[1, 0, 3])
                          + np.abs(positions[:, 1, 2] - body.bind_transforms[1, 2, 3])))
    skinned = skin_frames(body, motion, np.array([frame]))[0]
    np.testing.assert_allclose(skinned, body.vertices, atol=1e-6 * body.size)

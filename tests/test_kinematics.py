"""Forward kinematics: hand-computed cases, NumPy vs JAX, and the Motion invariants."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from usdmotion.errors import TopologyError
from usdmotion.kinematics import fk, fk_arrays, joint_positions, rest_positions
from usdmotion.motion import Motion, validate_topology
from usdmotion.rotations import euler_to_quat


def chain_motion(angles_deg, root=(0.0, 0.0, 0.0)) -> Motion:
    """Three joints along +Y (lengths 1, 2), Z rotations per frame."""
    angles = np.deg2rad(np.asarray(angles_deg, float))  # (F, 3) z angles
    eulers = np.zeros(angles.shape + (3,))
    eulers[..., 0] = angles
    return Motion(
        joint_names=("root", "mid", "tip"),
        parents=np.array([-1, 0, 1]),
        offsets=np.array([[0.0, 0, 0], [0, 1, 0], [0, 2, 0]]),
        rotations=euler_to_quat(eulers, "ZXY"),
        root_translation=np.tile(root, (angles.shape[0], 1)),
        fps=30.0,
    )


def test_hand_computed_planar_chain():
    m = chain_motion([[0, 0, 0], [90, 0, 0], [90, -90, 0], [45, 45, 0]], root=(1.0, 2.0, 3.0))
    p = joint_positions(m)
    root = np.array([1.0, 2.0, 3.0])
    s = np.sqrt(0.5)
    expected = np.array([
        [root, root + [0, 1, 0], root + [0, 3, 0]],
        [root, root + [-1, 0, 0], root + [-3, 0, 0]],       # +90° about Z turns +Y into -X
        [root, root + [-1, 0, 0], root + [-1, 2, 0]],       # then -90° brings the last bone back to +Y
        [root, root + [-s, s, 0], root + [-s, s, 0] + [-2, 0, 0]],
    ])
    assert np.allclose(p, expected, atol=1e-12)


def test_fk_matrices_agree_with_positions_and_are_rigid():
    m = chain_motion(np.random.default_rng(0).uniform(-180, 180, (10, 3)))
    t = fk(m)
    assert t.shape == (10, 3, 4, 4)
    assert np.allclose(t[..., :3, 3], joint_positions(m))
    r = t[..., :3, :3]
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(t[..., 3, :], [0, 0, 0, 1])


def test_branching_tree_in_any_order_of_depth():
    # root -> a -> b ; root -> c ; a -> d  (depths interleaved in index order)
    parents = np.array([-1, 0, 1, 0, 1])
    offsets = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 2.0]])
    q = np.zeros((1, 5, 4))
    q[..., 0] = 1
    q[0, 1] = euler_to_quat(np.array([0, 0, np.pi / 2]), "XYZ")  # a: +90° about Z
    m = Motion(("r", "a", "b", "c", "d"), parents, offsets, q, np.zeros((1, 3)), 10.0)
    p = joint_positions(m)[0]
    assert np.allclose(p, [[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 0, 1], [1, 0, 2]], atol=1e-12)
    assert np.allclose(rest_positions(m), [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 1], [1, 0, 2]])


def test_jax_fk_matches_numpy_and_jits():
    jax = pytest.importorskip("jax")
    m = chain_motion(np.random.default_rng(1).uniform(-90, 90, (6, 3)))
    trans = np.tile(m.offsets, (6, 1, 1))
    fn = jax.jit(lambda q, t: fk_arrays(q, t, m.parents)[1])
    assert np.allclose(np.asarray(fn(m.rotations, trans)), joint_positions(m), atol=1e-5)


def test_topology_validation():
    assert validate_topology(np.array([-1, 0, 0, 2]))[0]
    for parents, fragment in [([0, 0], "root"), ([-1, -1], "second root"), ([-1, 2, 0], "does not come before"),
                              ([-1, 1], "does not come before"), ([], "at least one joint")]:
        ok, reason = validate_topology(np.array(parents, dtype=int))
        assert not ok and fragment in reason
    with pytest.raises(TopologyError, match="cycle or bad order"):
        Motion(("a", "b"), np.array([-1, 1]), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (1, 2, 1)), np.zeros((1, 3)), 30)


def test_motion_is_immutable_and_validates_shapes():
    m = chain_motion([[0, 0, 0]])
    with pytest.raises(ValueError):
        m.rotations[0, 0, 0] = 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.fps = 10.0
    with pytest.raises(ValueError, match="root_translation"):
        dataclasses.replace(m, root_translation=np.zeros((2, 3)))
    with pytest.raises(TopologyError, match="unique"):
        dataclasses.replace(m, joint_names=("a", "a", "b"))
    with pytest.raises(ValueError, match="fps"):
        dataclasses.replace(m, fps=0.0)
    longer = m.with_frames(np.tile(m.rotations, (3, 1, 1)), np.zeros((3, 3)))
    assert longer.n_frames == 3 and longer.source_channels is None


def test_sliced_keeps_the_euler_hint_of_the_kept_frames():
    from usdmotion.io.bvh import motion_from_bvh, parse_bvh

    text = ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            "JOINT b\n{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n}\n}\nMOTION\nFrames: 4\n"
            "Frame Time: 0.1\n" + "".join(f"{k} 0 0 {10 * k} 0 0 {370 + k} 0 0\n" for k in range(4)))
    motion = motion_from_bvh(parse_bvh(text))
    part = motion.sliced(1, 3)
    assert part.n_frames == 2
    assert np.array_equal(part.rotations, motion.rotations[1:3])
    assert np.array_equal(part.root_translation, motion.root_translation[1:3])
    assert np.array_equal(part.source_channels, motion.source_channels[1:3])  # 371°, 372° survive a write


def test_position_bounds_are_exactly_the_bounds_of_joint_positions():
    from usdmotion.io import read_motion
    from usdmotion.kinematics import position_bounds

    walk = read_motion(Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh", units="asf")
    positions = joint_positions(walk).reshape(-1, 3)
    low, high = position_bounds(walk)
    assert np.array_equal(low, positions.min(axis=0)) and np.array_equal(high, positions.max(axis=0))


def test_a_motion_without_frames_writes_a_usd_stage_with_its_rest_pose_extent(tmp_path):
    # main at 472b012 failed here with NumPy's "zero-size array to reduction operation minimum"
    from pxr import Usd, UsdGeom, UsdSkel

    from usdmotion.io import read_motion, write_motion

    walk = read_motion(Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh", units="asf")
    empty = walk.with_frames(rotations=walk.rotations[:0], root_translation=walk.root_translation[:0])
    stage = Usd.Stage.Open(str(write_motion(empty, tmp_path / "empty.usda")))
    root = stage.GetDefaultPrim()
    lo, hi = (np.array(v) for v in UsdGeom.Boundable(root).GetExtentAttr().Get())
    query = UsdSkel.Cache().GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(root.GetPath().AppendChild("Skeleton"))))
    world = np.array([np.array(m)[3, :3] for m in query.ComputeJointSkelTransforms(Usd.TimeCode.Default())])
    assert np.allclose(lo, world.min(axis=0), atol=1e-5) and np.allclose(hi, world.max(axis=0), atol=1e-5)

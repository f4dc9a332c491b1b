"""Re-orientation, displacement maps and additive layers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from edit_support import angle_between, euler_wxyz, walker
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions
from usdmotion.ops.edit import EditError, displace, layer, reorient
from usdmotion.ops.edit.trajectory import carrier_joint


def test_rotate_turns_every_joint_about_the_start(shared_file):
    m = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    out = reorient(m, rotate=90)
    p, q = joint_positions(m), joint_positions(out)
    pivot = m.root_translation[0] * [1, 0, 1]
    expected = Rotation.from_euler("y", 90, degrees=True).apply((p - pivot).reshape(-1, 3)).reshape(p.shape) + pivot
    np.testing.assert_allclose(q, expected, atol=1e-8)


def test_heading_and_position_set_travel_direction_and_start(shared_file):
    m = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    out = reorient(m, heading_deg=225, position=(10, -20))
    root = out.root_translation
    travel = root[-1] - root[0]
    assert math.degrees(math.atan2(travel[0], travel[2])) % 360 == pytest.approx(225, abs=1e-6)  # 0° = +Z, 90° = +X
    np.testing.assert_allclose(root[0, [0, 2]], [10, -20], atol=1e-9)
    assert root[0, 1] == pytest.approx(m.root_translation[0, 1])
    moved = reorient(m, translate=(1, 2, 3))
    np.testing.assert_allclose(joint_positions(moved), joint_positions(m) + [1, 2, 3], atol=1e-9)


def test_reorient_a_rig_whose_hips_carry_the_path(shared_file):
    m = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    assert carrier_joint(m) == 1  # joint_Root stays at the origin, Hips travels
    out = reorient(m, rotate=-90, position=(0, 0))
    p = joint_positions(out)
    hips = p[:, 1]
    np.testing.assert_allclose(hips[0, [0, 2]], 0.0, atol=1e-9)
    d_in = joint_positions(m)[-1, 1] - joint_positions(m)[0, 1]
    d_out = hips[-1] - hips[0]
    np.testing.assert_allclose(d_out, Rotation.from_euler("y", -90, degrees=True).apply(d_in), atol=1e-8)
    with pytest.raises(EditError, match="rotate or heading, not both"):
        reorient(m, rotate=1, heading_deg=2)
    with pytest.raises(EditError, match="2 \\(ground\\) or 3"):
        reorient(m, position=(1,))


def test_displacement_hits_the_keyed_pose_and_eases_out():
    m = walker(n_frames=120)
    arm = m.joint_names.index("LeftUpLeg")
    target = [10.0, 45.0, -20.0]  # Euler ZXY degrees, the joint's channel order
    out = displace(m, [{"joint": "LeftUpLeg", "frame": 60, "rotation": target}], falloff=20)
    assert angle_between(out.rotations[60, arm], euler_wxyz(np.array(target))) < 1e-9
    untouched = np.r_[0:40, 81:120]
    assert np.max(angle_between(out.rotations[untouched], m.rotations[untouched])) < 1e-12
    # between the keys: q · exp(δ(t)) with δ a clamped cubic through 0, δ(60), 0 (SciPy, independently)
    delta60 = Rotation.from_quat(m.rotations[60, arm], scalar_first=True).inv() * Rotation.from_euler(
        "ZXY", target, degrees=True)
    spline = CubicSpline([40, 60, 80], np.stack([np.zeros(3), delta60.as_rotvec(), np.zeros(3)]), bc_type="clamped")
    for f in (45, 52, 71):
        ref = Rotation.from_quat(m.rotations[f, arm], scalar_first=True) * Rotation.from_rotvec(spline(f))
        assert angle_between(out.rotations[f, arm], ref.as_quat(scalar_first=True)) < 1e-9
    others = [j for j in range(m.n_joints) if j != arm]
    np.testing.assert_array_equal(out.rotations[:, others], m.rotations[:, others])


def test_displacement_translation_and_parent_frame():
    m = walker(n_frames=50)
    out = displace(m, [{"joint": "Hips", "frame": 10, "translate": [0, -5, 0]},
                       {"joint": "Hips", "frame": 30, "translate": [0, -5, 0]}])
    np.testing.assert_allclose(out.root_translation - m.root_translation, [[0, -5, 0]] * 50, atol=1e-12)
    turn = displace(m, [{"joint": "Spine", "frame": 0, "rotate": [0, 0, 30]}], frame="parent")
    ref = Rotation.from_euler("ZXY", [0, 0, 30], degrees=True) * Rotation.from_quat(m.rotations[:, 1],
                                                                                     scalar_first=True)
    assert np.max(angle_between(turn.rotations[:, 1], ref.as_quat(scalar_first=True))) < 1e-9


def test_layer_adds_a_curve_about_the_local_axis():
    m = walker(n_frames=90)
    keys = [(0, 0.0), (30, 25.0), (89, -10.0)]
    out = layer(m, "Head", "rx", keys)
    curve = CubicSpline([0, 30, 89], [0.0, 25.0, -10.0], bc_type="clamped")(np.arange(90))
    ref = (Rotation.from_quat(m.rotations[:, 2], scalar_first=True)
           * Rotation.from_euler("x", curve[:, None], degrees=True))
    assert np.max(angle_between(out.rotations[:, 2], ref.as_quat(scalar_first=True))) < 1e-9
    lifted = layer(m, "Hips", "ty", [(0, 0.0), (89, 9.0)])
    np.testing.assert_allclose(lifted.root_translation[-1, 1] - m.root_translation[-1, 1], 9.0)
    spine = layer(m, "Spine", "tz", [(0, 2.0)])
    np.testing.assert_allclose(joint_positions(spine)[:, 1] - joint_positions(m)[:, 1],
                               Rotation.from_quat(m.rotations[:, 0], scalar_first=True).apply([0, 0, 2.0]), atol=1e-9)
    assert spine.channels[1][:3] == ("Xposition", "Yposition", "Zposition")  # BVH gets position channels


@pytest.mark.parametrize("keys, message", [
    ([{"joint": "Nope", "frame": 1, "rotate": [0, 0, 1]}], "no joint named 'Nope'"),
    ([{"joint": "Head", "frame": 500, "rotate": [0, 0, 1]}], "outside the motion's frames 0..49"),
    ([{"joint": "Head", "frame": 5}], "needs 'rotate', 'rotation' or 'translate'"),
    ([{"joint": "Head", "frame": 5, "rotate": [1, 2]}], "3 Euler angles"),
    ([{"joint": "Head", "frame": 5, "rotate": [1, 2, 3], "rotation": [1, 2, 3]}], "not both"),
    ([], "at least one key"),
])
def test_displacement_errors(keys, message):
    with pytest.raises(EditError, match=message):
        displace(walker(n_frames=50), keys)

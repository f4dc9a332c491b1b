"""Synthesis: the giant swing of ALGORITHMS.md §2 (Must show 2), documents and their errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdmotion.errors import InputError
from usdmotion.io import read_motion, write_motion
from usdmotion.kinematics import joint_positions
from usdmotion.synthesis import JointSpec, example_path, load_synthesis, synthesize

# The paper's table (ALGORITHMS.md §2), degrees, relative Z angles.
ARMS = [16.6, 27.8, 39.6, 52.7, 67.5, 84.1, 102.3, 121.9, 142.9, 164.8, 186.3, 205.5, 222.1, 237.3, 253.8, 272.9,
        293.4, 312.2, 327.2, 338.7, 347.8, 355.8, 363.3]
BODY = [7.0, 6.2, 5.5, 4.7, 3.9, 3.2, 2.8, 2.7, 2.9, 3.9, 6.4, 11.8, 20.6, 31.0, 38.2, 38.1, 31.3, 21.5, 12.7, 6.6,
        3.5, 3.0, 4.1]
LEGS = [-2.7, 0.2, 2.0, 0.8, -5.0, -15.8, -28.2, -36.5, -37.2, -31.4, -22.3, -11.1, -0.8, 3.9, 2.2, -2.3, -5.4,
        -5.5, -3.1, -0.3, 1.6, 2.3, 1.9]


def swing_by_hand() -> np.ndarray:
    """(23, 4, 3) positions of hands, shoulders, hips, feet: planar chain of 10, 12, 16 units along +Y at rest."""
    a = np.deg2rad(np.cumsum([ARMS, BODY, LEGS], axis=0))  # absolute segment angles
    out = np.zeros((23, 4, 3))
    for k, length in enumerate((10.0, 12.0, 16.0)):
        # R_z(a) (0, L, 0) = (-L sin a, L cos a, 0)
        out[:, k + 1] = out[:, k] + length * np.stack([-np.sin(a[k]), np.cos(a[k]), np.zeros(23)], axis=1)
    return out


@pytest.fixture(scope="module")
def swing():
    return load_synthesis(example_path("giant_swing"))


def test_giant_swing_example_is_the_papers_model(swing):
    assert swing.joint_names == ("Arms", "Body", "Legs", "Legs_End")
    assert swing.n_frames == 23 and swing.fps == 30.0
    assert np.allclose(np.linalg.norm(swing.offsets[1:], axis=1), [10, 12, 16])
    assert np.allclose(joint_positions(swing), swing_by_hand(), atol=1e-12)
    # the swing is a full backward circle: feet angle about the bar covers ~347 degrees
    feet = swing_by_hand()[:, 3]
    turn = np.unwrap(np.arctan2(feet[:, 1], feet[:, 0]))
    assert abs(np.degrees(turn[-1] - turn[0])) > 340


def test_giant_swing_bvh_reads_back_in_our_reader_and_pybvh(swing, tmp_path):
    path = write_motion(swing, tmp_path / "swing.bvh")
    text = path.read_text()
    assert "OFFSET 0.0 10.0 0.0" in text and "363.3" in text  # the table survives exactly, angles > 360 too
    ours = read_motion(path, units=0.05)
    assert np.allclose(joint_positions(ours), swing_by_hand(), atol=1e-9)
    assert np.allclose(ours.source_channels[:, 3], ARMS)
    pybvh = pytest.importorskip("pybvh", reason="pybvh (an independent BVH library) is not installed")
    theirs = pybvh.read_bvh_file(str(path), world_up="+y")
    assert [n.name for n in theirs.nodes] == ["Arms", "Body", "Legs", "EndSiteLegs"]
    assert theirs.frame_count == 23 and abs(theirs.frame_time - 1 / 30) < 1e-9
    assert np.allclose(theirs.node_positions(), swing_by_hand(), atol=1e-9)
    # pybvh keeps the channel values (radians), Z first for ZXY
    assert np.allclose(np.degrees(theirs.joint_angles[:, :, 0]), np.stack([ARMS, BODY, LEGS], 1))


def test_giant_swing_usd_evaluated_by_usd_core(swing, tmp_path):
    from pxr import Usd, UsdGeom, UsdSkel

    path = write_motion(swing, tmp_path / "swing.usdz")
    stage = Usd.Stage.Open(str(path))
    skel = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    query = UsdSkel.Cache().GetSkelQuery(skel)
    world = np.array([np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(t)))[:, 3, :3]
                      for t in range(23)])
    assert np.allclose(world, swing_by_hand(), atol=1e-4)  # float32
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.05)


def test_strip_figure_draws_every_frame_of_the_swing(swing):
    from usdmotion.kinplot import strip_figure

    fig = strip_figure(swing, mark_origin=True)
    ax = fig.axes[0]
    bones = ax.lines[:3 * 23]  # one line per bone and frame, frame by frame
    forward_sign = np.sign(bones[0].get_xdata()[1] / swing_by_hand()[0, 1, 0])  # view may mirror X
    for f in (0, 11, 22):
        (u0, u1), (v0, v1) = bones[3 * f + 2].get_xdata(), bones[3 * f + 2].get_ydata()  # legs: hips -> feet
        hips, feet = swing_by_hand()[f, 2], swing_by_hand()[f, 3]
        assert np.allclose([u0, u1], forward_sign * np.array([hips[0], feet[0]]), atol=1e-9)
        assert np.allclose([v0, v1], [hips[1], feet[1]], atol=1e-9)
    assert len(fig.axes) == 1 + 12  # overview + a strip of 12 frames


def test_yaml_and_csv_table_give_the_same_motion(swing, tmp_path):
    spec = json.loads(example_path("giant_swing").read_text())
    angles = spec.pop("angles")
    spec.pop("$schema")
    spec["table"] = "angles.csv"
    rows = ["Arms.Z,Body.Z,Legs.Z"] + [f"{a},{b},{c}" for a, b, c in zip(*(angles[k]["Z"] for k in angles))]
    (tmp_path / "angles.csv").write_text("\n".join(rows) + "\n")
    import yaml

    (tmp_path / "swing.yaml").write_text(yaml.safe_dump(spec))
    other = load_synthesis(tmp_path / "swing.yaml")
    assert np.allclose(joint_positions(other), joint_positions(swing))
    assert np.array_equal(other.source_channels, swing.source_channels)


def test_api_builds_branching_skeletons_and_moving_roots():
    joints = [JointSpec("pelvis", offset=(0, 1, 0)), JointSpec("l_hip", "pelvis", (0.1, 0, 0), (0, -0.5, 0)),
              JointSpec("r_hip", "pelvis", (-0.1, 0, 0), (0, -0.5, 0), rotation_order="XYZ")]
    motion = synthesize(joints, {"l_hip": {"X": [0, 90]}, "r_hip": {"X": [0, -90]}},
                        fps=10, root_position={"Z": [0.0, 0.2]}, meters_per_unit=1.0)
    p = joint_positions(motion)
    assert motion.joint_names == ("pelvis", "l_hip", "l_hip_End", "r_hip", "r_hip_End")
    assert motion.channels[3] == ("Xrotation", "Yrotation", "Zrotation")
    assert np.allclose(p[1, 0], [0, 1, 0.2])
    assert np.allclose(p[1, 2], [0.1, 1, 0.2 - 0.5])    # +90 about X turns -Y into -Z
    assert np.allclose(p[1, 4], [-0.1, 1, 0.2 + 0.5])


@pytest.mark.parametrize("joints, angles, message", [
    ([JointSpec("a"), JointSpec("b", "c")], {}, r"/joints/1/parent: parent of 'b' 'c' is not defined before it"),
    ([JointSpec("a"), JointSpec("a", "a")], {}, r"/joints/1/name: joint 'a' is defined twice"),
    ([JointSpec("a", "b")], {}, r"/joints/0/parent: the first joint is the root"),
    ([JointSpec("a")], {"b": {"Z": [1]}}, r"/angles/b: no joint named 'b'"),
    ([JointSpec("a")], {"a": {"W": [1]}}, r"/angles/a/W: axis must be X, Y or Z"),
    ([JointSpec("a")], {"a": {"Z": [1, float("nan")]}}, r"/angles/a/Z: value 1 is not a finite number"),
    ([JointSpec("a"), JointSpec("b", "a")], {"a": {"Z": [1, 2]}, "b": {"Z": [1]}}, r"tables differ in length"),
    ([JointSpec("a b")], {}, r"/joints/0/name: 'a b' is not a usable joint name"),
])
def test_api_errors_are_one_line_and_name_the_place(joints, angles, message):
    with pytest.raises(InputError, match=message) as info:
        synthesize(joints, angles, source="spec.json")
    assert str(info.value).startswith("spec.json: ") and "\n" not in str(info.value)


@pytest.mark.parametrize("text, suffix, message", [
    ('{"fps": 30}', ".json", r"swing\.json: /: 'joints' is a required property"),
    ('{"fps": 30, "joints": [{"name": "a", "offset": [0, 1]}]}', ".json", r"/joints/0/offset: \[0, 1\] is too short"),
    ('{"fps": 30, "joints": [{"name": "a"}], "angles": {"a": {"Z": [1, NaN]}}}', ".json", r"not valid JSON"),
    ('{"fps": 30,\n "joints": [}', ".json", r"swing\.json:2:\d+: not valid JSON"),
    ("fps: 30\njoints: [{name: a}]\nangles: {a: {Z: [1, .nan]}}\n", ".yaml", r"/angles/a/Z/1: nan is not a finite"),
    ('{"fps": -1, "joints": [{"name": "a"}]}', ".json", r"/fps: -1 is less than or equal to the minimum of 0"),
])
def test_bad_documents(tmp_path, text, suffix, message):
    path = tmp_path / f"swing{suffix}"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        load_synthesis(path)
    assert "\n" not in str(info.value)

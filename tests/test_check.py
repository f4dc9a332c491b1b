"""Constraint checks against runs computed by hand from known angle tables."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdmotion.check import check_kinematics, check_motion, load_limits
from usdmotion.errors import InputError
from usdmotion.ops.analyse.measures import analyse, slice_frames
from usdmotion.ops.analyse.smoothing import FilterSpec
from usdmotion.synthesis import JointSpec, example_path, load_synthesis, synthesize

FPS = 100.0
T = np.arange(0, 2.0, 1 / FPS)
AMP, FREQ = 60.0, 1.0
ANGLE = AMP * np.sin(2 * np.pi * FREQ * T + 0.2)             # degrees
RATE = AMP * 2 * np.pi * FREQ * np.cos(2 * np.pi * FREQ * T + 0.2)  # deg/s


def swinging_arm():
    joints = [JointSpec("shoulder", offset=(0, 1.5, 0)), JointSpec("elbow", "shoulder", (0, -0.3, 0), (0, -0.25, 0))]
    return synthesize(joints, {"elbow": {"Z": ANGLE}}, fps=FPS, meters_per_unit=1.0)


def expected_runs(values: np.ndarray, bad: np.ndarray, worst) -> list[tuple[int, int, float]]:
    runs, start = [], None
    for i, b in enumerate(list(bad) + [False]):  # hand-written reference, one frame at a time
        if b and start is None:
            start = i
        if not b and start is not None:
            runs.append((start, i - 1, float(worst(values[start:i]))))
            start = None
    return runs


def test_angle_and_speed_violations_are_the_runs_computed_by_hand():
    limits = {"joints": {"elbow": {"z": [-40, 50], "max_angular_speed": 300}}}
    found = check_motion(swinging_arm(), limits, filter=FilterSpec("none"))
    angles = [v for v in found if v.quantity.startswith("angle")]
    over = [(v.first_frame, v.last_frame, v.value) for v in angles if v.bound == "max"]
    under = [(v.first_frame, v.last_frame, v.value) for v in angles if v.bound == "min"]
    fast = [(v.first_frame, v.last_frame, v.value) for v in found if v.quantity == "angular_speed"]
    assert over == [(a, b, pytest.approx(w, abs=1e-3)) for a, b, w in expected_runs(ANGLE, ANGLE > 50, np.max)]
    assert under == [(a, b, pytest.approx(w, abs=1e-3)) for a, b, w in expected_runs(ANGLE, ANGLE < -40, np.min)]
    speed = np.abs(RATE)
    assert fast == [(a, b, pytest.approx(w, rel=1e-4)) for a, b, w in expected_runs(speed, speed > 300, np.max)]
    assert len(over) == 2 and len(under) == 2 and len(fast) == 5
    assert all(v.joint == "elbow" and v.unit in ("deg", "deg/s") for v in found)
    assert [v.first_frame for v in found] == sorted(v.first_frame for v in found)


def test_bend_speed_and_glob_limits():
    kin = analyse(swinging_arm(), FilterSpec("none"))
    # bend at the elbow = |angle|; the end site moves at |rate| * 0.25 m (rad/s)
    found = check_kinematics(kin, {"joints": {"elbow": {"bend": [None, 55]}, "*_End": {"max_speed": 1.5}}})
    bends = [v for v in found if v.quantity == "bend"]
    assert [(v.first_frame, v.last_frame) for v in bends] == [
        (a, b) for a, b, _ in expected_runs(np.abs(ANGLE), np.abs(ANGLE) > 55, np.max)]
    tip_speed = np.deg2rad(np.abs(RATE)) * 0.25
    speeds = [v for v in found if v.quantity == "speed"]
    assert [(v.joint, v.first_frame, v.last_frame) for v in speeds] == [
        ("elbow_End", a, b) for a, b, _ in expected_runs(tip_speed, tip_speed > 1.5, np.max)]
    assert check_kinematics(kin, {"joints": {"elbow": {"bend": [0, 61], "max_speed": 1.0}}}) == []


def test_frames_are_reported_in_source_numbering():
    motion = swinging_arm()
    kin = analyse(slice_frames(motion, 50), FilterSpec("none"), first_frame=50)
    found = check_kinematics(kin, {"joints": {"elbow": {"z": [None, 50]}}})
    runs = expected_runs(ANGLE, ANGLE > 50, np.max)
    assert [(v.first_frame, v.last_frame) for v in found] == [(max(a, 50), b) for a, b, _ in runs if b >= 50]
    assert found[0].start_time == pytest.approx(found[0].first_frame / FPS)


def test_synthesised_variants_breaking_limits_are_discarded():
    """The paper's wish: generate variants of the giant swing, keep those within the limits."""
    limits = load_limits(example_path("giant_swing").with_name("giant_swing_limits.json"))
    base = json.loads(example_path("giant_swing").read_text())
    kept = []
    for hip_scale in (0.8, 1.0, 1.3, 1.6):
        from usdmotion.synthesis import motion_from_spec

        spec = json.loads(json.dumps(base))
        spec["angles"]["Legs"]["Z"] = [hip_scale * a for a in base["angles"]["Legs"]["Z"]]
        if not check_motion(motion_from_spec(spec), limits):
            kept.append(hip_scale)
    # hip limit -45 deg: the paper's deepest hip angle is -37.2, x1.3 gives -48.4
    assert kept == [0.8, 1.0]


def test_unknown_joint_and_undefined_bend_name_the_file():
    kin = analyse(load_synthesis(example_path("giant_swing")))
    with pytest.raises(InputError, match=r"lim\.json: /joints/Bdy: no joint named 'Bdy' \(did you mean Body"):
        check_kinematics(kin, {"joints": {"Bdy": {"z": [0, 1]}}}, "lim.json")
    with pytest.raises(InputError, match=r"/joints/Arms/bend: joint 'Arms' has no single bone in and out"):
        check_kinematics(kin, {"joints": {"Arms": {"bend": [0, 1]}}}, "lim.json")
    with pytest.warns(UserWarning, match=r"/joints/Foot\* matches no joint"):
        assert check_kinematics(kin, {"joints": {"Foot*": {"max_speed": 1}}}, "lim.json") == []


@pytest.mark.parametrize("text, message", [
    ('{"joints": {"Body": {"z": [10, 5]}}}', r"/joints/Body/z: minimum 10 is above maximum 5"),
    ('{"joints": {"Body": {"zz": [1, 5]}}}', r"/joints/Body: Additional properties are not allowed \('zz'"),
    ('{"joints": {"Body": {"max_speed": -1}}}', r"/joints/Body/max_speed: -1 is less than or equal to the minimum"),
    ('{"joints": {"Body": {"z": [1]}}}', r"/joints/Body/z: \[1\] is too short"),
    ('{"joints": {}}', r"/joints: {} should be non-empty"),
    ('{"joints": {"Body": {"z": [1, 2]}}', r"lim\.json:1:\d+: not valid JSON"),
])
def test_malformed_limits(tmp_path, text, message):
    path = tmp_path / "lim.json"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        load_limits(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)

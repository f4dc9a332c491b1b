"""Body-segment models: name parsing, landmarks on the shared rigs, de Leva's numbers."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.anthropometry import body_model, custom_model, de_leva_model, find_landmarks, side_and_base
from usdmotion.errors import InputError
from usdmotion.io import read_motion
from usdmotion.synthesis import example_path, load_synthesis


@pytest.mark.parametrize("name, expected", [
    ("LeftForeArm", ("left", "forearm")), ("mixamorig:RightLeg", ("right", "leg")), ("lShldr", ("left", "shldr")),
    ("LowerArm_L", ("left", "lowerarm")), ("lhand", ("left", "hand")), ("rfemur", ("right", "femur")),
    ("lowerback", (None, "lowerback")), ("RHipJoint", ("right", "hipjoint")), ("Hips", (None, "hips")),
    ("Knee.R", ("right", "knee")), ("leg", (None, "leg")), ("UpperLeg_R", ("right", "upperleg")),
])
def test_side_and_base(name, expected):
    assert side_and_base(name) == expected


RIGS = {
    "cmu/cgspeed_12_01_walk.bvh": ("preset cgspeed-mb", {"left_knee": "LeftLeg", "right_hand_tip": "RightHandIndex1_End",
                                                         "neck": "Neck", "head_top": "Head_End"}),
    "cmu/max_131_01_start_walk_stop.bvh": ("preset cgspeed-max", {"left_shoulder": "LeftShoulder",
                                                                  "left_toe_tip": "LeftToe_End"}),
    "cmu/daz_10_01_soccer_kick.bvh": ("preset daz", {"right_knee": "rShin", "left_hip": "lThigh"}),
    "bandai1/dataset-1_walk_normal_001.bvh": ("preset bandai", {"left_elbow": "LowerArm_L", "right_ankle": "Foot_R"}),
    "other_rigs/ad_mixamo_Boxing.bvh": ("guessed from joint names", {
        "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm", "left_wrist": "LeftHand", "right_hip": "RightUpLeg",
        "right_knee": "RightLeg", "right_ankle": "RightFoot", "right_toe_tip": "RightToeBase_End", "neck": "Neck",
        "head_top": "HeadTop_End_End", "left_hand_tip": "LeftHandMiddle3_End"}),
    "edge_cases/bvhio_example.bvh": ("guessed from joint names", {"left_shoulder": "LeftUpArm",
                                                                  "left_elbow": "LeftLowArm", "left_knee": "LeftLowLeg"}),
    "other_rigs/ad_karate_mawashigeri.bvh": ("guessed from joint names", {"left_shoulder": "lhumerus",
                                                                          "left_elbow": "lradius", "left_hip": "lfemur",
                                                                          "left_knee": "ltibia", "left_ankle": "lfoot"}),
}


@pytest.mark.parametrize("relative", sorted(RIGS))
def test_landmarks_on_the_shared_rigs(shared_file, relative):
    motion = read_motion(shared_file(relative))
    found, how = find_landmarks(motion)
    expected_how, expected = RIGS[relative]
    assert how == expected_how
    assert {k: motion.joint_names[found[k]] for k in expected} == expected
    model = de_leva_model(motion)
    assert model.weights.shape == (14, motion.n_joints) and np.isclose(model.mass_fractions.sum(), 1.0)


def test_de_leva_numbers_and_overrides(shared_file):
    motion = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"), units="asf")
    male, female = de_leva_model(motion, "male"), de_leva_model(motion, "female")
    masses = dict(zip(male.segment_names, male.mass_fractions))
    assert masses["left_thigh"] == pytest.approx(0.1416) and masses["trunk"] == pytest.approx(0.4346)
    assert dict(zip(female.segment_names, female.mass_fractions))["head"] == pytest.approx(0.0668 / 0.9999)
    knee, ankle = motion.joint_index("LeftLeg"), motion.joint_index("LeftFoot")
    shank = male.weights[male.segment_names.index("left_shank")]
    assert shank[knee] == pytest.approx(1 - 0.4395) and shank[ankle] == pytest.approx(0.4395)
    moved = de_leva_model(motion, overrides={"left_ankle": "LeftToeBase"}, source="seg.json")
    assert moved.landmarks["left_ankle"] == "LeftToeBase"
    with pytest.raises(InputError, match=r"seg\.json: /landmarks/left_ankel: unknown landmark"):
        de_leva_model(motion, overrides={"left_ankel": "LeftFoot"}, source="seg.json")


def test_custom_segments_and_missing_landmarks():
    swing = load_synthesis(example_path("giant_swing"))
    with pytest.raises(InputError, match=r"cannot find neck, left_shoulder, .* --segments"):
        body_model(swing, source="swing.json")
    table = [{"name": "arms", "from": "Arms", "to": "Body", "mass_fraction": 0.1, "com_fraction": 0.5},
             {"name": "body", "from": "Body", "to": "Legs", "mass_fraction": 0.5, "com_fraction": 0.5},
             {"name": "legs", "from": "Legs", "to": "Legs_End", "mass_fraction": 0.4, "com_fraction": 0.4}]
    model = body_model(swing, segment_map={"segments": table})
    from usdmotion.kinematics import joint_positions

    p = joint_positions(swing)
    by_hand = (0.1 * (p[:, 0] + p[:, 1]) / 2 + 0.5 * (p[:, 1] + p[:, 2]) / 2 + 0.4 * (0.6 * p[:, 2] + 0.4 * p[:, 3]))
    assert np.allclose(model.com(p), by_hand)
    half = custom_model(swing, [dict(table[0], mass_fraction=0.5)])
    assert half.notes == ("mass fractions summed to 0.5; normalised to 1",)
    with pytest.raises(InputError, match=r"/segments/0/to: no joint named 'Boddy'"):
        custom_model(swing, [dict(table[0], to="Boddy")])

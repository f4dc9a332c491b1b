"""Rig recognition on the rig families of issue 17 (tests/data/rigs/, written by
tests/data/rigs/make_rigs.py with each family's real joint names): the rig profile,
segmentation roles, body landmarks and bend angles (analyze), contact joints, and the
automatic joint maps from the CMU and Bandai rigs with a reason for every unmapped joint."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import TEST_DATA

from usdmotion.anthropometry import de_leva_model, find_landmarks
from usdmotion.io import read_motion
from usdmotion.kinematics import rest_positions
from usdmotion.ops.analyse.measures import bend_triples
from usdmotion.ops.contacts import contact_joints
from usdmotion.ops.retarget.jointmap import auto_map, resolve_map, unmapped_reasons
from usdmotion.ops.segment.roles import find_roles
from usdmotion.skeleton_names import (detect_profile, joint_kinds, parse_side, profile_joints, rig_profiles)

RIGS = TEST_DATA / "rigs"
#: Per rig file: its profile, and the left-side limb joints (shoulder, elbow, wrist, hip, knee, ankle, toe).
EXPECTED = {
    "character_creator": ("character_creator", "CC_Base_Hip", ("CC_Base_L_Upperarm", "CC_Base_L_Forearm", "CC_Base_L_Hand",
                          "CC_Base_L_Thigh", "CC_Base_L_Calf", "CC_Base_L_Foot", "CC_Base_L_ToeBase")),
    "unreal": ("unreal", "pelvis", ("upperarm_l", "lowerarm_l", "hand_l", "thigh_l", "calf_l", "foot_l", "ball_l")),
    "rigify": ("rigify", "DEF-spine", ("DEF-upper_arm.L", "DEF-forearm.L", "DEF-hand.L", "DEF-thigh.L", "DEF-shin.L",
                                       "DEF-foot.L", "DEF-toe.L")),
    "biped": ("biped", "Bip01 Pelvis", ("Bip01 L UpperArm", "Bip01 L Forearm", "Bip01 L Hand", "Bip01 L Thigh",
                                        "Bip01 L Calf", "Bip01 L Foot", "Bip01 L Toe0")),
    "humanik": ("humanik", "Character1:Hips", tuple(f"Character1:{n}" for n in (
        "LeftArm", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"))),
    "smpl": ("smpl", "Pelvis", ("L_Shoulder", "L_Elbow", "L_Wrist", "L_Hip", "L_Knee", "L_Ankle", "L_Foot")),
}
LIMB = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")


def right(name: str) -> str:
    """The right-side twin of a left joint name of these rigs."""
    for left, right_ in (("Left", "Right"), ("_L_", "_R_"), (" L ", " R "), (".L", ".R"), ("_l", "_r"), ("L_", "R_")):
        if left in name:
            return name.replace(left, right_)
    raise AssertionError(name)


@pytest.fixture(scope="module")
def rigs():
    return {name: read_motion(RIGS / f"{name}.bvh") for name in EXPECTED}


@pytest.mark.parametrize("rig", sorted(EXPECTED))
def test_profile_roles_landmarks_and_bends_find_the_limbs(rigs, rig):
    motion = rigs[rig]
    profile, hips, (*limb, toe) = EXPECTED[rig]
    assert detect_profile(motion.joint_names) == profile
    names = motion.joint_names
    roles = {k: names[v] for k, v in find_roles(motion, source=rig).items()}  # segment
    for role, joint in zip(LIMB, limb):
        assert roles[f"left_{role}"] == joint and roles[f"right_{role}"] == right(joint), role
    assert roles["root"] == hips
    found, _ = find_landmarks(motion, source=rig)  # analyze: body-segment landmarks
    for part, joint in zip(("shoulder", "elbow", "wrist", "hip", "knee", "ankle"), limb):
        assert names[found[f"left_{part}"]] == joint and names[found[f"right_{part}"]] == right(joint), part
    model = de_leva_model(motion, source=rig)
    assert model.com_weights.sum() == pytest.approx(1.0) and model.notes == ()  # every landmark found
    triples = {names[j]: (names[a], names[b]) for j, a, b in bend_triples(motion)}  # analyze: joint angles
    for middle, lower in ((limb[1], limb[2]), (limb[4], limb[5])):
        assert triples[middle][1] == lower, middle  # the elbow and knee bend towards the wrist and ankle
    parts, indices = contact_joints(motion)
    assert [names[i] for i, p in zip(indices, parts) if p.startswith("left")] == [limb[5], toe]


def test_rest_bend_angles_are_those_of_the_limb_points(rigs):
    """The knee angle analyze reports at frame 1 equals the angle of hip-knee-ankle computed here."""
    from usdmotion.kinematics import joint_positions
    from usdmotion.ops.analyse.measures import bend_angles

    for rig, motion in rigs.items():
        _, _, (_, _, _, hip, knee, ankle, _) = EXPECTED[rig]
        p = joint_positions(motion)
        i = [motion.joint_index(n) for n in (hip, knee, ankle)]
        a, b = p[1, i[1]] - p[1, i[0]], p[1, i[2]] - p[1, i[1]]
        expected = np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b)))
        angles = bend_angles(p, bend_triples(motion), motion.n_joints)
        assert angles[1, i[1]] == pytest.approx(expected, abs=1e-6) and expected > 10, rig


@pytest.mark.parametrize("name, side_base", [
    ("CC_Base_L_Calf", ("left", "calf")), ("Bip01 R Forearm", ("right", "forearm")), ("L_Knee", ("left", "knee")),
    ("calf_l", ("left", "calf")), ("Character1:LeftUpLeg", ("left", "upleg")), ("Hand_L_End", (None, "handlend")),
    ("CC_Base_NeckTwist01", (None, "ccbasenecktwist01")),
])
def test_side_words_inside_names(name, side_base):
    assert parse_side(name) == side_base


def test_marked_twist_root_and_helper_bones(rigs):
    kinds = {rig: joint_kinds(rig_profiles()[EXPECTED[rig][0]], m.joint_names) for rig, m in rigs.items()}
    assert kinds["character_creator"]["RL_BoneRoot"] == "floor root"
    assert kinds["character_creator"]["CC_Base_L_ThighTwist01"] == "twist"
    assert kinds["character_creator"]["CC_Base_NeckTwist02"] == "twist"
    assert "CC_Base_NeckTwist01" not in kinds["character_creator"]  # the neck itself
    assert kinds["character_creator"]["CC_Base_L_KneeShareBone"] == "helper"
    assert kinds["unreal"]["root"] == "floor root" and kinds["unreal"]["ik_foot_root"] == "helper"
    assert kinds["unreal"]["thigh_twist_01_l"] == "twist" and kinds["unreal"]["ik_hand_gun"] == "helper"
    assert kinds["rigify"]["DEF-shin.L.001"] == "twist" and kinds["rigify"]["DEF-pelvis.L"] == "helper"
    assert kinds["biped"]["Bip01"] == "hips root" and kinds["biped"]["Bip01 Footsteps"] == "floor root"
    assert kinds["biped"]["Bip01 L ForeTwist"] == "twist"
    assert kinds["humanik"]["Character1:Reference"] == "floor root"
    assert kinds["humanik"]["Character1:LeftForeArmRoll"] == "twist"
    assert kinds["smpl"] == {}


def _source(shared_file, which):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if which == "cmu":
            return read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"), units="asf")
        return read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))


@pytest.mark.parametrize("which", ["cmu", "bandai"])
def test_automatic_maps_map_every_body_point_and_say_why_not_the_rest(shared_file, rigs, which, capsys):
    source = _source(shared_file, which)
    source_profile = detect_profile(source.joint_names)
    source_points = profile_joints(rig_profiles()[source_profile], source.joint_names)
    for rig, motion in rigs.items():
        profile = EXPECTED[rig][0]
        jmap = auto_map(source.joint_names, motion.joint_names, motion.end_sites)
        assert jmap.how == f"rig profiles {source_profile} -> {profile}"
        target_points = profile_joints(rig_profiles()[profile], motion.joint_names)
        both = set(source_points) & set(target_points)
        assert len(both) >= 19, (rig, sorted(both))  # hips, spine, chest, neck, head and 2 x 7 limb points
        assert {target_points[p]: source_points[p] for p in both} == {k: v for k, v in jmap.pairs.items() if v}
        reasons = unmapped_reasons(source.joint_names, motion.joint_names, jmap.pairs, motion.end_sites)
        unmapped = [n for n in motion.joint_names if jmap.pairs.get(n) is None]
        assert sorted(reasons) == sorted(unmapped)
        kinds = joint_kinds(rig_profiles()[profile], motion.joint_names)
        for name, why in reasons.items():
            assert why == kinds.get(name, why), name
            if why.startswith("no "):
                point = why.split()[1]
                assert point in target_points and point not in source_points
        print(f"{which} -> {rig}: {len(jmap.pairs)} mapped; unmapped: "
              + ", ".join(f"{n} ({w})" for n, w in reasons.items() if w != "end site"))
        # the resolved map is what retarget uses
        src, _, _ = resolve_map(None, source.joint_names, motion.joint_names, motion.end_sites)
        assert (src >= 0).sum() == len(both)
    printed = capsys.readouterr().out
    assert "RL_BoneRoot (floor root)" in printed and "thigh_twist_01_l (twist)" in printed


def test_mapped_points_sit_at_the_same_height_of_the_body(shared_file, rigs):
    """CMU's rest pose stands upright like the test rigs: every mapped pair is at the same height
    relative to the body (an independent check that the map pairs the same anatomy)."""
    source = _source(shared_file, "cmu")
    src_rest = rest_positions(source)
    src_height = np.ptp(src_rest[:, 1])
    for rig, motion in rigs.items():
        rest = rest_positions(motion)
        height = np.ptp(rest[:, 1])
        src, _, _ = resolve_map(None, source.joint_names, motion.joint_names, motion.end_sites)
        mapped = np.flatnonzero(src >= 0)
        t = (rest[mapped, 1] - rest[:, 1].min()) / height
        s = (src_rest[src[mapped], 1] - src_rest[:, 1].min()) / src_height
        assert np.abs(t - s).max() < 0.12, (rig, motion.joint_names[mapped[np.argmax(np.abs(t - s))]])
        lateral = np.abs(rest[mapped, 0]) > 0.05 * height  # and on the same side of the body
        assert np.all((np.sign(rest[mapped, 0]) == np.sign(src_rest[src[mapped], 0]))[lateral]), rig
        assert lateral.sum() >= 12, rig


def test_body_points_are_never_marked(rigs):
    biped = rigs["biped"]
    kinds = joint_kinds(rig_profiles()["biped"], biped.joint_names)
    assert "Bip01 HeadNub" not in kinds and "Bip01 L Toe0Nub" not in kinds  # head top, toe tip
    assert kinds["Bip01 L Finger2Nub"] == "helper"
    names = biped.joint_names
    triples = {names[j]: names[b] for j, _, b in bend_triples(biped)}
    assert triples["Bip01 Head"] == "Bip01 HeadNub" and triples["Bip01 L Toe0"] == "Bip01 L Toe0Nub"


@pytest.mark.parametrize("rig", sorted(EXPECTED))
def test_names_as_dcc_tools_write_them_to_usd_are_recognised_alike(rigs, rig):
    """Blender & co. write ``Bip01 L Thigh`` / ``DEF-thigh.L`` as USD paths ``Bip01_L_Thigh`` / ``DEF_thigh_L``."""
    import dataclasses
    import re

    motion = rigs[rig]
    safe = dataclasses.replace(motion, joint_names=tuple(re.sub(r"[^0-9A-Za-z_]", "_", n.split(":")[-1])
                                                         for n in motion.joint_names))
    rename = dict(zip(motion.joint_names, safe.joint_names))
    assert detect_profile(safe.joint_names) == EXPECTED[rig][0]
    assert {k: safe.joint_names[v] for k, v in find_roles(safe).items()} == \
        {k: rename[motion.joint_names[v]] for k, v in find_roles(motion).items()}
    assert find_landmarks(safe)[0] == find_landmarks(motion)[0]
    assert np.array_equal(bend_triples(safe), bend_triples(motion))
    assert joint_kinds(rig_profiles()[EXPECTED[rig][0]], safe.joint_names) == \
        {rename[k]: v for k, v in joint_kinds(rig_profiles()[EXPECTED[rig][0]], motion.joint_names).items()}


def test_smplx_lower_case_names_are_smpl_too(rigs):
    import dataclasses

    smpl = rigs["smpl"]
    words = {"L": "left", "R": "right"}

    def smplx(name: str) -> str:
        side, _, rest = name.partition("_")
        return f"{words[side]}_{rest.lower()}" if side in words and rest else name.lower()

    renamed = dataclasses.replace(smpl, joint_names=tuple(smplx(n) for n in smpl.joint_names))
    assert "left_knee" in renamed.joint_names and "pelvis" in renamed.joint_names
    assert detect_profile(renamed.joint_names) == "smpl"
    points = profile_joints(rig_profiles()["smpl"], renamed.joint_names)
    assert points["l_shin"] == "left_knee" and points["l_upper_arm"] == "left_shoulder" and points["hips"] == "pelvis"
    roles = {k: renamed.joint_names[v] for k, v in find_roles(renamed).items()}
    assert roles["left_knee"] == "left_knee" and roles["right_wrist"] == "right_wrist" and roles["root"] == "pelvis"

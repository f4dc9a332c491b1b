"""Joint maps: files (JSON Schema), rig profiles, automatic mapping. No JAX here."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from usdmotion.io import read_motion
from usdmotion.ops.retarget.jointmap import (JointMapError, auto_map, detect_profile, load_joint_map, normalise_name,
                                    profile_joints, resolve_map, rig_profiles)

RIGS = {  # shared file -> profile it must be recognised as
    "cmu/cgspeed_12_01_walk.bvh": "cmu_cgspeed",
    "cmu/cgspeed_01_01_playground_jumps.bvh": "cmu_cgspeed",
    "cmu/max_131_01_start_walk_stop.bvh": "cmu_max",
    "cmu/daz_10_01_soccer_kick.bvh": "daz",
    "bandai1/dataset-1_walk_normal_001.bvh": "bandai",
    "other_rigs/ad_mixamo_Boxing.bvh": "mixamo",
    "other_rigs/20tab_test_freebvh_mixamorig.bvh": "mixamo",
    "other_rigs/ad_rokoko_jesse_dance.bvh": "rokoko",
}


def names_of(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_motion(path).joint_names


@pytest.mark.parametrize("relative, profile", sorted(RIGS.items()))
def test_every_shared_rig_is_recognised(shared_file, relative, profile):
    names = names_of(shared_file(relative))
    assert detect_profile(names) == profile
    resolved = profile_joints(rig_profiles()[profile], names)
    assert set(resolved.values()) <= set(names)
    assert {"hips", "l_thigh", "r_hand", "head"} <= set(resolved)


def test_profiles_map_left_to_left(shared_file):
    src = names_of(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    for relative, left in (("cmu/daz_10_01_soccer_kick.bvh", "lShin"),
                           ("bandai1/dataset-1_walk_normal_001.bvh", "LowerLeg_L"),
                           ("other_rigs/20tab_test_freebvh_mixamorig.bvh", "mixamorig:LeftLeg")):
        jmap = auto_map(src, names_of(shared_file(relative)))
        assert jmap.pairs[left] == "LeftLeg"
        assert jmap.how.startswith("rig profiles cmu_cgspeed -> ")


def test_auto_map_same_names_and_normalised_names():
    same = auto_map(["Hips", "Spine", "LeftArm"], ["Hips", "Spine", "LeftArm", "Extra"])
    assert same.how == "same names" and same.pairs == {"Hips": "Hips", "Spine": "Spine", "LeftArm": "LeftArm"}
    fuzzy = auto_map(["pelvis", "Left_UpLeg", "upleg_R", "spinal"], ["Pelvis", "lUpLeg", "RightUpLeg", "Spine"])
    assert fuzzy.how == "normalised names"
    assert fuzzy.pairs == {"Pelvis": "pelvis", "lUpLeg": "Left_UpLeg", "RightUpLeg": "upleg_R"}
    assert [normalise_name(n) for n in ("mixamorig:LeftUpLeg", "Hand_L", "lShldr", "Spinal", "RHipJoint")] == \
        ["lupleg", "lhand", "lshldr", "spinal", "rhipjoint"]


def test_map_file_precedence_weights_and_unmapped(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"joints": {"b": "y", "c": None, "d": {"source": "x", "weight": 2.5}},
                                "weights": {"a": 0.0}, "auto": True}))
    jmap = load_joint_map(path)
    src, weights, resolved = resolve_map(jmap, ["x", "y", "a"], ["a", "b", "c", "d", "e"])
    assert src.tolist() == [2, 1, -1, 0, -1]  # a: auto (same name), b, c: listed, d: listed, e: nothing
    np.testing.assert_array_equal(weights, [0.0, 1, 1, 2.5, 1])
    assert resolved.how == f"normalised names + map file {path}"  # 1 of 5 names shared: not "same names"
    # without "auto" only the listed joints are mapped
    path.write_text(json.dumps({"joints": {"b": "y"}}))
    src, _, _ = resolve_map(load_joint_map(path), ["x", "y", "a"], ["a", "b"])
    assert src.tolist() == [-1, 1]
    # a derived rig's identity is the default, the file overrides it
    src, _, _ = resolve_map(load_joint_map(path), ["a", "b", "y"], ["a", "b"], default={"a": "a", "b": "b"})
    assert src.tolist() == [0, 2]


@pytest.mark.parametrize("text, message", [
    ("{", "not valid JSON"),
    ('{"joints": {"a": 3}}', "invalid joint map at joints/a"),
    ('{"joints": {}, "colour": "red"}', "invalid joint map at top level"),
    ('{"weights": {"a": 1}}', "invalid joint map at top level"),
    ('{"source_profile": "daz"}', "invalid joint map"),
])
def test_bad_map_files(tmp_path, text, message):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(JointMapError, match=message) as info:
        load_joint_map(path)
    assert str(info.value).startswith(str(path))


def test_missing_map_file(tmp_path):
    with pytest.raises(JointMapError, match="no such file"):
        load_joint_map(tmp_path / "nope.json")


def test_profile_map_rejects_a_skeleton_that_does_not_fit(tmp_path, shared_file):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"source_profile": "daz", "target_profile": "bandai"}))
    src = names_of(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    tgt = names_of(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    with pytest.raises(JointMapError, match="source skeleton does not fit rig profile 'daz'"):
        resolve_map(load_joint_map(path), src, tgt)

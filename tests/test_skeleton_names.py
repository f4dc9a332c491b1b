"""Joint recognition keeps its behaviour: roles, landmarks, bend triples and automatic
joint maps on every rig of the shared corpus equal the record made before
``ops/roles.py``, ``anthropometry.py`` and ``ops/jointmap.py`` shared one core,
:mod:`usdmotion.skeleton_names` (``tests/data/skeleton_names_golden.json``; how it was
made: ``tests/skeleton_names_record.py``).

The one side parser is the union of the two it replaced, so two renamed copies of the
DAZ rig that are not part of the corpus are now recognised further, on purpose: a
``grp|`` namespace (the landmark parser kept it in the name) and capital one-letter
sides before a limb word (``Lhand``: the role parser took ``Lforearm`` only). For them
the test checks that they are recognised exactly like the rig they were renamed from.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from conftest import SHARED_DATA, TEST_DATA
from skeleton_names_record import VARIANTS, record_maps, record_names, record_skeleton, skeletons_of

from usdmotion import anthropometry as A
from usdmotion.ops.segment import roles as R
from usdmotion.ops.retarget.jointmap import auto_map, detect_profile, load_joint_map, normalise_name, resolve_map
from usdmotion.skeleton_names import parse_side, profile_joints, rig_presets, rig_profiles

GOLDEN = json.loads((TEST_DATA / "skeleton_names_golden.json").read_text("utf-8"))
DAZ = "cmu/daz_10_01_soccer_kick.bvh"
#: Record fields that the union side parser changes on purpose, per renamed rig.
WIDENED = {"variant:namespace_pipe": {"landmarks", "landmarks_guessed", "de_leva", "profile", "profile_joints"},
           "variant:upper_case_letter": {"landmarks", "landmarks_guessed", "de_leva"}}
#: Names outside the corpus whose capital side letter now counts before any limb word.
#: Corpus rigs named like HumanIK (Hips, LeftUpLeg, LeftLeg, LeftForeArm; no rig of its own) that the
#: generic ``humanik`` profile recognises since it was added (issue 17): automatic maps to and from a
#: recognised rig go through the profiles now, no longer through normalised names.
HUMANIK = {"edge_cases/bvhtoolbox_walk01.bvh", "edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh",
           "edge_cases/pybvh_bvh_test3_60joints_mixed_orders.bvh", "edge_cases/wspr_milad_blank_line_6ch_125fps.bvh",
           "other_rigs/ad_fair1_zombie.bvh"}
#: Corpus rigs recognised by a profile since the record: the HumanIK-named ones, and AnimatedDrawings'
#: karate BVH (CMU ASF bone names on a BVH rig), whose ``asf`` profile takes part in automatic maps since
#: a karate → Rokoko retarget matched 5 joints by normalised names and its result lay ~1 m from the source.
#: The OptiTrack Arena and MocapBank rigs (Biovision-style LeftCollar/LeftShoulder/LeftElbow/LeftHip/LeftKnee names)
#: have the ``optitrack`` profile since a CMU walk onto the OptiTrack rig, mapped by normalised names (6 joints, cgspeed's
#: zero-length LeftShoulder onto its shoulder joint), was refused as "2.06x the size: units mismatched".
NEWLY_PROFILED = {**dict.fromkeys(HUMANIK, "humanik"), "other_rigs/ad_karate_mawashigeri.bvh": "asf",
                  "other_rigs/wspr_louise_optitrack_arena.bvh": "optitrack",
                  "edge_cases/20tab_test_mocapbank_crlf.bvh": "optitrack",
                  "edge_cases/pybvh_bvh_test2_crlf_yxz.bvh": "optitrack",  # Motive's Chest..Chest4, LeftToe
                  # ninth session: the Biovision example's names (LeftUpArm, LeftLowArm, LeftLowLeg; mapped by
                  # normalised names without elbows or knees), and AnimatedDrawings' cartwheel rig (ASF bone names
                  # with lowerback, upperback, LowerNeck, Neck: 6 joints by normalised names)
                  "edge_cases/bvhio_example.bvh": "biovision", "other_rigs/ad_cartwheel_clean.bvh": "asf"}
CAPITAL_SIDES = {"Lfoot": ("left", "foot"), "Lhand": ("left", "hand"), "Lshldr": ("left", "shldr"),
                 "Lthigh": ("left", "thigh"), "Rfoot": ("right", "foot"), "Rhand": ("right", "hand"),
                 "Rshldr": ("right", "shldr"), "Rthigh": ("right", "thigh")}


def plain(value):
    """``value`` as JSON reads it back (tuples → lists)."""
    return json.loads(json.dumps(value))


@pytest.fixture(scope="module")
def skeletons():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found under {SHARED_DATA} (set USDMOTION_SHARED_DATA)")
    return skeletons_of(SHARED_DATA)


@pytest.mark.parametrize("label", sorted(GOLDEN["skeletons"]))
def test_recognition_on_every_rig_is_unchanged(skeletons, label):
    if label not in skeletons:
        pytest.skip(f"{label} not found under {SHARED_DATA}")
    now, before = plain(record_skeleton(skeletons[label])), GOLDEN["skeletons"][label]
    same = set(before) - WIDENED.get(label, set()) - ({"profile"} if label in NEWLY_PROFILED else set())
    assert {k: now[k] for k in same} == {k: before[k] for k in same}
    if label in NEWLY_PROFILED:
        assert before["profile"] is None and now["profile"] == NEWLY_PROFILED[label]


@pytest.mark.parametrize("label", sorted(WIDENED))
def test_renamed_rigs_are_recognised_like_the_original(skeletons, label):
    relative = dict((f"variant:{v[0]}", v[1]) for v in VARIANTS)[label]
    if relative not in skeletons:
        pytest.skip(f"{relative} not found under {SHARED_DATA}")
    original, renamed = skeletons[relative], skeletons[label]
    rename = dict(zip(original.joint_names, renamed.joint_names))
    guessed = {k: rename.get(v) for k, v in plain(record_skeleton(original))["landmarks_guessed"].items()}
    now, before = plain(record_skeleton(renamed)), GOLDEN["skeletons"][label]
    assert now["landmarks_guessed"] == guessed
    assert now["landmarks"] == {"found": guessed, "how": "guessed from joint names"}
    assert "error" not in now["de_leva"] and "error" in before["de_leva"]  # was: shoulders... not found
    if label == "variant:namespace_pipe":
        assert now["profile"] == "daz" and before["profile"] is None
        resolved = profile_joints(rig_profiles()["daz"], original.joint_names)
        assert now["profile_joints"]["daz"] == {k: rename[v] for k, v in resolved.items()}


def test_name_parsing_is_unchanged_where_either_parser_found_a_side():
    now = plain(record_names(GOLDEN["names"]))
    for name, before in GOLDEN["names"].items():
        if "|" in name:  # a group namespace is dropped now by every parser, as ":" was
            plain_name = name.split("|")[-1]
            assert now[name]["parse_side"] == now[plain_name]["parse_side"], name
            assert now[name]["normalise_name"] == GOLDEN["names"][plain_name]["normalise_name"], name
            continue
        roles_side, landmark_side = before["parse_side"], before["side_and_base"]
        expected = (roles_side if roles_side[0] else landmark_side if landmark_side[0]
                    else list(CAPITAL_SIDES.get(name, (None, landmark_side[1]))))
        assert now[name]["parse_side"] == now[name]["side_and_base"] == expected, name
        assert now[name]["normalise_name"] == before["normalise_name"], name


def test_automatic_joint_maps_are_unchanged(skeletons):
    maps = plain(record_maps(skeletons))
    recorded = {k: v for k, v in GOLDEN["maps"].items() if "variant:namespace_pipe" not in k}  # checked below
    expected = {k: v for k, v in recorded.items() if all(s in skeletons for s in k.split(" -> "))}
    assert len(expected) > 0.9 * len(recorded), "most of the corpus is missing"
    profile = {label: detect_profile(skeletons[label].joint_names) for label in skeletons}

    def families(key):  # both rigs recognised, by different profiles: same names no longer come first
        source, target = key.split(" -> ")
        return bool(profile[source] and profile[target] and profile[source] != profile[target])

    kept = {k: v for k, v in expected.items() if not set(NEWLY_PROFILED) & set(k.split(" -> ")) and not families(k)}
    assert {k: maps.get(k) for k in kept} == kept
    for key in set(expected) - set(kept):  # through the profiles where both are recognised
        source, target = key.split(" -> ")
        if profile[source] and profile[target] and (expected[key]["how"] != "same names" or families(key)):
            assert maps[key]["how"] == f"rig profiles {profile[source]} -> {profile[target]}", key
        else:
            assert maps[key] == expected[key], key


def test_group_namespace_maps_like_the_rig_without_it(skeletons):
    if DAZ not in skeletons:
        pytest.skip(f"{DAZ} not found under {SHARED_DATA}")
    daz, grouped = skeletons[DAZ], skeletons["variant:namespace_pipe"]
    rename = dict(zip(daz.joint_names, grouped.joint_names))
    for label, other in skeletons.items():
        if other.joint_names in (daz.joint_names, grouped.joint_names):
            continue
        plain_map, grouped_map = auto_map(other.joint_names, daz.joint_names, daz.end_sites), \
            auto_map(other.joint_names, grouped.joint_names, grouped.end_sites)
        assert grouped_map.how == plain_map.how, label
        assert grouped_map.pairs == {rename[t]: s for t, s in plain_map.pairs.items()}, label
        back, grouped_back = auto_map(daz.joint_names, other.joint_names), auto_map(grouped.joint_names,
                                                                                   other.joint_names)
        assert grouped_back.pairs == {t: rename[s] for t, s in back.pairs.items()}, label


def test_presets_are_tried_in_the_documented_order():
    assert R.PRESET_NAMES == ("cgspeed-mb", "cgspeed-max", "daz", "bandai", "mixamo", "asf", "character-creator",
                              "unreal", "rigify", "biped", "smpl")
    assert A.PRESET_NAMES == ("cgspeed-mb", "cgspeed-max", "daz", "bandai", "character-creator", "unreal", "rigify",
                              "biped", "smpl")
    mixamo = next(p for p in rig_presets("roles") if p.name == "mixamo")
    assert mixamo.points["l_forearm"] == "mixamorig:LeftForeArm" and "mixamorig:Spine1" in mixamo.signature
    daz = next(p for p in rig_presets("landmarks") if p.name == "daz")
    assert daz.points["head_top"] == "leftEye_End" and daz.points["neck_base"] == "neck"


def test_asf_profile_is_detected_and_maps_the_karate_rig(shared_file, tmp_path):
    """AnimatedDrawings' karate BVH (CMU ASF bone names) is recognised as ``asf``: automatic maps
    to a recognised rig go through the profiles (19 joints; by normalised names 5 matched, and a
    karate → Rokoko retarget lay ~1 m from its source). A map file naming the profiles agrees."""
    from usdmotion.io import read_motion

    karate = read_motion(shared_file("other_rigs/ad_karate_mawashigeri.bvh"))
    resolved = profile_joints(rig_profiles()["asf"], karate.joint_names)
    assert resolved["l_forearm"] == "lradius" and resolved["spine"] == "thorax" and "chest" not in resolved
    assert detect_profile(karate.joint_names) == "asf"
    cmu = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    automatic = auto_map(cmu.joint_names, karate.joint_names, karate.end_sites)
    assert automatic.how == "rig profiles cmu_cgspeed -> asf"
    assert sum(v is not None for v in automatic.pairs.values()) >= 17
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"source_profile": "cmu_cgspeed", "target_profile": "asf"}))
    src, _, jmap = resolve_map(load_joint_map(path), cmu.joint_names, karate.joint_names)
    assert cmu.joint_names[src[karate.joint_index("ltibia")]] == "LeftLeg"
    assert cmu.joint_names[src[karate.joint_index("rhumerus")]] == "RightArm"
    assert {t: s for t, s in automatic.pairs.items() if s} == {t: s for t, s in jmap.pairs.items() if s}


@pytest.mark.parametrize("rig", ["other_rigs/ad_karate_mawashigeri.bvh", "other_rigs/ad_cartwheel_clean.bvh"])
def test_asf_rigs_spine_joints_map_to_the_cmu_joints_at_their_height(shared_file, rig):
    """Each spine joint of an ``asf`` rig is paired with the CMU joint at its height: the
    karate rig's one spine joint, ``thorax``, sits a third of the way from the hips to the
    shoulders and was paired with cgspeed's chest (``Spine1``, at 0.82 of the way); a CMU walk
    onto it ended at per-joint RMS 2.46 units, ``thorax`` 5.75 (now 1.98 and 2.47). Independent
    computation: each rest pose's heights above the hips over its shoulders' (forward kinematics);
    the segmentation roles still turn with ``thorax`` as the chest."""
    from usdmotion.io import read_motion
    from usdmotion.kinematics import rest_positions

    def heights(motion, shoulder):  # rest height above the hips, in shoulder heights
        up = "XYZ".index(motion.up_axis)
        rest = rest_positions(motion)[:, up]
        return {n: (rest[j] - rest[0]) / (rest[motion.joint_index(shoulder)] - rest[0])
                for j, n in enumerate(motion.joint_names)}

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmu, target = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh")), read_motion(shared_file(rig))
    pairs = auto_map(cmu.joint_names, target.joint_names, target.end_sites).pairs
    spine = [n for n in ("thorax", "lowerback", "upperback") if n in target.joint_names]
    cmu_h, target_h = heights(cmu, "LeftArm"), heights(target, "lhumerus")
    for name in spine:
        assert abs(target_h[name] - cmu_h[pairs[name]]) < 0.2, (name, pairs[name], target_h[name], cmu_h[pairs[name]])
    assert R.match_preset(target) == ("asf" if "thorax" in target.joint_names else None)


def test_cmu_asf_amc_skeletons_map_onto_their_cgspeed_conversion_joint_for_joint(shared_file):
    """A CMU ASF/AMC take (subject 86) is recognised as ``cmu_asf`` and its automatic map onto
    cgspeed's BVH conversion of the same take pairs joints that stand at the same place on every
    frame. Independent check: forward kinematics of both files (by normalised names 13 joints
    matched; now every body point of both profiles)."""
    from usdmotion.io import read_motion
    from usdmotion.kinematics import joint_positions

    amc = read_motion(shared_file("cmu86/86_01.amc"))
    bvh = read_motion(shared_file("cmu86/86_01_from_amc_cgspeed_layout.bvh"), units="asf")
    assert detect_profile(amc.joint_names) == "cmu_asf"
    jmap = auto_map(amc.joint_names, bvh.joint_names, bvh.end_sites)
    assert jmap.how == "rig profiles cmu_asf -> cmu_cgspeed"
    pairs = {t: s for t, s in jmap.pairs.items() if s}
    assert len(pairs) >= 21
    a, b = joint_positions(amc), joint_positions(bvh)
    for target, source in pairs.items():
        gap = np.linalg.norm(a[:, amc.joint_index(source)] - b[:, bvh.joint_index(target)], axis=-1).max()
        assert gap < 1e-3, (target, source, gap)


@pytest.mark.parametrize("name, side_base, key", [
    ("grp|LeftForeArm", ("left", "forearm"), "lforearm"), ("rig:Knee.R", ("right", "knee"), "rknee"),
    ("lhandIK", ("left", "handik"), "lhandik"), ("Rtibia", ("right", "tibia"), "rtibia"),
    ("L_Hand", ("left", "hand"), "lhand"), ("lowerback", (None, "lowerback"), "lowerback"),
])
def test_one_side_parser_for_roles_landmarks_and_maps(name, side_base, key):
    assert parse_side(name) == R.parse_side(name) == A.side_and_base(name) == side_base
    assert normalise_name(name) == key


def test_signature_joints_gate_the_role_preset_only(shared_file):
    """A look-alike rig (one signature joint renamed) is guessed for roles; landmark presets
    need only their own joints (both as before the presets became data)."""
    import dataclasses

    from usdmotion.io import read_motion

    walk = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    assert R.match_preset(walk) == "cgspeed-mb" and A.find_landmarks(walk)[1] == "preset cgspeed-mb"
    lookalike = dataclasses.replace(walk, joint_names=tuple("RHipJoint2" if n == "RHipJoint" else n
                                                            for n in walk.joint_names))
    assert R.match_preset(lookalike) is None
    assert A.find_landmarks(lookalike)[1] == "preset cgspeed-mb"

"""UsdSkel joint path tokens are DCC-safe: valid identifiers, last elements unique in the
whole skeleton (Blender names bones, and binds skin weights, by the last element), and the
original names survive a USD round trip. Blender itself is checked in test_blender.py."""

from __future__ import annotations

import numpy as np

from usdmotion.io.usd import joint_path_tokens, read_usd, validate_stage, write_usd
from usdmotion.motion import Motion

NAMES = ("rig:Hips", "Left Leg", "1st Knee", "a:b", "a:b_End", "rig:Spine", "a_b", "a_b_End", "rig_Spine",
         "rig_Spine_2", "a_b_2")
PARENTS = np.array([-1, 0, 1, 2, 3, 0, 5, 6, 0, 0, 5])


def test_tokens_are_valid_unique_and_follow_the_hierarchy():
    from pxr import Sdf

    tokens = joint_path_tokens(NAMES, PARENTS)
    leaves = [t.rsplit("/", 1)[-1] for t in tokens]
    assert len(set(leaves)) == len(leaves), leaves
    assert all(Sdf.Path.IsValidIdentifier(leaf) for leaf in leaves), leaves
    for j, token in enumerate(tokens):
        parent = tokens[PARENTS[j]] + "/" if PARENTS[j] >= 0 else ""
        assert token == parent + leaves[j]
    assert leaves[NAMES.index("Left Leg")] == "Left_Leg"
    assert leaves[NAMES.index("1st Knee")] == "_1st_Knee"
    # First come, first served (parents before children): 'a:b' (under '1st Knee') and
    # 'a_b' (under 'rig:Spine') collide only after sanitising, under different parents;
    # a suffix never reuses a name taken earlier, whether sanitised or real.
    assert [leaves[NAMES.index(n)] for n in ("a:b", "a_b", "a_b_2")] == ["a_b", "a_b_2", "a_b_2_2"]
    assert [leaves[NAMES.index(n)] for n in ("rig:Spine", "rig_Spine", "rig_Spine_2")] == [
        "rig_Spine", "rig_Spine_2", "rig_Spine_2_2"]

def test_original_names_survive_a_round_trip(tmp_path):
    n_frames = 3
    rotations = np.zeros((n_frames, len(NAMES), 4))
    rotations[..., 0] = 1.0
    offsets = np.tile([0.0, 10.0, 0.0], (len(NAMES), 1))
    motion = Motion(joint_names=NAMES, parents=PARENTS, offsets=offsets, rotations=rotations,
                    root_translation=np.zeros((n_frames, 3)), fps=30.0)
    path = write_usd(motion, tmp_path / "names.usda")
    assert validate_stage(str(path)) == []
    assert read_usd(path).joint_names == NAMES

"""ASF/AMC reader: exact against the shared cgspeed-layout BVH of CMU 86_01, frame numbering,
skeleton lookup, and one-line errors (file:line) for a corpus of malformed ASF/AMC files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.errors import InputError
from usdmotion.io import read_motion
from usdmotion.io.amc import AmcParseError, read_amc
from usdmotion.io.asf import AsfParseError, read_asf
from usdmotion.io.bvh import read_bvh
from usdmotion.io.bvh_write import channel_values
from usdmotion.kinematics import joint_positions, skeleton_height
from usdmotion.rotations import euler_to_quat, quat_mul, quat_rotate

CGSPEED_NAMES = {  # ASF bone → cgspeed BVH joint, as in the shared derived file
    "root": "Hips", "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase", "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg",
    "rfoot": "RightFoot", "rtoes": "RightToeBase", "lowerback": "LowerBack", "upperback": "Spine",
    "thorax": "Spine1", "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head", "lclavicle": "LeftShoulder",
    "lhumerus": "LeftArm", "lradius": "LeftForeArm", "lwrist": "LeftHand", "lhand": "LeftFingerBase",
    "lfingers": "LeftHandIndex1", "lthumb": "LThumb", "rclavicle": "RightShoulder", "rhumerus": "RightArm",
    "rradius": "RightForeArm", "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}


@pytest.fixture(scope="module")
def take_86_01():
    from conftest import shared_path

    asf = shared_path("cmu86/86.asf")
    amc = shared_path("cmu86/86_01.amc")
    bvh = shared_path("cmu86/86_01_from_amc_cgspeed_layout.bvh")
    return read_motion(amc, skeleton=asf), read_bvh(bvh, units="asf")


def _bvh_index(ours, theirs):
    names = {f"{k}_End": f"{v}_End" for k, v in CGSPEED_NAMES.items()} | CGSPEED_NAMES
    return [theirs.joint_names.index(names[n]) for n in ours.joint_names]


def test_86_01_equals_the_derived_cgspeed_bvh(take_86_01):
    ours, theirs = take_86_01
    assert ours.n_frames == theirs.n_frames == 4579  # AMC frames 1..4579 → 0..4578, no T-pose frame
    order = _bvh_index(ours, theirs)
    assert order == list(range(theirs.n_joints))  # same joints, same depth-first order
    assert np.array_equal(ours.parents, theirs.parents)
    # The file is written with 4 decimals (channels) and 5 (offsets): every channel we compute,
    # expressed in its layout (Euler triple nearest the file's), is within half a unit of the
    # 4th decimal of the file's value.
    ours_in_layout = dataclasses.replace(ours, source_channels=theirs.source_channels)
    assert ours.channels == theirs.channels
    mine = channel_values(ours_in_layout, theirs.channels)
    assert np.abs(mine - theirs.source_channels).max() <= 0.5e-4 + 1e-9
    assert np.abs(ours.offsets - theirs.offsets).max() <= 0.5e-5 + 1e-9
    # World positions at every frame agree to the file's own precision: its 4-decimal root
    # position alone is off by up to √3·0.5e-4 = 8.7e-5 units = 3.3e-6 × height.
    height = skeleton_height(theirs)
    mine_xyz, theirs_xyz = joint_positions(ours), joint_positions(theirs)
    error = np.linalg.norm(mine_xyz - theirs_xyz, axis=-1)
    assert error.max() <= 4e-6 * height
    # Where that error comes from (issue 18 asks for 1e-6 × height, which this reference cannot
    # express): the root alone is within the rounding bound of its 4-decimal position, and
    # every joint relative to the root within 2e-6 × height (4-decimal angles, 0.5e-4° each,
    # summed along chains of up to 8 bones); measured 2.7e-6 and 1.7e-6 × height.
    root_error = np.linalg.norm(mine_xyz[:, 0] - theirs_xyz[:, 0], axis=-1)
    assert root_error.max() <= np.sqrt(3) * 0.5e-4 + 1e-9
    relative = (mine_xyz - mine_xyz[:, :1]) - (theirs_xyz - theirs_xyz[:, :1])
    assert np.linalg.norm(relative, axis=-1).max() <= 2e-6 * height
    assert ours.fps == pytest.approx(120.0) and ours.meters_per_unit == pytest.approx(0.0254 / 0.45)


def test_first_frame_is_amc_frame_1_by_independent_acclaim_fk():
    """Acclaim forward kinematics written out per bone from the ASF text (world matrices
    ``C M C⁻¹`` chained, bone ends = start + R·direction·length) for AMC frame 1."""
    from conftest import shared_path

    asf, amc = shared_path("cmu86/86.asf"), shared_path("cmu86/86_01.amc")
    ours = read_amc(amc, asf, layout="acclaim")
    skel = read_asf(asf)
    frame1 = {}
    lines = amc.read_text().splitlines()
    start = lines.index("1") + 1
    for line in lines[start:]:
        if line.strip() == "2":
            break
        name, *vals = line.split()
        frame1[name] = [float(v) for v in vals]
    world_rot, end = {}, {}
    for b, name in enumerate(skel.names):
        angles = np.zeros(3)
        for dof, v in zip(skel.dofs[b], frame1.get(name, [])):
            if dof.startswith("r"):
                angles["xyz".index(dof[1])] = np.deg2rad(v)
        ax = skel.axes[b]
        c = euler_to_quat(np.array([ax[2], ax[1], ax[0]]), "ZYX")
        m = euler_to_quat(np.array([angles[2], angles[1], angles[0]]), "ZYX")
        local = quat_mul(quat_mul(c, m), c * np.array([1, -1, -1, -1]))
        if b == 0:
            world_rot[name] = local
            end[name] = skel.root_position + np.array(frame1["root"][:3])
            start_of = {name: end[name]}
            continue
        parent = skel.names[skel.parents[b]]
        world_rot[name] = quat_mul(world_rot[parent], local)
        start_of[name] = end[parent]
        end[name] = end[parent] + quat_rotate(world_rot[name], skel.directions[b] * skel.lengths[b])
    positions = joint_positions(ours)[0]
    for j, name in enumerate(ours.joint_names):
        expected = end[name[:-4]] if name.endswith("_End") else start_of[name]
        assert np.allclose(positions[j], expected, atol=1e-9), name


def test_skeleton_beside_the_amc_is_found(tmp_path):
    from conftest import shared_path

    asf, amc = shared_path("cmu86/86.asf"), shared_path("cmu86/86_01.amc")
    (tmp_path / "86.asf").write_bytes(asf.read_bytes())
    lines = amc.read_text().splitlines(keepends=True)
    cut = lines.index("4\n")
    (tmp_path / "86_01.amc").write_text("".join(lines[:cut]))
    motion = read_motion(tmp_path / "86_01.amc")
    assert motion.n_frames == 3
    reference = read_motion(amc, skeleton=asf)
    assert np.allclose(motion.rotations, reference.rotations[:3])
    (tmp_path / "86.asf").unlink()
    with pytest.raises(AmcParseError, match="no skeleton: pass --skeleton"):
        read_motion(tmp_path / "86_01.amc")


# ---------------------------------------------------------------- malformed corpus

ASF = """\
# a three-bone skeleton
:version 1.10
:name VICON
:units
  mass 1.0
  length 0.45
  angle deg
:documentation
   made for the tests
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name lfemur
     direction 0 -1 0
     length 7.5
     axis 0 0 20  XYZ
    dof rx ry rz
    limits (-160.0 20.0)
           (-70.0 70.0)
           (-60.0 70.0)
  end
  begin
     id 2
     name ltibia
     direction 0 -1 0
     length 7.0
     axis 0 0 20 XYZ
    dof rx
  end
:hierarchy
  begin
    root lfemur
    lfemur ltibia
  end
"""

AMC = """\
#!OML:ASF test.asf
:FULLY-SPECIFIED
:DEGREES
1
root 1 18 2 10 20 30
lfemur -20 5 3
ltibia 40
2
root 1.1 18 2 11 21 31
lfemur -21 5 3
ltibia 41
"""


def _edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# name: (asf text, amc text, error class, line, message fragment)
MALFORMED = {
    "asf_unknown_section": (_edit(ASF, ":documentation", ":docs"), AMC, AsfParseError, 8, "unknown section"),
    "asf_no_hierarchy": (ASF.split(":hierarchy")[0], AMC, AsfParseError, 34, "no :hierarchy section"),
    "asf_direction_two_values": (_edit(ASF, "direction 0 -1 0\n     length 7.5", "direction 0 -1\n     length 7.5"),
                                 AMC, AsfParseError, 19, "direction has 2 values, expected 3"),
    "asf_length_not_number": (_edit(ASF, "length 7.0", "length seven"), AMC, AsfParseError, 31,
                              "'seven' is not a number"),
    "asf_bone_without_length": (_edit(ASF, "     length 7.0\n", ""), AMC, AsfParseError, 27, "bone has no 'length'"),
    "asf_missing_end": (_edit(ASF, "    dof rx\n  end\n", "    dof rx\n"), AMC, AsfParseError, 27, "no 'end'"),
    "asf_translation_dof": (_edit(ASF, "dof rx\n", "dof rx tx\n"), AMC, AsfParseError, 33, "dof 'tx' is not supported"),
    "asf_bad_axis_order": (_edit(ASF, "axis 0 0 20 XYZ", "axis 0 0 20 XYY"), AMC, AsfParseError, 32,
                           "not a permutation of XYZ"),
    "asf_hierarchy_unknown_bone": (_edit(ASF, "lfemur ltibia\n  end", "lfemur ltibia lfoot\n  end"), AMC,
                                   AsfParseError, 38, "'lfoot', which :bonedata does not define"),
    "asf_bone_not_in_hierarchy": (_edit(ASF, "    lfemur ltibia\n", ""), AMC, AsfParseError, 27,
                                  "'ltibia' is not reachable from root"),
    "asf_two_parents": (_edit(ASF, "root lfemur\n", "root lfemur ltibia\n"), AMC, AsfParseError, 38,
                        "'ltibia' has two parents"),
    "amc_unknown_bone": (ASF, _edit(AMC, "ltibia 40", "lknee 40"), AmcParseError, 7,
                         "bone 'lknee' is not in the skeleton"),
    "amc_too_few_values": (ASF, _edit(AMC, "lfemur -21 5 3", "lfemur -21 5"), AmcParseError, 10,
                           "lfemur has 2 values, its DOFs are rx ry rz"),
    "amc_not_a_number": (ASF, _edit(AMC, "ltibia 41", "ltibia 4l"), AmcParseError, 11, "'4l' is not a number"),
    "amc_nan": (ASF, _edit(AMC, "ltibia 41", "ltibia nan"), AmcParseError, 11, "not finite"),
    "amc_frame_skipped": (ASF, _edit(AMC, "\n2\n", "\n3\n"), AmcParseError, 8, "frame 3 follows frame 1"),
    "amc_bone_missing": (ASF, _edit(AMC, "lfemur -20 5 3\n", ""), AmcParseError, 4, "frame 1 has no values for lfemur"),
    "amc_bone_twice": (ASF, _edit(AMC, "ltibia 40\n", "ltibia 40\nltibia 40\n"), AmcParseError, 8,
                       "ltibia appears twice in frame 1"),
    "amc_values_before_frame": (ASF, _edit(AMC, ":DEGREES\n1\n", ":DEGREES\n"), AmcParseError, 4,
                                "'root' before the first frame number"),
    "amc_no_frames": (ASF, ":FULLY-SPECIFIED\n:DEGREES\n", AmcParseError, 2, "no frames"),
    "amc_empty": (ASF, "", AmcParseError, 1, "empty AMC file"),
    "amc_header_after_frames": (ASF, AMC + ":RADIANS\n", AmcParseError, 12, "header line ':RADIANS' after"),
}


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_malformed_gives_typed_error_with_line(name, tmp_path):
    asf_text, amc_text, error_class, line, message = MALFORMED[name]
    asf, amc = tmp_path / "t.asf", tmp_path / "t_01.amc"
    asf.write_text(asf_text)
    amc.write_text(amc_text)
    with pytest.raises(error_class) as info:
        read_motion(amc, skeleton=asf)
    error = info.value
    assert isinstance(error, InputError)
    expected_path = asf if error_class is AsfParseError else amc
    assert (error.path, error.line) == (str(expected_path), line), str(error)
    assert message in error.message
    assert "\n" not in str(error)


@pytest.mark.parametrize("name", ["asf_two_parents", "amc_too_few_values", "amc_frame_skipped"])
def test_cli_one_line_exit_2_no_output(name, tmp_path, capsys):
    asf_text, amc_text, error_class, line, _ = MALFORMED[name]
    (tmp_path / "t.asf").write_text(asf_text)  # found beside the AMC: same name
    (tmp_path / "t.amc").write_text(amc_text)
    out = tmp_path / "out.bvh"
    code = main(["convert", str(tmp_path / "t.amc"), str(out)])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("usdmotion: error: ")
    assert f"t.{'asf' if error_class is AsfParseError else 'amc'}:{line}:" in lines[0]
    assert "Traceback" not in captured.err + captured.out
    assert not out.exists()


def test_valid_minimal_pair_reads(tmp_path):
    (tmp_path / "t.asf").write_text(ASF)
    (tmp_path / "t.amc").write_text(AMC)
    motion = read_motion(tmp_path / "t.amc")
    assert motion.joint_names == ("root", "lfemur", "ltibia", "ltibia_End")
    assert motion.n_frames == 2
    # root at the AMC translation; the knee 7.5 below the hip at rest, rotated by the frame's root and femur
    assert np.allclose(motion.root_translation[1], [1.1, 18, 2])
    positions = joint_positions(motion)
    assert np.allclose(np.linalg.norm(positions[:, 2] - positions[:, 1], axis=-1), 7.5)
    assert np.allclose(np.linalg.norm(positions[:, 3] - positions[:, 2], axis=-1), 7.0)


def test_cli_convert_amc_with_skeleton_option(shared_file, tmp_path, capsys):
    """``usdmotion convert 13_29.amc 13_29.bvh --skeleton 86.asf`` (subject 86's skeleton as a proxy):
    the BVH re-reads to the same world positions as the library's AMC reading."""
    amc, asf = shared_file("mocap6/13_29.amc"), shared_file("cmu86/86.asf")
    out = tmp_path / "13_29.bvh"
    assert main(["convert", str(amc), str(out), "--skeleton", str(asf)]) == 0, capsys.readouterr().err
    assert "4592 frames at 120 fps" in capsys.readouterr().out
    ours = read_motion(amc, skeleton=asf)
    back = read_bvh(out, units="asf")
    assert back.n_frames == ours.n_frames == 4592 and back.joint_names == ours.joint_names
    error = np.linalg.norm(joint_positions(back) - joint_positions(ours), axis=-1)
    assert error.max() <= 1e-6 * skeleton_height(ours)
    # Without the option and without an .asf beside it: one line, exit 2, nothing written.
    out.unlink()
    assert main(["convert", str(amc), str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no skeleton: pass --skeleton FILE.asf" in err[0] and not out.exists()

"""``usdmotion retarget``: round trips through BVH and UsdSkel (positions evaluated by
usd-core), the JSON report, and bad input (one line, exit 2, nothing written)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from conftest import without_warnings

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.io.bvh import read_bvh
from usdmotion.io.bvh_write import write_bvh
from usdmotion.kinematics import joint_positions

WALK = "cmu/cgspeed_12_01_walk.bvh"
DAZ = "cmu/daz_10_01_soccer_kick.bvh"
#: the paper experiment's list (as in test_retarget.py: the same compiled solver is reused)
REMOVE = ("LHipJoint,RHipJoint,LowerBack,Spine1,Neck,LeftShoulder,RightShoulder,LeftFingerBase,RightFingerBase,"
          "LeftHandIndex1,RightHandIndex1,LThumb,RThumb")


@pytest.fixture(autouse=True)
def _no_persistent_cache(monkeypatch):
    monkeypatch.setenv("USDMOTION_JAX_CACHE", "off")


@pytest.fixture
def walk16(shared_file, tmp_path):
    """The first 16 motion frames of the CMU walk, as a small BVH."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = read_motion(shared_file(WALK))
    m = m.with_frames(m.rotations[1:17], m.root_translation[1:17])
    return write_bvh(m, tmp_path / "walk16.bvh")


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def usd_world_positions(path) -> tuple[list[str], np.ndarray]:
    """World joint positions ``(F, J, 3)`` of a UsdSkel stage, evaluated by usd-core."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    skel = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    query = UsdSkel.Cache().GetSkelQuery(skel)
    frames = []
    for t in range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1):
        world = query.ComputeJointWorldTransforms(UsdGeom.XformCache(t))
        frames.append([np.array(m.ExtractTranslation()) for m in world])
    return list(skel.GetJointNamesAttr().Get()), np.array(frames)


def test_derived_rig_to_bvh_round_trip_and_report(capsys, tmp_path, walk16):
    out, report = tmp_path / "walk18.bvh", tmp_path / "report.json"
    code, stdout, err = run(capsys, "retarget", walk16, out, "--remove", REMOVE, "--report", report)
    assert code == 0, err
    assert stdout.startswith(f"wrote {out}: ") and stdout.count("\n") == 1
    rep = json.loads(report.read_text())
    assert rep["removed"][:2] == ["LHipJoint", "RHipJoint"] and "LThumb_End" in rep["removed"]
    back = read_bvh(out)
    source = read_bvh(walk16)
    assert back.channels[back.joint_index("LeftUpLeg")] == ("Zrotation", "Yrotation", "Xrotation")
    assert back.parents[back.joint_index("Neck1")] == back.joint_index("Spine")
    # the loss of the file as written, from our FK of the re-read file
    p_back, p_src = joint_positions(back), joint_positions(source)
    idx = [source.joint_index(n) for n in back.joint_names]
    per_frame = np.sum((p_back - p_src[:, idx]) ** 2, axis=(1, 2))
    assert per_frame.sum() == pytest.approx(rep["loss"]["final"]["total"], rel=1e-6, abs=1e-9)
    assert rep["loss"]["final"]["per_frame_max"] == pytest.approx(per_frame.max(), rel=1e-6, abs=1e-9)
    assert rep["loss"]["final_over_copied"] < 0.01
    assert rep["loss"]["final"]["total"] < rep["loss"]["initial"]["total"]
    for name in ("Neck1", "LeftArm"):
        k = back.joint_index(name)
        rms = np.sqrt(np.mean(np.sum((p_back[:, k] - p_src[:, source.joint_index(name)]) ** 2, -1)))
        assert rep["per_joint_rms"][name] == pytest.approx(rms, rel=1e-5, abs=1e-9)
    neck1 = back.offsets[back.joint_index("Neck1")]
    assert rep["bone_lengths"]["Neck1"]["after"] == pytest.approx(np.linalg.norm(neck1))
    assert rep["method"] == "lm" and rep["dtype"] == "float32" and rep["time_s"]["total"] > 0


def test_cross_rig_to_usd_positions_evaluated_by_usd_core(capsys, tmp_path, walk16, shared_file):
    out, report = tmp_path / "daz.usda", tmp_path / "daz.json"
    code, stdout, err = run(capsys, "retarget", walk16, out, "--target", shared_file(DAZ), "--units", "asf",
                            "--report", report)
    assert code == 0, err
    rep = json.loads(report.read_text())
    names, world = usd_world_positions(out)
    assert names == list(read_bvh(shared_file(DAZ)).joint_names)
    source = read_bvh(walk16, units="asf")
    p_src = joint_positions(source) * rep["units"]["source_scale"]
    assert rep["units"]["source_scale"] == pytest.approx(0.0254 / 0.45 / 0.01)
    for target_name, source_name in rep["map"]["pairs"].items():
        err_ = world[:, names.index(target_name)] - p_src[:, source.joint_index(source_name)]
        rms = np.sqrt(np.mean(np.sum(err_**2, -1)))
        assert rms == pytest.approx(rep["per_joint_rms"][target_name], rel=1e-4, abs=1e-4)  # float32 in USD
    # contacts are on by default with --target: the feet, the flips and the comparison are reported
    assert "feet: skate" in stdout and set(rep["compare"]) == {"rotation_copy", "plain", "result"}
    assert rep["contacts"]["joints"] and rep["quality"]["feet"]["contact_frames"] > 0
    assert rep["compare"]["result"]["rms_cm"] == pytest.approx(rep["quality"]["rms_cm"])
    # the same contacts from a file (usdmotion contacts --json) give the same result
    contacts = tmp_path / "contacts.json"
    assert run(capsys, "contacts", walk16, "--units", "asf", "--json", contacts)[0] == 0
    again = tmp_path / "again.json"
    code, _, err = run(capsys, "retarget", walk16, tmp_path / "again.usda", "--target", shared_file(DAZ), "--units",
                       "asf", "--contacts", contacts, "--no-compare", "--report", again)
    assert code == 0, err
    assert json.loads(again.read_text())["per_joint_rms"] == pytest.approx(rep["per_joint_rms"], rel=1e-9)
    # and the BVH written from the same run's motion agrees with usd-core
    bvh = tmp_path / "daz.bvh"
    assert run(capsys, "retarget", walk16, bvh, "--target", shared_file(DAZ), "--units", "asf")[0] == 0
    back = read_bvh(bvh)
    assert back.channels == read_bvh(shared_file(DAZ)).channels  # the target's channel layout and orders
    np.testing.assert_allclose(joint_positions(back), world, atol=1e-4 * np.ptp(world[0], axis=0).max())


def test_adam_reference_method_from_the_cli(capsys, tmp_path, walk16):
    report = tmp_path / "adam.json"
    code, _, err = run(capsys, "retarget", walk16, tmp_path / "a.bvh", "--remove", REMOVE, "--method", "adam",
                       "--report", report)
    assert code == 0, err
    rep = json.loads(report.read_text())
    assert rep["method"] == "adam" and rep["iterations"] == 500 and rep["init"] == "copy"
    assert rep["loss"]["final"]["total"] < 0.5 * rep["loss"]["copied"]["total"]


# ----------------------------------------------------------------------- bad input


def write_map(tmp_path, doc, name="map.json"):
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


@pytest.mark.parametrize("args, message", [
    (["--map", "MAP:{\"joints\": {\"Hipz\": \"Hips\"}}", "--remove", "LThumb"],
     "map.json: joints: no target joint named 'Hipz' (did you mean Hips?)"),
    (["--map", "MAP:{\"joints\": {\"Hips\": \"Hip\"}}", "--remove", "LThumb"], "no source joint named 'Hip'"),
    (["--map", "MAP:{\"joints\": {\"Hips\": {\"source\": \"Hips\", \"weight\": -1}}}", "--remove", "LThumb"],
     "invalid joint map at joints/Hips"),
    (["--map", "MAP:{\"joints\": {\"Hips\": \"Hips\",}}", "--remove", "LThumb"], "map.json:1:"),
    (["--map", "MAP:{\"source_profile\": \"cmu_cgspeed\", \"target_profile\": \"nope\"}", "--remove", "LThumb"],
     "unknown rig profile 'nope'"),
    (["--remove", "Hips"], "cannot remove the root joint 'Hips'"),
    (["--remove", "LeftKnee"], "walk16.bvh: no joint named 'LeftKnee' (did you mean LeftLeg"),
    (["--add", "Prop:RightHand"], "expected NAME:PARENT:X,Y,Z"),
    (["--add", "Prop:RightPalm:0,1,0"], "no parent joint named 'RightPalm'"),
    (["--add", "Head:Neck1:0,1,0"], "already has a joint named 'Head'"),
    (["--add", "Tip:Head_End:0,1,0"], "is an End Site"),
    ([], "give --target, or joints to --remove / --add"),
    (["--remove", "LThumb", "--scale", "-2"], "--scale must be a positive number"),
    (["--remove", "LThumb", "--scale", "big"], "--scale must be 'units', 'auto' or a positive number"),
    (["--target", "DAZ", "--units", "cm"], "units look mismatched"),  # a CMU take said to be cm
    # a factor that leaves the source far out of the target's reach (exit 0, RMS 1e29 and numpy's
    # overflow warnings, before): the same 2x bound as the units' check, around --scale auto's factor
    (["--target", "DAZ", "--units", "asf", "--scale", "1e30"], "--scale 1e+30 makes the source 1"),
    (["--target", "DAZ", "--units", "asf", "--scale", "0.5"], "--scale 0.5 makes the source 0."),
    (["--target", "DAZ", "--units", "asf", "--directions", "mean"], "--directions mean needs a target derived"),
    (["--target", "DAZ", "--units", "asf", "--map", "MAP:{\"joints\": {\"hip\": null}}"], "could be matched"),
    (["--target", "CYCLE"], "cyc.usda"),
    (["--target", "DAZ", "--units", "asf", "--contacts", "NOFILE"], "nope.json"),
    (["--target", "DAZ", "--units", "asf", "--contacts", "auto", "--method", "adam"], "needs --method lm"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(capsys, tmp_path, walk16, shared_file, args, message):
    expanded = []
    for a in args:
        if a.startswith("MAP:"):
            a = str(write_map(tmp_path, a[4:]))
        elif a == "DAZ":
            a = str(shared_file(DAZ))
        elif a == "CYCLE":
            a = str(cyclic_usd(tmp_path))
        elif a == "NOFILE":
            a = str(tmp_path / "nope.json")
        expanded.append(a)
    out = tmp_path / "out.bvh"
    code, stdout, err = run(capsys, "retarget", walk16, out, *expanded, "--report", tmp_path / "r.json")
    assert code == 2
    errors = without_warnings(err)
    assert len(errors) == 1 and errors[0].startswith("usdmotion: error: ") and "Traceback" not in err
    assert message in err
    assert not out.exists() and not (tmp_path / "r.json").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".out")] == []  # no temp leftovers


def cyclic_usd(tmp_path):
    """A UsdSkel target whose joint list names a child before its parent (invalid topology)."""
    path = tmp_path / "cyc.usda"
    path.write_text('#usda 1.0\n(\n    defaultPrim = "Root"\n)\n\ndef SkelRoot "Root"\n{\n'
                    '    def Skeleton "Skel"\n    {\n        uniform token[] joints = ["A/B", "A"]\n'
                    '        uniform matrix4d[] restTransforms = [( (1,0,0,0), (0,1,0,0), (0,0,1,0), (0,1,0,1) ),'
                    ' ( (1,0,0,0), (0,1,0,0), (0,0,1,0), (0,0,0,1) )]\n'
                    '        uniform matrix4d[] bindTransforms = [( (1,0,0,0), (0,1,0,0), (0,0,1,0), (0,1,0,1) ),'
                    ' ( (1,0,0,0), (0,1,0,0), (0,0,1,0), (0,0,0,1) )]\n    }\n}\n')
    return path


@pytest.mark.parametrize("output, message", [("out.txt", "unknown output format '.txt'"),
                                             ("missing/out.bvh", "does not exist")])
def test_bad_output_paths(capsys, tmp_path, walk16, output, message):
    code, _, err = run(capsys, "retarget", walk16, tmp_path / output, "--remove", "LThumb")
    assert code == 2 and message in err and len(without_warnings(err)) == 1


def test_output_must_not_overwrite_the_input(capsys, walk16):
    before = walk16.read_bytes()
    code, _, err = run(capsys, "retarget", walk16, walk16, "--remove", "LThumb")
    assert code == 2 and "would overwrite an input" in err
    assert walk16.read_bytes() == before


def test_cyclic_rig_is_rejected_by_the_library():
    from usdmotion.ops.retarget.hierarchy import RetargetError, Rig

    with pytest.raises(RetargetError, match="cycle"):
        Rig(("a", "b", "c"), np.array([-1, 2, 1]), np.zeros((3, 3)), np.zeros(3, bool), None, path="t.bvh")

"""UsdSkel export and import, checked with usd-core's own skeleton evaluation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from reference_fk import reference_world_positions, usd_world_positions

from usdmotion.errors import OutputError, UsdReadError
from usdmotion.io import read_motion, write_motion
from usdmotion.io.bvh import motion_from_bvh, parse_bvh
from usdmotion.io.bvh_write import write_bvh
from usdmotion.io.usd import read_usd, validate_stage, write_usd
from usdmotion.kinematics import joint_positions

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt  # noqa: E402

WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"

# Diverse rigs: CMU, DAZ-style, Bandai (positions on every joint, rest along +X), Rokoko fingers,
# Z-up inch with mixed orders, 60 joints mixed orders, 6 channels on every joint, Mixamo ':' names,
# no End Sites Z-up, rotation channels before position channels.
FILES = [
    ("cmu/cgspeed_12_01_walk.bvh", (".usda", ".usdc", ".usdz")),
    ("cmu/daz_10_01_soccer_kick.bvh", (".usdc",)),
    ("bandai1/dataset-1_walk_normal_001.bvh", (".usdc", ".usdz")),
    ("other_rigs/ad_rokoko_jesse_dance.bvh", (".usdc",)),
    ("edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh", (".usda",)),
    ("edge_cases/pybvh_bvh_test3_60joints_mixed_orders.bvh", (".usdc",)),
    ("edge_cases/wspr_milad_blank_line_6ch_125fps.bvh", (".usdc",)),
    ("other_rigs/20tab_test_freebvh_mixamorig.bvh", (".usda",)),
    ("other_rigs/ad_cartwheel_clean.bvh", (".usdz",)),
    ("edge_cases/pybvh_rotation_first_root.bvh", (".usda",)),
]


@pytest.mark.parametrize(("name", "extensions"), FILES, ids=[f[0].split("/")[-1] for f in FILES])
def test_usd_core_world_positions_match_independent_fk(shared_file, tmp_path, name, extensions):
    path = shared_file(name)
    data = parse_bvh(path.read_bytes(), path)
    motion = motion_from_bvh(data)
    expected = reference_world_positions(data.parents, data.offsets, data.channels, data.values, motion.root_offset)
    height = float(np.ptp(expected[0], axis=0).max())
    for ext in extensions:
        out = write_motion(motion, tmp_path / f"motion{ext}")
        evaluated = usd_world_positions(out)
        assert evaluated.shape == expected.shape
        assert np.max(np.abs(evaluated - expected)) <= 1e-4 * height, ext
        assert validate_stage(str(out)) == [], ext


def test_stage_metadata_names_and_layout(shared_file, tmp_path):
    motion = read_motion(shared_file("other_rigs/20tab_test_freebvh_mixamorig.bvh"), units="in", up_axis="Z")
    out = write_usd(motion, tmp_path / "3walk.usda")
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.0254)
    assert stage.GetTimeCodesPerSecond() == pytest.approx(30.0)
    assert stage.GetFramesPerSecond() == pytest.approx(30.0)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, motion.n_frames - 1)
    root = stage.GetDefaultPrim()
    assert root.IsA(UsdSkel.Root) and Sdf.Path.IsValidIdentifier(root.GetName())
    skeleton = UsdSkel.Skeleton(root.GetChild("Skeleton"))
    joints = [str(t) for t in skeleton.GetJointsAttr().Get()]
    assert len(joints) == len(set(joints)) == motion.n_joints
    assert all(Sdf.Path.IsValidIdentifier(part) for token in joints for part in token.split("/"))
    assert joints[0] == "mixamorig_Hips"
    assert list(skeleton.GetJointNamesAttr().Get()) == list(motion.joint_names)
    binding = UsdSkel.BindingAPI(skeleton.GetPrim())
    animation = UsdSkel.Animation(stage.GetPrimAtPath(binding.GetAnimationSourceRel().GetTargets()[0]))
    assert len(animation.GetRotationsAttr().GetTimeSamples()) == motion.n_frames
    # bindTransforms are the world rest pose: translations = accumulated OFFSETs
    bind = np.array(skeleton.GetBindTransformsAttr().Get())[:, 3, :3]
    from usdmotion.kinematics import rest_positions

    assert np.allclose(bind, rest_positions(motion), atol=1e-9)


def _authored_by_schema_classes(ours, path) -> None:
    """``ours`` (a written stage) authored again into ``path`` with usd-core's schema classes
    (UsdSkel.Root/Skeleton/Animation/BindingAPI, UsdGeom's stage metadata, Boundable and
    ModelAPI), in write_usd's order, taking every value from ``ours``: the reference for
    write_usd's authoring straight into an Sdf.Layer (usdmotion/io/usd_schema.py), which must
    write the same layer without importing Usd, UsdSkel or UsdGeom."""
    source = Usd.Stage.Open(str(ours))
    root_in = source.GetDefaultPrim()
    skel_in, anim_in = UsdSkel.Skeleton(root_in.GetChild("Skeleton")), UsdSkel.Animation(root_in.GetChild("Animation"))
    stage = Usd.Stage.CreateNew(str(path))
    root = UsdSkel.Root.Define(stage, root_in.GetPath())
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.SetStageUpAxis(stage, UsdGeom.GetStageUpAxis(source))
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(source))
    for name in ("TimeCodesPerSecond", "FramesPerSecond", "StartTimeCode", "EndTimeCode"):
        getattr(stage, f"Set{name}")(getattr(source, f"Get{name}")())
    skel = UsdSkel.Skeleton.Define(stage, skel_in.GetPath())
    for name in ("Joints", "JointNames", "RestTransforms", "BindTransforms"):
        getattr(skel, f"Create{name}Attr")(getattr(skel_in, f"Get{name}Attr")().Get())
    skel.GetPrim().SetCustomDataByKey("usdmotion", skel_in.GetPrim().GetCustomDataByKey("usdmotion"))
    anim = UsdSkel.Animation.Define(stage, anim_in.GetPath())
    anim.CreateJointsAttr(anim_in.GetJointsAttr().Get())
    anim.CreateScalesAttr(anim_in.GetScalesAttr().Get())
    samples = [(anim.CreateTranslationsAttr(), anim_in.GetTranslationsAttr()),
               (anim.CreateRotationsAttr(), anim_in.GetRotationsAttr())]
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    if anim_in.GetBlendShapesAttr().HasAuthoredValue():
        anim.CreateBlendShapesAttr(anim_in.GetBlendShapesAttr().Get())
        samples.append((anim.CreateBlendShapeWeightsAttr(), anim_in.GetBlendShapeWeightsAttr()))
    for attr, attr_in in samples:
        for time in attr_in.GetTimeSamples():
            attr.Set(attr_in.Get(time), time)
    Usd.ModelAPI(root).SetKind(Usd.ModelAPI(root_in).GetKind())
    box = UsdGeom.Boundable(root_in).GetExtentAttr().Get()
    UsdGeom.Boundable(root).CreateExtentAttr(box)
    UsdGeom.ModelAPI(root).SetExtentsHint(box)
    stage.GetRootLayer().Save()


@pytest.mark.parametrize("weights", [False, True], ids=["skeleton", "blend-shape-weights"])
def test_the_skeleton_is_authored_as_usd_cores_schema_classes_author_it(tmp_path, weights):
    import dataclasses

    motion = read_motion(WALK, units="asf").sliced(0, 40)
    if weights:
        ramp = np.linspace(0.0, 1.0, motion.n_frames)
        motion = dataclasses.replace(motion, blend_shape_names=("smile", "blink"),
                                     blend_shape_weights=np.stack([ramp, 1.0 - ramp], axis=1))
    for ext in (".usda", ".usdc"):
        ours = write_usd(motion, tmp_path / f"walk{ext}")
        _authored_by_schema_classes(ours, tmp_path / f"reference{ext}")
        assert ours.read_bytes() == (tmp_path / f"reference{ext}").read_bytes(), ext


def test_usd_to_motion_to_bvh_round_trip(shared_file, tmp_path):
    original = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    usd = write_usd(original, tmp_path / "walk.usdc")
    back = read_usd(usd)
    assert back.joint_names == original.joint_names
    assert back.channels == original.channels and back.root_offset == original.root_offset
    assert np.array_equal(back.end_sites, original.end_sites)
    assert np.allclose(joint_positions(back), joint_positions(original), atol=1e-4)
    bvh = write_bvh(back, tmp_path / "walk.bvh")
    again = read_motion(bvh, root_offset=original.root_offset)
    assert np.allclose(joint_positions(again), joint_positions(original), atol=1e-4)


def _foreign_stage(path):
    """A UsdSkel stage shaped like a DCC export: rest rotations, an animation over a
    subset of joints in another order, a transformed skeleton prim, fps 24."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(24)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(4)
    UsdSkel.Root.Define(stage, "/Character")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/Character"))
    UsdGeom.Xform.Define(stage, "/Character/Armature").AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    skeleton = UsdSkel.Skeleton.Define(stage, "/Character/Armature/Skel")
    UsdGeom.Xformable(skeleton).AddRotateZOp().Set(90.0)
    joints = ["pelvis", "pelvis/spine", "pelvis/spine/head", "pelvis/thigh"]
    skeleton.CreateJointsAttr(Vt.TokenArray(joints))
    rest = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, 0, 1)),
            Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 0, 0), 30)) * Gf.Matrix4d().SetTranslateOnly(Gf.Vec3d(0, 0, 0.3)),
            Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, 0, 0.4)),
            Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.1, 0, -0.1))]
    skeleton.CreateRestTransformsAttr(Vt.Matrix4dArray(rest))
    world, bind = {}, []
    for token, matrix in zip(joints, rest):
        parent = token.rsplit("/", 1)[0] if "/" in token else None
        world[token] = matrix * world[parent] if parent else matrix
        bind.append(world[token])
    skeleton.CreateBindTransformsAttr(Vt.Matrix4dArray(bind))
    animation = UsdSkel.Animation.Define(stage, "/Character/Armature/Skel/Anim")
    animation.CreateJointsAttr(Vt.TokenArray(["pelvis/spine", "pelvis"]))
    animation.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * 2))
    for t in range(1, 5):
        animation.CreateTranslationsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0.3), Gf.Vec3f(0.1 * t, 0, 1)]), t)
        spin = Gf.Rotation(Gf.Vec3d(0, 0, 1), 20 * t).GetQuat()
        tilt = Gf.Rotation(Gf.Vec3d(1, 0, 0), 10 * t).GetQuat()
        animation.CreateRotationsAttr().Set(Vt.QuatfArray([Gf.Quatf(tilt), Gf.Quatf(spin)]), t)
    binding = UsdSkel.BindingAPI.Apply(skeleton.GetPrim())
    binding.CreateAnimationSourceRel().SetTargets([animation.GetPath()])
    stage.GetRootLayer().Save()
    return path


def test_reading_a_dcc_style_stage_matches_usd_core(tmp_path):
    path = _foreign_stage(tmp_path / "foreign.usda")
    motion = read_usd(path)
    assert motion.joint_names == ("pelvis", "spine", "head", "thigh")
    assert motion.n_frames == 4 and motion.fps == 24.0
    assert motion.up_axis == "Z" and motion.meters_per_unit == 1.0
    assert np.allclose(joint_positions(motion), usd_world_positions(path), atol=1e-6)  # time codes 1..4
    # and it converts on: BVH written from it reproduces the positions
    bvh = write_bvh(motion, tmp_path / "foreign.bvh")
    assert np.allclose(joint_positions(read_motion(bvh)), joint_positions(motion), atol=1e-6)


def test_bad_usd_inputs_raise_typed_errors(tmp_path):
    with pytest.raises(UsdReadError, match="no such file"):
        read_usd(tmp_path / "missing.usda")
    garbage = tmp_path / "garbage.usda"
    garbage.write_text("this is not USD\n")
    with pytest.raises(UsdReadError, match="cannot open as USD"):
        read_usd(garbage)
    empty = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    empty.DefinePrim("/World", "Xform")
    empty.GetRootLayer().Save()
    with pytest.raises(UsdReadError, match="no UsdSkel Skeleton"):
        read_usd(tmp_path / "empty.usda")


def test_unknown_extension_and_missing_folder_are_output_errors(tmp_path):
    motion = motion_from_bvh(parse_bvh(
        "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n}\nMOTION\n"
        "Frames: 1\nFrame Time: 0.1\n0 0 0\n"))
    with pytest.raises(OutputError, match="unknown output format"):
        write_motion(motion, tmp_path / "out.fbx")
    with pytest.raises(OutputError, match="does not exist"):
        write_motion(motion, tmp_path / "no" / "such" / "out.usda")
    assert list(tmp_path.iterdir()) == []  # nothing half-written

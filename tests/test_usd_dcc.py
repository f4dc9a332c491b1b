"""Reading stages as DCC tools and shot layouts author them (issue 15 items 1, 2, 4, 5;
issue 16 items 5 and 9): every joint position is compared with usd-core's own
``ComputeJointWorldTransforms`` at the stage's time codes, within 1e-5 × height."""

from __future__ import annotations

import numpy as np
import pytest
from usd_dcc_stages import JOINTS, author_skeleton, positions_by_name, usd_core_positions

from usdmotion.errors import UsdReadError
from usdmotion.io import read_motion
from usdmotion.io.usd import read_usd

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt  # noqa: E402

POSITION_TOL = 1e-5  # × height


def _assert_matches_usd_core(motion, path, skel_path, times):
    names, expected = usd_core_positions(path, skel_path, times)
    got = positions_by_name(motion, names)
    height = float(np.ptp(expected[0], axis=0).max())
    assert got.shape == expected.shape
    assert np.abs(got - expected).max() <= POSITION_TOL * height, np.abs(got - expected).max() / height


def _new_stage(path, tcps=24.0, mpu=0.01):
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetTimeCodesPerSecond(tcps)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    return stage


# ------------------------------------------------------------------ 1: ancestor scale


@pytest.mark.parametrize("scale", [100.0, 0.5])
def test_uniform_ancestor_scale_and_rotation_fold_into_the_motion(tmp_path, scale):
    """Blender's convert_scene_units / a scaled, rotated armature object: Xform ancestors
    with scale, rotation and translation above the Skeleton."""
    path = tmp_path / "scaled.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    units = UsdGeom.Xform.Define(stage, "/Char/Units")
    units.AddScaleOp().Set(Gf.Vec3f(scale, scale, scale))
    arm = UsdGeom.Xform.Define(stage, "/Char/Units/Armature")
    arm.AddTranslateOp().Set(Gf.Vec3d(0.3, 0, -1))
    arm.AddRotateXYZOp().Set(Gf.Vec3f(-90, 0, 30))
    arm.AddScaleOp().Set(Gf.Vec3f(1.5, 1.5, 1.5))
    author_skeleton(stage, "/Char/Units/Armature/Skel", times=range(1, 9))
    stage.GetRootLayer().Save()
    motion = read_usd(path)
    _assert_matches_usd_core(motion, path, "/Char/Units/Armature/Skel", range(1, 9))
    heights = np.ptp(positions_by_name(motion, ["Hips", "Head"])[0], axis=0)
    assert heights.max() > 0.5 * scale * 1.5 * 0.5  # the scale is in the lengths, not dropped


def test_non_uniform_ancestor_scale_is_refused_naming_the_prim(tmp_path):
    path = tmp_path / "squash.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    UsdGeom.Xform.Define(stage, "/Char/Armature").AddScaleOp().Set(Gf.Vec3f(1, 2, 1))
    author_skeleton(stage, "/Char/Armature/Skel")
    stage.GetRootLayer().Save()
    with pytest.raises(UsdReadError, match=r"/Char/Armature/Skel: non-uniform scale") as err:
        read_usd(path)
    assert str(path) in str(err.value)


# ------------------------------------------------------------------ 2: time


def _asset(path, fps=120.0, frames=30):
    stage = _new_stage(path, tcps=fps)
    stage.SetFramesPerSecond(fps)
    UsdSkel.Root.Define(stage, "/Char")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/Char"))
    author_skeleton(stage, "/Char/Skel", times=range(frames))
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(frames - 1)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize(("offset", "scale", "fps"), [(0.0, 1.0, 120.0), (10.0, 1.0, 120.0), (5.0, 2.0, 60.0)])
def test_a_120fps_asset_referenced_into_a_24tcps_shot_keeps_its_timing(tmp_path, offset, scale, fps):
    asset = _asset(tmp_path / "asset.usdc")
    shot = tmp_path / "shot.usda"
    stage = _new_stage(shot, tcps=24.0)
    stage.SetFramesPerSecond(24.0)
    prim = stage.DefinePrim("/Shot/Char")
    prim.GetReferences().AddReference(str(asset), Sdf.LayerOffset(offset, scale))
    stage.GetRootLayer().Save()

    times = np.asarray(UsdSkel.Animation(stage.GetPrimAtPath("/Shot/Char/Skel_Anim")).GetRotationsAttr()
                       .GetTimeSamples())  # usd-core's stage times of the samples
    motion = read_motion(shot)
    assert motion.n_frames == 30 == times.size
    assert motion.fps == pytest.approx(fps, rel=1e-9)
    assert motion.duration == pytest.approx((times[-1] - times[0]) / stage.GetTimeCodesPerSecond(), rel=1e-9)
    _assert_matches_usd_core(motion, shot, "/Shot/Char/Skel", times)


def _uneven(path):
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    author_skeleton(stage, "/Char/Skel", times=[0, 1, 2, 3, 5, 6, 7])
    stage.GetRootLayer().Save()
    return path


def test_uneven_time_samples_are_refused_or_resampled_by_option(tmp_path):
    path = _uneven(tmp_path / "uneven.usda")
    with pytest.raises(UsdReadError, match=r"/Char/Skel_Anim: time samples are unevenly spaced .*time 3"):
        read_usd(path)
    motion = read_usd(path, resample=True)
    assert motion.n_frames == 8 and motion.fps == 24.0
    _assert_matches_usd_core(motion, path, "/Char/Skel", range(8))  # USD's own interpolation at t=4


# ------------------------------------------------------------------ 4: several skeletons


def test_several_skeletons_are_listed_and_one_is_chosen(tmp_path):
    path = tmp_path / "two.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/A")
    author_skeleton(stage, "/A/Skel", seed=1)
    UsdSkel.Root.Define(stage, "/B")
    UsdGeom.Xform.Define(stage, "/B/Offset").AddTranslateOp().Set(Gf.Vec3d(2, 0, 0))
    author_skeleton(stage, "/B/Offset/Skel", seed=2)
    stage.GetRootLayer().Save()
    with pytest.raises(UsdReadError, match=r"2 skeletons in the stage \(/A/Skel, /B/Offset/Skel\)"):
        read_usd(path)
    for choice in ("/A/Skel", "/B/Offset/Skel"):
        _assert_matches_usd_core(read_usd(path, skeleton=choice), path, choice, range(10))
    with pytest.raises(UsdReadError, match="matches several"):
        read_usd(path, skeleton="Skel")
    with pytest.raises(UsdReadError, match="is not one of"):
        read_usd(path, skeleton="/C/Skel")


# ------------------------------------------------------------------ 5: several roots


def test_several_root_joints_are_read_with_world_positions_kept(tmp_path):
    path = tmp_path / "roots.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    UsdGeom.Xform.Define(stage, "/Char/Arm").AddRotateYOp().Set(40.0)
    joints = ["ik_foot_root", "ik_foot_root/ik_foot_l"] + JOINTS + ["prop"]
    offsets = np.vstack([[[0, 0, 0], [0.1, 0, 0.05]], author_offsets(), [[0.5, 1.0, 0.2]]])
    author_skeleton(stage, "/Char/Arm/Skel", joints=joints, offsets=offsets)
    stage.GetRootLayer().Save()
    with pytest.warns(UserWarning, match="3 root joints; Hips is the root"):
        motion = read_usd(path)
    assert motion.joint_names[0] == "Hips" and motion.parents[0] == -1
    assert motion.parents[motion.joint_index("prop")] == 0
    assert motion.parents[motion.joint_index("ik_foot_l")] == motion.joint_index("ik_foot_root")
    _assert_matches_usd_core(motion, path, "/Char/Arm/Skel", range(10))


def author_offsets():
    from usd_dcc_stages import OFFSETS

    return OFFSETS


# ------------------------------------------------------------------ issue 16 item 5: validation


def _broken(path, edit):
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    skel = author_skeleton(stage, "/Char/Skel", times=range(4))
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/Char/Skel_Anim"))
    edit(anim, skel)
    stage.GetRootLayer().Save()
    return path


def _short_rotations(anim, skel):
    anim.GetRotationsAttr().Set(Vt.QuatfArray([Gf.Quatf(1)] * (len(JOINTS) - 1)), 2.0)


def _nan_translation(anim, skel):
    value = np.array(anim.GetTranslationsAttr().Get(1.0))
    value[3, 1] = np.nan
    anim.GetTranslationsAttr().Set(Vt.Vec3fArray.FromNumpy(value), 1.0)


def _zero_quaternion(anim, skel):
    value = np.array(anim.GetRotationsAttr().Get(3.0))
    value[2] = 0
    anim.GetRotationsAttr().Set(Vt.QuatfArray.FromNumpy(value), 3.0)


def _huge_quaternion(anim, skel):
    value = np.array(anim.GetRotationsAttr().Get(0.0))
    value[0] = [1e30, 0, 0, 1e30]
    anim.GetRotationsAttr().Set(Vt.QuatfArray.FromNumpy(value), 0.0)


def _no_rotations(anim, skel):
    anim.GetPrim().RemoveProperty("rotations")


def _short_rest(anim, skel):
    skel.GetRestTransformsAttr().Set(Vt.Matrix4dArray([Gf.Matrix4d(1)] * 3))


BROKEN = [
    (_short_rotations, r"/Char/Skel_Anim\.rotations at time 2 has 8 values for 9 joints"),
    (_nan_translation, r"/Char/Skel_Anim\.translations at time 1: value 3 is not finite"),
    (_zero_quaternion, r"/Char/Skel_Anim\.rotations at time 3: rotation of joint Hips/Spine/Chest has length 0"),
    (_huge_quaternion, r"/Char/Skel_Anim\.rotations at time 0: (rotation of joint Hips has length|value 0 is not)"),
    (_no_rotations, r"/Char/Skel_Anim: the SkelAnimation has no rotations"),
    (_short_rest, r"(/Char/Skel is invalid|/Char/Skel\.restTransforms has 3 matrices for 9 joints)"),
]


@pytest.mark.parametrize(("edit", "message"), BROKEN, ids=[b[0].__name__.strip("_") for b in BROKEN])
def test_broken_animation_arrays_are_refused_naming_file_prim_and_time(tmp_path, edit, message):
    path = _broken(tmp_path / "broken.usda", edit)
    with pytest.raises(UsdReadError, match=message) as err:
        read_usd(path)
    assert str(err.value).startswith(str(path))


# ------------------------------------------------------------------ 3 (not yet carried): said, not silent


def test_a_skinned_mesh_that_is_not_carried_over_is_named_in_a_warning(tmp_path):
    path = tmp_path / "skinned.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    skel = author_skeleton(stage, "/Char/Skel")
    mesh = UsdGeom.Mesh.Define(stage, "/Char/Body")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(0, 1, 0), Gf.Vec3f(1, 0, 0)]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(True, 1).Set(Vt.IntArray([0]))
    binding.CreateJointWeightsPrimvar(True, 1).Set(Vt.FloatArray([1.0]))
    stage.GetRootLayer().Save()
    with pytest.warns(UserWarning, match=r"its skinned geometry \(/Char/Body\) is not read and is not carried"):
        read_usd(path)

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


# ------------------------------------------------------------------ 3: skinned meshes carried


def _skinned_stage(path):
    """A skinned quad strip with normals, UVs, a colour and a blend shape, bound to a
    skeleton under a scaled, rotated, moved Xform, with a non-identity geomBindTransform."""
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    arm = UsdGeom.Xform.Define(stage, "/Char/Arm")
    arm.AddTranslateOp().Set(Gf.Vec3d(0.5, 0, 2))
    arm.AddRotateYOp().Set(35.0)
    arm.AddScaleOp().Set(Gf.Vec3f(100, 100, 100))
    skel = author_skeleton(stage, "/Char/Arm/Skel")
    rest = np.array(skel.GetRestTransformsAttr().Get())
    world = {}
    for j, token in enumerate(JOINTS):  # bind = rest world (row-vector)
        parent = token.rsplit("/", 1)[0] if "/" in token else None
        world[token] = rest[j] @ world[parent] if parent else rest[j]
    skel.GetBindTransformsAttr().Set(Vt.Matrix4dArray.FromNumpy(np.stack([world[t] for t in JOINTS])))
    geom_bind = Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.01, -0.02, 0.03))
    rng = np.random.default_rng(3)
    points = np.concatenate([rng.uniform(-0.2, 0.2, (12, 3)) + [0, y, 0] for y in (0.3, 1.0, 1.5)])
    mesh = UsdGeom.Mesh.Define(stage, "/Char/Body")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * 12))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.arange(36, dtype=np.int32)))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.tile(np.float32([0, 0, 1]), (36, 1))))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex).Set(
        Vt.Vec2fArray.FromNumpy(rng.uniform(0, 1, (36, 2)).astype(np.float32)))
    mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(0.2, 0.4, 0.6)]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointsAttr(Vt.TokenArray([JOINTS[6], JOINTS[0], JOINTS[3]]))  # the mesh's own joint order
    indices = rng.integers(0, 3, (36, 2)).astype(np.int32)
    weights = rng.uniform(0.1, 1, (36, 2)).astype(np.float32)
    binding.CreateJointIndicesPrimvar(False, 2).Set(Vt.IntArray.FromNumpy(indices.reshape(-1)))
    binding.CreateJointWeightsPrimvar(False, 2).Set(Vt.FloatArray.FromNumpy((weights / weights.sum(1, keepdims=True))
                                                                            .reshape(-1)))
    binding.CreateGeomBindTransformAttr(geom_bind)
    smile = UsdSkel.BlendShape.Define(stage, "/Char/Body/smile")
    smile.CreateOffsetsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0.01, 0), Gf.Vec3f(0.02, 0, 0)]))
    smile.CreatePointIndicesAttr(Vt.IntArray([4, 7]))
    binding.CreateBlendShapesAttr(Vt.TokenArray(["smile"]))
    binding.CreateBlendShapeTargetsRel().SetTargets([smile.GetPath()])
    stage.GetRootLayer().Save()
    return path


def usd_core_skinned_world(path, times):
    """World positions ``(T, V, 3)`` of every skinned mesh's points by usd-core, by mesh name."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    out = {}
    for root in (p for p in stage.Traverse() if p.IsA(UsdSkel.Root)):
        cache = UsdSkel.Cache()
        cache.Populate(UsdSkel.Root(root), Usd.PrimDefaultPredicate)
        for binding in cache.ComputeSkelBindings(UsdSkel.Root(root), Usd.PrimDefaultPredicate):
            skel_query = cache.GetSkelQuery(binding.GetSkeleton())
            for query in binding.GetSkinningTargets():
                frames = []
                for t in times:
                    skinned = Vt.Vec3fArray(UsdGeom.Mesh(query.GetPrim()).GetPointsAttr().Get(t))
                    assert query.ComputeSkinnedPoints(skel_query.ComputeSkinningTransforms(t), skinned, t)
                    skel_world = np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(binding.GetSkeleton().GetPrim()))
                    homog = np.concatenate([np.array(skinned, np.float64), np.ones((len(skinned), 1))], axis=1)
                    frames.append((homog @ skel_world)[:, :3])
                out[query.GetPrim().GetName()] = np.asarray(frames)
    return out


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_skinned_meshes_are_carried_through_convert_and_trim(tmp_path, ext):
    from usdmotion.io import write_motion

    source = _skinned_stage(tmp_path / "skinned.usda")
    motion = read_motion(source)
    assert [m.name for m in motion.meshes] == ["Body"]
    expected = usd_core_skinned_world(source, range(10))["Body"]
    height = float(np.ptp(expected.reshape(-1, 3), axis=0).max())

    out = write_motion(motion, tmp_path / f"out{ext}")
    got = usd_core_skinned_world(out, range(10))["Body"]
    assert np.abs(got - expected).max() <= POSITION_TOL * height

    clip = write_motion(motion.sliced(3, 8), tmp_path / f"clip{ext}")  # what trim does
    got = usd_core_skinned_world(clip, range(5))["Body"]
    assert np.abs(got - expected[3:8]).max() <= POSITION_TOL * height

    stage = Usd.Stage.Open(str(out))
    body = UsdGeom.Mesh(stage.GetPrimAtPath(f"/out/Body"))
    assert np.allclose(np.array(body.GetDisplayColorPrimvar().Get())[0], [0.2, 0.4, 0.6])
    src = Usd.Stage.Open(str(source))
    src_st = UsdGeom.PrimvarsAPI(src.GetPrimAtPath("/Char/Body")).GetPrimvar("st").Get()
    assert np.array_equal(np.array(UsdGeom.PrimvarsAPI(body).GetPrimvar("st").Get()), np.array(src_st))
    assert len(body.GetFaceVertexIndicesAttr().Get()) == 36
    shape = UsdSkel.BlendShape(stage.GetPrimAtPath("/out/Body/smile"))
    linear = (np.array(Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.01, -0.02, 0.03)))
              @ np.array(UsdGeom.XformCache(0).GetLocalToWorldTransform(src.GetPrimAtPath("/Char/Arm/Skel"))))[:3, :3]
    assert np.allclose(np.array(shape.GetOffsetsAttr().Get()), np.array([[0, 0.01, 0], [0.02, 0, 0]]) @ linear,
                       atol=1e-5)
    assert list(shape.GetPointIndicesAttr().Get()) == [4, 7]


def test_a_mesh_whose_skeleton_changed_is_left_out_with_a_warning(tmp_path):
    import dataclasses

    from usdmotion.io import write_motion

    motion = read_motion(_skinned_stage(tmp_path / "skinned.usda"))
    longer = dataclasses.replace(motion, offsets=motion.offsets * 1.1)  # e.g. a retarget to another body
    with pytest.warns(UserWarning, match="skinned mesh Body left out: the skeleton's rest offsets changed"):
        out = write_motion(longer, tmp_path / "out.usda")
    assert not Usd.Stage.Open(str(out)).GetPrimAtPath("/out/Body")


def test_our_own_mesh_output_keeps_its_body_and_bvh_output_says_it_drops_it(tmp_path):
    from usdmotion.io import write_motion
    from usdmotion.io.usd_mesh import body_decorator
    from usdmotion.skin import build_body

    motion = read_motion(_skinned_stage(tmp_path / "skinned.usda"))
    plain = dataclasses_replace(motion, meshes=())
    first = write_motion(plain, tmp_path / "first.usdc", decorate=body_decorator(build_body(plain)))
    expected = usd_core_skinned_world(first, range(10))["Body"]
    again = write_motion(read_motion(first), tmp_path / "again.usda")
    got = usd_core_skinned_world(again, range(10))["Body"]
    assert np.abs(got - expected).max() <= POSITION_TOL * float(np.ptp(expected.reshape(-1, 3), axis=0).max())
    with pytest.warns(UserWarning, match=r"skinned meshes \(Body\) are not written: BVH holds no geometry"):
        write_motion(read_motion(first), tmp_path / "again.bvh")


def dataclasses_replace(motion, **changes):
    import dataclasses

    return dataclasses.replace(motion, **changes)


# ------------------------------------------------------------------ 6: the stage's own body for render


def usd_core_baked_world(path, times):
    """World points ``(T, V, 3)`` of every skinned mesh after usd-core's ``UsdSkel.BakeSkinning``."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    stage.SetEditTarget(stage.GetSessionLayer())  # bake into the session layer, not the file
    assert UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(times), max(times)))
    out = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh) and prim.HasAPI(UsdSkel.BindingAPI):
            frames = []
            for t in times:
                points = np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(t), np.float64)
                world = np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(prim))
                frames.append((np.concatenate([points, np.ones((len(points), 1))], axis=1) @ world)[:, :3])
            out[prim.GetName()] = np.asarray(frames)
    return out


def test_the_stage_body_skins_as_usd_core_bakes_it(tmp_path):
    from usdmotion.skin import skin_frames
    from usdmotion.skin_stage import stage_body

    source = _skinned_stage(tmp_path / "skinned.usda")
    motion = read_motion(source)
    body = stage_body(motion)
    assert body.faces.shape == (12, 3) and len(body.vertices) == 36
    expected = usd_core_baked_world(source, range(10))["Body"]
    got = skin_frames(body, motion)
    assert np.abs(got - expected).max() <= POSITION_TOL * float(np.ptp(expected.reshape(-1, 3), axis=0).max())


def test_retarget_says_the_source_mesh_is_left_out(tmp_path, capsys):
    from usdmotion.cli import main

    source = _skinned_stage(tmp_path / "skinned.usda")
    code = main(["retarget", str(source), str(tmp_path / "out.usda"), "--remove", "RShin", "--iterations", "5"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "skinned meshes (Body) left out: retarget changes the skeleton" in err
    assert not Usd.Stage.Open(str(tmp_path / "out.usda")).GetPrimAtPath("/out/Body")


@pytest.mark.parametrize(("custom", "message"), [
    ({"channels": Vt.StringArray(["Qrotation Wposition"] * len(JOINTS))}, "'Qrotation' is not a BVH channel"),
    ({"channels": Vt.StringArray(["Xrotation Xrotation"] * len(JOINTS))}, "a channel repeats"),
    ({"endSites": Vt.IntArray([0])}, "endSites that are not leaf joints"),
])
def test_distrusted_metadata_is_ignored_and_the_bvh_reads_back(tmp_path, custom, message):
    from usdmotion.io import write_motion

    path = tmp_path / "meta.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/Char")
    author_skeleton(stage, "/Char/Skel").GetPrim().SetCustomDataByKey("usdmotion", custom)
    stage.GetRootLayer().Save()
    with pytest.warns(UserWarning, match=message):
        motion = read_usd(path)
    back = read_motion(write_motion(motion, tmp_path / "back.bvh"))
    _assert_matches_usd_core(back, path, "/Char/Skel", range(10))


def test_info_lists_the_skeletons_of_a_stage(tmp_path, capsys):
    import json

    from usdmotion.cli import main

    path = tmp_path / "one.usda"
    stage = _new_stage(path)
    UsdSkel.Root.Define(stage, "/A")
    author_skeleton(stage, "/A/Skel")
    stage.GetRootLayer().Save()
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["skeletons"] == ["/A/Skel"]
    UsdSkel.Root.Define(stage, "/B")
    author_skeleton(stage, "/B/Skel")
    stage.GetRootLayer().Save()
    assert main(["info", str(path)]) == 2
    assert "2 skeletons in the stage (/A/Skel, /B/Skel); choose one with --skeleton" in capsys.readouterr().err
    assert main(["info", str(path), "--skeleton", "/B/Skel", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["skeletons"] == ["/A/Skel", "/B/Skel"]


def test_cli_resample_option_reads_uneven_samples(tmp_path, capsys):
    from usdmotion.cli import main

    path = _uneven(tmp_path / "uneven.usda")
    assert main(["info", str(path)]) == 2
    assert "unevenly spaced" in capsys.readouterr().err
    assert main(["convert", str(path), str(tmp_path / "even.bvh"), "--resample"]) == 0
    assert read_motion(tmp_path / "even.bvh").n_frames == 8


def test_trim_resample_and_reorient_commands_keep_the_mesh(tmp_path, capsys):
    from usdmotion.cli import main

    source = _skinned_stage(tmp_path / "skinned.usda")
    expected = usd_core_skinned_world(source, range(10))["Body"]
    height = float(np.ptp(expected.reshape(-1, 3), axis=0).max())
    assert main(["trim", str(source), str(tmp_path / "trim.usda"), "--frames", "2:7"]) == 0, capsys.readouterr().err
    got = usd_core_skinned_world(tmp_path / "trim.usda", range(5))["Body"]
    assert np.abs(got - expected[2:7]).max() <= POSITION_TOL * height
    assert main(["resample", str(source), str(tmp_path / "slow.usdc"), "--fps", "48"]) == 0, capsys.readouterr().err
    slow = usd_core_skinned_world(tmp_path / "slow.usdc", range(0, 19, 2))["Body"]  # every other frame = the input's
    assert np.abs(slow - expected).max() <= 1e-3 * height  # resampling slerps between frames; on-frame it matches
    assert main(["reorient", str(source), str(tmp_path / "turned.usda"), "--rotate", "90"]) == 0
    assert Usd.Stage.Open(str(tmp_path / "turned.usda")).GetPrimAtPath("/turned/Body")
    capsys.readouterr()
    assert main(["info", str(tmp_path / "turned.usda")]) == 0
    assert "mesh        Body: 36 points skinned to the skeleton, blend shapes smile" in capsys.readouterr().out


def test_a_broken_skinned_mesh_is_not_read_and_said_so(tmp_path):
    path = _skinned_stage(tmp_path / "skinned.usda")
    stage = Usd.Stage.Open(str(path))
    UsdSkel.BindingAPI(stage.GetPrimAtPath("/Char/Body")).GetJointIndicesPrimvar().Set(Vt.IntArray([7] * 72))
    stage.GetRootLayer().Save()
    with pytest.warns(UserWarning, match="/Char/Body: skinned mesh not read: joint indices outside the joint list"):
        motion = read_usd(path)
    assert motion.meshes == ()

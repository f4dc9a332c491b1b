"""UsdSkel stages authored the way layout/shot files and DCC exporters author them, with
usd-core only, and usd-core's own evaluation of them (the independent reference)."""

from __future__ import annotations

import numpy as np

# A small humanoid-ish rig: hips chain plus legs; joint path tokens, parents before children.
JOINTS = ["Hips", "Hips/Spine", "Hips/Spine/Chest", "Hips/Spine/Chest/Head", "Hips/Spine/Chest/LArm",
          "Hips/LThigh", "Hips/LThigh/LShin", "Hips/RThigh", "Hips/RThigh/RShin"]
OFFSETS = np.array([[0, 0.95, 0], [0, 0.12, 0.01], [0, 0.25, 0], [0, 0.3, 0], [0.2, 0.2, 0],
                    [0.1, -0.05, 0], [0, -0.42, 0.01], [-0.1, -0.05, 0], [0, -0.42, 0.01]])


def random_quats_xyzw(rng, shape, spread=0.6) -> np.ndarray:
    """Unit quaternions ``shape + (4,)`` (x, y, z, w), rotations up to ~``spread`` rad."""
    axis = rng.normal(size=shape + (3,))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = rng.uniform(-spread, spread, size=shape + (1,))
    return np.concatenate([axis * np.sin(angle / 2), np.cos(angle / 2)], axis=-1)


def author_skeleton(stage, skel_path: str, joints=JOINTS, offsets=OFFSETS, times=range(10), seed=0,
                    rest_rotations: bool = True, scales: bool = True):
    """Define a Skeleton at ``skel_path`` with rest transforms (rotated rests like Blender's
    when ``rest_rotations``) and a bound SkelAnimation ``<skel_path>_Anim`` sampled at
    ``times``; returns the Skeleton."""
    from pxr import Gf, UsdSkel, Vt

    rng = np.random.default_rng(seed)
    skel = UsdSkel.Skeleton.Define(stage, skel_path)
    skel.CreateJointsAttr(Vt.TokenArray(list(joints)))
    rest_q = random_quats_xyzw(rng, (len(joints),), 0.3 if rest_rotations else 0.0)
    rest = []
    for q, t in zip(rest_q, offsets):
        m = Gf.Matrix4d().SetRotate(Gf.Quatd(float(q[3]), Gf.Vec3d(*map(float, q[:3]))))
        rest.append(m.SetTranslateOnly(Gf.Vec3d(*map(float, t))))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(rest))  # not used for reading motion
    anim = UsdSkel.Animation.Define(stage, skel_path + "_Anim")
    anim.CreateJointsAttr(Vt.TokenArray(list(joints)))
    if scales:
        anim.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((len(joints), 3), np.float16)))
    rot_attr, tr_attr = anim.CreateRotationsAttr(), anim.CreateTranslationsAttr()
    for k, t in enumerate(times):
        trans = np.array(offsets, np.float32)
        trans[0] += np.float32([0.05 * k, 0.01 * np.sin(k), 0.02 * k])
        rot_attr.Set(Vt.QuatfArray.FromNumpy(random_quats_xyzw(rng, (len(joints),)).astype(np.float32)), float(t))
        tr_attr.Set(Vt.Vec3fArray.FromNumpy(trans), float(t))
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    return skel


def usd_core_positions(path, skel_path: str, times) -> tuple[list[str], np.ndarray]:
    """``(joint leaf names, world positions (T, J, 3))`` by usd-core's
    ``ComputeJointWorldTransforms`` at stage ``times`` (ancestor transforms included)."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    query = UsdSkel.Cache().GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(skel_path)))
    frames = [np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(float(t))))[:, 3, :3] for t in times]
    return [str(t).rsplit("/", 1)[-1] for t in query.GetJointOrder()], np.asarray(frames)


def positions_by_name(motion, names: list[str]) -> np.ndarray:
    """``joint_positions(motion)`` ``(F, J, 3)`` in the order of ``names``."""
    from usdmotion.kinematics import joint_positions

    return joint_positions(motion)[:, [motion.joint_names.index(n) for n in names]]

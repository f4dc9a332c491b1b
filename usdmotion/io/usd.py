"""UsdSkel writing and reading: ``Motion`` ⇄ ``UsdSkel.Root › Skeleton › SkelAnimation``.

Stage layout written::

    /<Name>                 SkelRoot (defaultPrim)
    /<Name>/Skeleton        Skeleton, SkelBindingAPI, skel:animationSource → Animation
    /<Name>/Animation       SkelAnimation (translations, rotations per frame; scales)

* Joint paths are DCC-safe identifiers (``mixamorig:Hips`` → ``mixamorig_Hips``), each
  last element unique in the skeleton (``a:b`` and ``a_b`` → ``a_b``, ``a_b_2``); the
  original names are kept in ``jointNames`` and in the Skeleton's customData
  ``usdmotion:jointNames``, together with the BVH channel layout, end-site flags and
  root-offset convention, so USD → BVH restores the file it came from.
* ``restTransforms`` are the local rest transforms (OFFSETs, no rotation);
  ``bindTransforms`` their world composition: the BVH rest pose.
* Stage metadata: ``upAxis``, ``metersPerUnit``, ``timeCodesPerSecond`` =
  ``framesPerSecond`` = fps, time codes 0 … F-1 (one per frame, which Blender needs).
* Animation data is written with bulk ``Vt`` arrays under one ``Sdf.ChangeBlock``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError, UsdMotionWarning, UsdReadError
from usdmotion.io.atomic import atomic_output
from usdmotion.usd_diagnostics import usd_error_message
from usdmotion.kinematics import compose_transforms, rest_pose
from usdmotion.motion import Motion
from usdmotion.rotations import matrix_to_quat, quat_mul, quat_rotate, wxyz_to_xyzw

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
CUSTOM_KEY = "usdmotion"


def _identifier(name: str) -> str:
    from pxr import Tf

    name = name.strip() or "joint"
    if name[0].isdigit():
        name = "_" + name
    return Tf.MakeValidIdentifier(name)


def joint_path_tokens(joint_names: tuple[str, ...], parents: np.ndarray) -> list[str]:
    """UsdSkel joint paths (``"Hips/Spine/Chest"``) whose last elements are valid identifiers,
    unique in the whole skeleton, not only among siblings: DCC tools name bones by the last
    element (Blender renames a repeat to ``a_b.001`` and binds skin weights by that name, so
    the vertices of the second ``a_b`` lose their weights)."""
    tokens: list[str] = []
    used: set[str] = set()
    for j, name in enumerate(joint_names):
        parent_path = tokens[parents[j]] if parents[j] >= 0 else ""
        base = _identifier(name)
        leaf, k = base, 2
        while leaf in used:
            leaf, k = f"{base}_{k}", k + 1
        used.add(leaf)
        tokens.append(f"{parent_path}/{leaf}" if parent_path else leaf)
    return tokens


def _usd_matrices(transforms: np.ndarray):
    """``Vt.Matrix4dArray`` from column-vector 4×4 transforms ``(J, 4, 4)`` (USD is row-vector)."""
    from pxr import Vt

    return Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.swapaxes(transforms, -1, -2)))


def _rest_transforms(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """``(local (J,4,4), world (J,4,4))`` rest transforms: OFFSETs, identity rotations."""
    identity = np.zeros((motion.n_joints, 4))
    identity[:, 0] = 1.0
    return compose_transforms(identity, motion.offsets), compose_transforms(*rest_pose(motion))


def _stage_name(path: Path, name: str | None) -> str:
    return _identifier(name or path.stem.split(".")[0] or "Motion")


def define_skeleton(stage, motion: Motion, root_path: str):
    """Author SkelRoot, Skeleton and SkelAnimation for ``motion`` under ``root_path``.

    Returns the ``UsdSkel.Skeleton``.
    """
    from pxr import Sdf, UsdGeom, UsdSkel, Vt

    root = UsdSkel.Root.Define(stage, root_path)
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if motion.up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, motion.meters_per_unit)
    stage.SetTimeCodesPerSecond(motion.fps)
    stage.SetFramesPerSecond(motion.fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(max(motion.n_frames - 1, 0))

    tokens = Vt.TokenArray(joint_path_tokens(motion.joint_names, motion.parents))
    skel = UsdSkel.Skeleton.Define(stage, f"{root_path}/Skeleton")
    skel.CreateJointsAttr(tokens)
    skel.CreateJointNamesAttr(Vt.TokenArray(list(motion.joint_names)))
    rest_local, rest_world = _rest_transforms(motion)
    skel.CreateRestTransformsAttr(_usd_matrices(rest_local))
    skel.CreateBindTransformsAttr(_usd_matrices(rest_world))
    custom = {
        "jointNames": Vt.StringArray(list(motion.joint_names)),
        "endSites": Vt.IntArray([int(j) for j in np.flatnonzero(motion.end_sites)]),
        "rootOffset": motion.root_offset,
    }
    if motion.channels is not None:
        custom["channels"] = Vt.StringArray([" ".join(c) for c in motion.channels])
    skel.GetPrim().SetCustomDataByKey(CUSTOM_KEY, custom)

    anim = UsdSkel.Animation.Define(stage, f"{root_path}/Animation")
    anim.CreateJointsAttr(tokens)
    anim.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((motion.n_joints, 3), np.float16)))
    translations_attr = anim.CreateTranslationsAttr()
    rotations_attr = anim.CreateRotationsAttr()
    binding = UsdSkel.BindingAPI.Apply(skel.GetPrim())
    binding.CreateAnimationSourceRel().SetTargets([anim.GetPath()])

    layer = stage.GetRootLayer()
    t_path, r_path = translations_attr.GetPath(), rotations_attr.GetPath()
    if motion.n_frames == 0:
        translations_attr.Set(Vt.Vec3fArray.FromNumpy(motion.offsets.astype(np.float32)))
        rotations_attr.Set(Vt.QuatfArray.FromNumpy(np.tile(np.float32([0, 0, 0, 1]), (motion.n_joints, 1))))
    with Sdf.ChangeBlock():
        for start in range(0, motion.n_frames, _CHUNK_FRAMES):  # float32 copies of one chunk at a time
            translations, rotations = _float32_samples(motion, start, start + _CHUNK_FRAMES)
            for k in range(translations.shape[0]):  # one time sample per frame: the USD API's unit
                layer.SetTimeSample(t_path, float(start + k), Vt.Vec3fArray.FromNumpy(translations[k]))
                layer.SetTimeSample(r_path, float(start + k), Vt.QuatfArray.FromNumpy(rotations[k]))
    return skel


#: Frames converted to float32 at a time while writing (bounds the temporary copies).
_CHUNK_FRAMES = 4096


def _float32_samples(motion: Motion, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """``(translations (n, J, 3), rotations xyzw (n, J, 4))`` float32 of frames ``start:stop``."""
    stop = min(stop, motion.n_frames)
    if motion.joint_translations is not None:
        translations = motion.joint_translations[start:stop].astype(np.float32)
    else:
        translations = np.empty((stop - start, motion.n_joints, 3), np.float32)
        translations[:] = motion.offsets.astype(np.float32)
    translations[:, 0] = motion.root_translation[start:stop]
    rotations = wxyz_to_xyzw(motion.rotations[start:stop]).astype(np.float32)
    return translations, rotations


def write_usd(motion: Motion, path: str | os.PathLike, name: str | None = None,
              decorate=None) -> Path:
    """Write ``motion`` as a UsdSkel stage (``.usda``, ``.usdc``, ``.usd`` or ``.usdz``).

    Args:
        motion: the motion.
        path: output file; the extension picks the format. Written atomically.
        name: SkelRoot prim name (default: the file stem, made a valid identifier).
        decorate: optional ``callable(stage, skeleton)`` that adds prims (e.g. a skinned
            mesh) before the stage is saved.
    """
    from pxr import Usd

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in USD_EXTENSIONS:
        raise OutputError(f"{path}: unknown USD extension {ext!r} (use {', '.join(USD_EXTENSIONS)})")
    _check_float32(motion, path)
    root_path = "/" + _stage_name(path, name)
    with atomic_output(path) as tmp:
        layer_path = tmp
        scratch = None
        if ext == ".usdz":
            scratch = Path(tempfile.mkdtemp(prefix="usdmotion-"))
            layer_path = scratch / (path.stem + ".usdc")
        try:
            stage = Usd.Stage.CreateNew(str(layer_path))
            skel = define_skeleton(stage, motion, root_path)
            if decorate is not None:
                decorate(stage, skel)
            stage.GetRootLayer().Save()
            del stage
            if ext == ".usdz":
                from pxr import Sdf, UsdUtils  # only here: UsdUtils imports UsdShade, Sdr, ... (~0.03 s)

                if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(layer_path)), str(tmp)):
                    raise OutputError(f"{path}: usdz packaging failed")
        finally:
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
    return path


def _check_float32(motion: Motion, path: Path) -> None:
    """Refuse translations that USD's float32 samples cannot hold (they would become inf)."""
    limit = float(np.finfo(np.float32).max)
    for name, a in (("joint offsets", motion.offsets), ("root translation", motion.root_translation),
                    ("joint translations", motion.joint_translations)):
        if a is not None and a.size and not -limit <= a.min() <= a.max() <= limit:
            raise OutputError(f"{path}: {name} hold values beyond USD's float32 range (±{limit:.3g}) or NaN; "
                              "nothing written")


def validate_stage(stage) -> list[str]:
    """Run every registered ``pxr.UsdValidation`` validator; return the error messages."""
    from pxr import Usd, UsdValidation

    if isinstance(stage, (str, os.PathLike)):
        stage = Usd.Stage.Open(str(stage))
    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    errors = context.Validate(stage)
    return [f"{e.GetName()}: {e.GetMessage()}" for e in errors
            if e.GetType() == UsdValidation.ValidationErrorType.Error]


# --------------------------------------------------------------------------- reading


def _open_stage(path: Path):
    from pxr import Tf, Usd

    if not path.is_file():
        raise UsdReadError(path, "no such file")
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:
        line, message = usd_error_message(exc)
        raise UsdReadError(path, f"cannot open as USD: {message}", line) from None
    if stage is None:
        raise UsdReadError(path, "cannot open as USD")
    return stage


def _find_skeleton(stage, path: Path):
    from pxr import Usd, UsdSkel

    default = stage.GetDefaultPrim()
    roots = [default] if default and default.IsValid() else []
    roots.append(stage.GetPseudoRoot())
    for start in roots:
        for prim in Usd.PrimRange(start):
            if prim.IsA(UsdSkel.Skeleton):
                return UsdSkel.Skeleton(prim)
    raise UsdReadError(path, "no UsdSkel Skeleton in the stage")


def _decompose(local: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Column-vector ``(..., 4, 4)`` → ``(rotation wxyz (..., 4), translation (..., 3), max |scale-1|)``."""
    linear = local[..., :3, :3]
    scale = np.linalg.norm(linear, axis=-2)
    safe = np.where(scale > 0, scale, 1.0)
    rotation = matrix_to_quat(linear / safe[..., None, :])
    return rotation, local[..., :3, 3], float(np.max(np.abs(scale - 1.0), initial=0.0))


def read_usd(path: str | os.PathLike) -> Motion:
    """Read the first UsdSkel skeleton of a stage (ours or a DCC tool's) into a :class:`Motion`.

    Local joint transforms come from ``UsdSkel.SkeletonQuery`` (animation where authored,
    rest transforms elsewhere); the skeleton prim's own world transform is folded into
    the root so world positions match ``ComputeJointWorldTransforms``. Positions are in
    stage units.
    """
    from pxr import Usd, UsdGeom, UsdSkel

    path = Path(path)
    stage = _open_stage(path)
    skel = _find_skeleton(stage, path)
    cache = UsdSkel.Cache()
    query = cache.GetSkelQuery(skel)
    if not query:
        raise UsdReadError(path, f"skeleton {skel.GetPath()} is invalid (joints, rest transforms?)")
    topology = query.GetTopology()
    ok, reason = topology.Validate()
    if not ok:
        raise UsdReadError(path, f"skeleton {skel.GetPath()}: {reason}")
    parents = np.asarray(topology.GetParentIndices(), dtype=np.int64)
    tokens = [str(t) for t in query.GetJointOrder()]
    if np.count_nonzero(parents < 0) != 1 or parents[0] != -1:
        raise UsdReadError(path, f"skeleton {skel.GetPath()} has {np.count_nonzero(parents < 0)} root joints; "
                                 "exactly one is supported")
    custom = dict(skel.GetPrim().GetCustomDataByKey(CUSTOM_KEY) or {})
    names = _joint_names(skel, tokens, custom)

    anim_query = query.GetAnimQuery()
    times = list(anim_query.GetJointTransformTimeSamples()) if anim_query else []
    if not times:
        times = [Usd.TimeCode.Default()]
    local = np.stack([np.array(query.ComputeJointLocalTransforms(t)) for t in times])  # per time sample
    local = np.swapaxes(local, -1, -2)  # row-vector → column-vector
    rotations, translations, scale_error = _decompose(local)
    if scale_error > 1e-4:
        warnings.warn(f"{path}: joint scales (up to {1 + scale_error:.4g}) are ignored", UsdMotionWarning,
                      stacklevel=2)
    rest = np.swapaxes(np.array(query.ComputeJointLocalTransforms(Usd.TimeCode.Default(), True)), -1, -2)
    offsets = rest[:, :3, 3].copy()

    skel_world = np.stack([np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(skel.GetPrim())).T
                           for t in times])
    skel_q, skel_t, skel_scale = _decompose(skel_world)
    if skel_scale > 1e-4:
        warnings.warn(f"{path}: the skeleton prim's scale is ignored", UsdMotionWarning, stacklevel=2)
    rotations[:, 0] = quat_mul(skel_q, rotations[:, 0])
    translations[:, 0] = skel_t + quat_rotate(skel_q, translations[:, 0])

    moving = np.abs(translations[:, 1:] - offsets[None, 1:]).max(initial=0.0) > 1e-5 * max(
        1.0, float(np.abs(offsets).max(initial=0.0)))
    fps = float(stage.GetTimeCodesPerSecond() or 24.0)
    end_sites = np.zeros(len(names), bool)
    end_sites[[int(j) for j in custom.get("endSites", []) if 0 <= int(j) < len(names)]] = True
    channels = custom.get("channels")
    channels = tuple(tuple(c.split()) for c in channels) if channels is not None and len(channels) == len(names) else None
    return Motion(
        joint_names=names,
        parents=parents,
        offsets=offsets,
        rotations=rotations,
        root_translation=translations[:, 0],
        fps=fps,
        joint_translations=translations if moving else None,
        end_sites=end_sites,
        meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
        up_axis="Z" if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z else "Y",
        channels=channels,
        root_offset="add" if custom.get("rootOffset") == "add" else "replace",
    )


def _joint_names(skel, tokens: list[str], custom: dict) -> tuple[str, ...]:
    stored = custom.get("jointNames")
    if stored is not None and len(stored) == len(tokens) and len(set(stored)) == len(stored):
        return tuple(str(n) for n in stored)
    names_attr = skel.GetJointNamesAttr().Get()
    if names_attr is not None and len(names_attr) == len(tokens) and len(set(names_attr)) == len(names_attr):
        return tuple(str(n) for n in names_attr)
    leaves = [t.rsplit("/", 1)[-1] for t in tokens]
    if len(set(leaves)) == len(leaves):
        return tuple(leaves)
    return tuple(tokens)

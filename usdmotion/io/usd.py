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
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError, UsdMotionWarning, UsdReadError
from usdmotion.io.atomic import atomic_output
from usdmotion.io.usd_ar import ar_quick_look_problems, finish_stage
from usdmotion.io.usd_check import check_skeleton_layer
from usdmotion.io.usd_read import read_usd_skeleton
from usdmotion.io.usd_schema import define_prim, schema_attribute, schema_relationship
from usdmotion.io.usd_skin import add_skinned_meshes
from usdmotion.kinematics import compose_transforms, position_bounds, rest_pose
from usdmotion.motion import Motion
from usdmotion.usd_diagnostics import usd_error_message

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


@dataclass
class FrameSamples:
    """A take's animation as the USD writer needs it, chunk by chunk in frame order.

    Attributes:
        n_frames: ``F``.
        chunks: ``(translations, rotations xyzw (n, J, 4))`` float32 per chunk of ``n``
            frames (see :func:`float32_samples`): ``translations`` is ``(n, J, 3)``, or
            ``(n, 3)`` root positions when every other joint sits at its offset.
        blend_shape_weights: ``(F, S)`` or ``None``.
    """

    n_frames: int
    chunks: Iterable[tuple[np.ndarray, np.ndarray]]
    blend_shape_weights: np.ndarray | None = None

    @classmethod
    def of(cls, motion: Motion, made_now: bool = False) -> FrameSamples:
        """``motion``'s samples: made a chunk at a time while they are written, or with
        ``made_now`` all at once, each chunk let go once written (:func:`_drained`), so the
        motion's float64 arrays can be freed before the writing starts."""
        chunks = (float32_samples(motion, start, start + _CHUNK_FRAMES)
                  for start in range(0, motion.n_frames, _CHUNK_FRAMES))
        return cls(motion.n_frames, _drained(list(chunks)) if made_now else chunks, motion.blend_shape_weights)


def _drained(items: list) -> Iterator:
    """Yield ``items`` in order, removing each from the list (nothing else keeps it)."""
    items.reverse()
    while items:
        yield items.pop()


def define_skeleton(layer, motion: Motion, root_path: str, frames: FrameSamples | None = None):
    """Author SkelRoot, Skeleton and SkelAnimation for ``motion`` under ``root_path`` in ``layer``.

    ``frames``: the animation's samples when ``motion`` no longer holds them (only its
    skeleton is read then; see :func:`write_usd`); default: ``FrameSamples.of(motion)``.
    Returns the Skeleton's ``Sdf.PrimSpec``. Authored into the ``Sdf.Layer`` as
    ``Usd.Stage`` and the ``UsdSkel``/``UsdGeom`` schema classes author it
    (:mod:`usdmotion.io.usd_schema`): the same layer, without importing ``pxr.Usd``.
    """
    from pxr import Sdf, Vt

    types = Sdf.ValueTypeNames
    root = define_prim(layer, root_path, "SkelRoot")
    layer.defaultPrim = root.name                                                 # stage.SetDefaultPrim
    layer.pseudoRoot.SetInfo("upAxis", "Y" if motion.up_axis == "Y" else "Z")     # UsdGeom.SetStageUpAxis
    layer.pseudoRoot.SetInfo("metersPerUnit", motion.meters_per_unit)             # UsdGeom.SetStageMetersPerUnit
    layer.timeCodesPerSecond = motion.fps
    layer.framesPerSecond = motion.fps
    frames = FrameSamples.of(motion) if frames is None else frames
    layer.startTimeCode = 0
    layer.endTimeCode = max(frames.n_frames - 1, 0)

    tokens = Vt.TokenArray(joint_path_tokens(motion.joint_names, motion.parents))
    skel = define_prim(layer, f"{root_path}/Skeleton", "Skeleton")
    schema_attribute(skel, "joints", types.TokenArray, tokens, uniform=True)
    schema_attribute(skel, "jointNames", types.TokenArray, Vt.TokenArray(list(motion.joint_names)), uniform=True)
    rest_local, rest_world = _rest_transforms(motion)
    schema_attribute(skel, "restTransforms", types.Matrix4dArray, _usd_matrices(rest_local), uniform=True)
    schema_attribute(skel, "bindTransforms", types.Matrix4dArray, _usd_matrices(rest_world), uniform=True)
    custom = {
        "jointNames": Vt.StringArray(list(motion.joint_names)),
        "endSites": Vt.IntArray([int(j) for j in np.flatnonzero(motion.end_sites)]),
        "rootOffset": motion.root_offset,
    }
    if motion.channels is not None:
        custom["channels"] = Vt.StringArray([" ".join(c) for c in motion.channels])
    skel.SetInfo("customData", {CUSTOM_KEY: custom})                             # prim.SetCustomDataByKey

    anim = define_prim(layer, f"{root_path}/Animation", "SkelAnimation")
    schema_attribute(anim, "joints", types.TokenArray, tokens, uniform=True)
    scales = Vt.Vec3hArray.FromNumpy(np.ones((motion.n_joints, 3), np.float16))
    schema_attribute(anim, "scales", types.Half3Array, scales)
    translations_attr = schema_attribute(anim, "translations", types.Float3Array)
    rotations_attr = schema_attribute(anim, "rotations", types.QuatfArray)
    skel.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))  # UsdSkel.BindingAPI.Apply
    schema_relationship(skel, "skel:animationSource", [anim.path])

    weights_path = None
    if frames.blend_shape_weights is not None:
        schema_attribute(anim, "blendShapes", types.TokenArray, Vt.TokenArray(list(motion.blend_shape_names)),
                         uniform=True)
        weights_path = schema_attribute(anim, "blendShapeWeights", types.FloatArray).path
    t_path, r_path = translations_attr.path, rotations_attr.path
    offsets = motion.offsets.astype(np.float32)
    if frames.n_frames == 0:
        translations_attr.default = Vt.Vec3fArray.FromNumpy(offsets)
        rotations_attr.default = Vt.QuatfArray.FromNumpy(np.tile(np.float32([0, 0, 0, 1]), (motion.n_joints, 1)))
    set_sample, vec3f, quatf = layer.SetTimeSample, Vt.Vec3fArray.FromNumpy, Vt.QuatfArray.FromNumpy
    with Sdf.ChangeBlock():
        start = 0
        for translations, rotations in frames.chunks:
            if translations.ndim == 2:  # root positions: every other joint at its offset
                root, translations = translations, np.empty(rotations.shape[:2] + (3,), np.float32)
                translations[:] = offsets
                translations[:, 0] = root
            for k, (t, r) in enumerate(zip(translations, rotations), start):  # one time sample per frame:
                set_sample(t_path, float(k), vec3f(t))                          # the USD API's unit
                set_sample(r_path, float(k), quatf(r))
            start += len(rotations)
        if weights_path is not None:
            weights = frames.blend_shape_weights.astype(np.float32)
            for k, w in enumerate(weights):
                set_sample(weights_path, float(k), Vt.FloatArray.FromNumpy(w))
    return skel


#: Frames converted to float32 at a time while writing (bounds the temporary copies).
_CHUNK_FRAMES = 4096


def float32_samples(motion: Motion, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """``(translations, rotations xyzw (n, J, 4))`` float32 of frames ``start:stop``:
    ``translations`` ``(n, J, 3)`` when joints other than the root move, else the root's
    ``(n, 3)`` (the others sit at their offsets)."""
    stop = min(stop, motion.n_frames)
    if motion.joint_translations is not None:
        translations = motion.joint_translations[start:stop].astype(np.float32)
        translations[:, 0] = motion.root_translation[start:stop]
    else:
        translations = motion.root_translation[start:stop].astype(np.float32)
    wxyz = motion.rotations[start:stop]
    rotations = np.empty(wxyz.shape, np.float32)  # wxyz → xyzw and float32 in one pass (same values)
    rotations[..., :3] = wxyz[..., 1:]
    rotations[..., 3] = wxyz[..., 0]
    return translations, rotations


def write_usd(motion: Motion | list[Motion], path: str | os.PathLike, name: str | None = None,
              decorate=None, validate: bool = False) -> Path:
    """Write ``motion`` as a UsdSkel stage (``.usda``, ``.usdc``, ``.usd`` or ``.usdz``).

    Args:
        motion: the motion, or a one-item list handing it over: the writer takes it out,
            makes its float32 samples and bounds, and keeps only its skeleton, so the
            take's float64 arrays are freed (when the list held the caller's last
            reference) before the samples fill the USD layer. A long take's peak memory is
            then the layer plus the samples, not the layer plus the motion
            (``benchmarks/huge_inputs.py``). The file is the same either way.
        path: output file; the extension picks the format. Written atomically.
        name: SkelRoot prim name (default: the file stem, made a valid identifier).
        decorate: optional ``callable(stage, skeleton)`` that adds prims (e.g. a skinned
            mesh) before the stage is saved.
        validate: also run every ``pxr.UsdValidation`` validator on the written file
            (:func:`validate_stage`) before it replaces ``path``; an error raises
            ``OutputError`` and nothing is written. Without it, the layer's UsdSkel layout
            is still checked (:func:`usdmotion.io.usd_check.check_skeleton_layer`, no ``pxr.Usd``
            import); the suite validates every kind of stage the writer makes.

    The layer is authored through ``Sdf`` (:mod:`usdmotion.io.usd_schema`); a ``Usd.Stage``
    is opened on it only to add meshes.
    """
    from pxr import Sdf

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in USD_EXTENSIONS:
        raise OutputError(f"{path}: unknown USD extension {ext!r} (use {', '.join(USD_EXTENSIONS)})")
    handed_over = isinstance(motion, list)
    motion = motion.pop() if handed_over else motion
    _check_float32(motion, path)
    root_path = "/" + _stage_name(path, name)
    frames = FrameSamples.of(motion, made_now=handed_over)
    n_frames = motion.n_frames
    bounds = position_bounds(motion) if n_frames else None
    if handed_over:
        motion = motion.sliced(0, 0)  # the skeleton: the take's arrays go with the caller's last reference
    with atomic_output(path) as tmp:
        layer_path = tmp
        scratch = None
        if ext == ".usdz":
            scratch = Path(tempfile.mkdtemp(prefix="usdmotion-"))
            layer_path = scratch / (path.stem + ".usdc")
        try:
            layer = Sdf.Layer.CreateNew(str(layer_path))
            skel_path = define_skeleton(layer, motion, root_path, frames).path
            stage = None
            if motion.meshes or decorate is not None:
                from pxr import Usd, UsdSkel  # meshes only (start-up, see define_skeleton)

                stage = Usd.Stage.Open(layer)
                skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath(skel_path))
                if motion.meshes:
                    add_skinned_meshes(stage, skeleton, motion, path)
                if decorate is not None:
                    decorate(stage, skeleton)

            finish_stage(layer, root_path, motion, bounds, stage)
            check_skeleton_layer(layer, root_path, motion.n_joints, n_frames, path)
            if not layer.Save():  # e.g. the disk full: USD says why on stderr and returns False
                raise OutputError(f"{path}: cannot write: USD could not save the layer; nothing written")
            del stage, layer
            if ext == ".usdz":
                from pxr import UsdUtils  # only here: UsdUtils imports UsdShade, Sdr, ... (~0.03 s)

                if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(layer_path)), str(tmp)):
                    raise OutputError(f"{path}: usdz packaging failed")
            if validate:
                problems = validate_stage(str(tmp))
                if problems:
                    raise OutputError(f"{path}: the written stage fails pxr.UsdValidation: {problems[0]}"
                                      f"{f' (and {len(problems) - 1} more)' if len(problems) > 1 else ''}; "
                                      "nothing written")
        finally:
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
    if ext == ".usdz":
        _warn_unless_ar_ready(path)
    return path


def _check_float32(motion: Motion, path: Path) -> None:
    """Refuse translations that USD's float32 samples cannot hold (they would become inf)."""
    limit = float(np.finfo(np.float32).max)
    for name, a in (("joint offsets", motion.offsets), ("root translation", motion.root_translation),
                    ("joint translations", motion.joint_translations)):
        if a is not None and a.size and not -limit <= a.min() <= a.max() <= limit:
            raise OutputError(f"{path}: {name} hold values beyond USD's float32 range (±{limit:.3g}) or NaN; "
                              "nothing written")


def _warn_unless_ar_ready(path: Path) -> None:
    import warnings

    problems = ar_quick_look_problems(path)
    if problems:
        warnings.warn(f"{path}: not AR Quick Look compliant: {'; '.join(problems[:3])}"
                      f"{' …' if len(problems) > 3 else ''}", UsdMotionWarning, stacklevel=3)


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


def read_usd(path: str | os.PathLike, skeleton: str | None = None, resample: bool = False) -> Motion:
    """Read one UsdSkel skeleton of a stage (ours or a DCC tool's) into a :class:`Motion`.

    Joint world positions equal usd-core's ``ComputeJointWorldTransforms`` (ancestor
    transforms, uniform scale included, fold into the root); the frame rate comes from
    the sample spacing and ``timeCodesPerSecond``. ``skeleton``: the Skeleton prim path
    when the stage has several; ``resample``: read unevenly spaced samples at even steps.
    Positions are in stage units. See :mod:`usdmotion.io.usd_read`.
    """
    path = Path(path)
    return read_usd_skeleton(_open_stage(path), path, skeleton=skeleton, resample=resample)

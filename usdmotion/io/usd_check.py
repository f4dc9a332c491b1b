"""A structural check of the UsdSkel layer :func:`usdmotion.io.usd.write_usd` authors, run on
every write before the file is saved (no ``pxr.Usd`` import: ``Sdf`` only, well under 1 ms).

It checks what ``pxr.UsdValidation``'s validators check of this layout (stage metadata, the
``SkelBindingAPI`` applied on the Skeleton under its SkelRoot) and what they cannot (every
joint array of one length, one time sample per frame, a finite extent). A violation is a bug
in the writer: it raises ``OutputError`` and nothing is written, so an invalid stage never
exits 0. The full validators run behind ``convert --validate`` and on every kind of stage
the writer makes in the test suite (``tests/test_usd.py``, ``tests/test_usd_check.py``).
"""

from __future__ import annotations

import math
import os

from usdmotion.errors import OutputError


def skeleton_layer_problems(layer, root_path: str, n_joints: int, n_frames: int) -> list[str]:
    """What is wrong with the SkelRoot ``root_path`` of ``layer`` (an ``Sdf.Layer``) for a skeleton
    of ``n_joints`` joints and ``n_frames`` frames; empty when nothing is."""
    pseudo = layer.pseudoRoot
    root = layer.GetPrimAtPath(root_path)
    skel = layer.GetPrimAtPath(f"{root_path}/Skeleton")
    anim = layer.GetPrimAtPath(f"{root_path}/Animation")
    if not (root and skel and anim):
        return [f"{root_path}, its Skeleton and Animation must all be defined"]
    problems = []
    if layer.defaultPrim != root.name or root.typeName != "SkelRoot":
        problems.append(f"defaultPrim {layer.defaultPrim!r} is not the SkelRoot {root.name!r}")
    if pseudo.GetInfo("upAxis") not in ("Y", "Z"):
        problems.append(f"upAxis {pseudo.GetInfo('upAxis')!r} is neither Y nor Z")
    for key in ("metersPerUnit", "timeCodesPerSecond", "framesPerSecond"):
        if not (pseudo.HasInfo(key) and math.isfinite(pseudo.GetInfo(key)) and pseudo.GetInfo(key) > 0):
            problems.append(f"{key} is not a positive number")
    if (layer.startTimeCode, layer.endTimeCode) != (0, max(n_frames - 1, 0)):
        problems.append(f"time codes {layer.startTimeCode}–{layer.endTimeCode} for {n_frames} frames")
    if (skel.typeName, anim.typeName) != ("Skeleton", "SkelAnimation"):
        problems.append(f"prim types {skel.typeName}, {anim.typeName}")
    if "SkelBindingAPI" not in skel.GetInfo("apiSchemas").GetAddedOrExplicitItems():
        problems.append("the Skeleton has skel: properties without SkelBindingAPI")
    source = skel.relationships.get("skel:animationSource")
    if source is None or list(source.targetPathList.explicitItems) != [anim.path]:
        problems.append("skel:animationSource does not target the Animation")
    joints = _default(skel, "joints")
    if joints is None or len(joints) != n_joints or len(set(joints)) != n_joints:
        problems.append(f"the Skeleton's joints are not {n_joints} distinct paths")
    for prim, name in ((skel, "jointNames"), (skel, "restTransforms"), (skel, "bindTransforms"), (anim, "scales")):
        value = _default(prim, name)
        if value is None or len(value) != n_joints:
            problems.append(f"{prim.name}.{name} does not hold {n_joints} values")
    if list(_default(anim, "joints") or ()) != list(joints or ()):
        problems.append("the Animation's joints differ from the Skeleton's")
    for name in ("translations", "rotations"):
        path = anim.path.AppendProperty(name)
        samples = layer.GetNumTimeSamplesForPath(path)
        if samples != n_frames or (not n_frames and len(_default(anim, name) or ()) != n_joints):
            problems.append(f"Animation.{name} has {samples} time samples for {n_frames} frames")
    extent = _default(root, "extent")
    if extent is None or len(extent) != 2 or not all(
            math.isfinite(lo) and lo <= hi for lo, hi in zip(extent[0], extent[1])):
        problems.append(f"extent {extent} is not a finite box")
    return problems


def check_skeleton_layer(layer, root_path: str, n_joints: int, n_frames: int, path: str | os.PathLike) -> None:
    """Raise ``OutputError`` for the first of :func:`skeleton_layer_problems` (output ``path``)."""
    problems = skeleton_layer_problems(layer, root_path, n_joints, n_frames)
    if problems:
        raise OutputError(f"{path}: internal error: the stage written is not valid UsdSkel ({problems[0]}); "
                          "nothing written")


def _default(prim, name: str):
    attr = prim.attributes.get(name)
    return attr.default if attr is not None and attr.HasInfo("default") else None

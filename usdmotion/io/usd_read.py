"""Reading a UsdSkel stage, as usdmotion or a DCC tool authored it, into a :class:`Motion`.

Data flow: stage → chosen ``Skeleton`` (:func:`choose_skeleton`) → topology and rest
transforms → the bound ``SkelAnimation``'s arrays read in bulk over every time sample
(:mod:`usdmotion.io.usd_samples`) → the skeleton prim's world transform folded into the
root joints (:func:`fold_skeleton_transform`) → several root joints made one
(:func:`merge_roots`) → ``Motion``.

What DCC tools author and how it is read:

* **Ancestor transforms.** Translations, rotations and a *uniform* scale of the
  Skeleton prim and its ancestors (Blender's ``convert_scene_units``, a scaled armature
  object, Maya centimetre rigs) fold exactly into the root and the offsets, so joint
  positions equal usd-core's ``ComputeJointWorldTransforms``. A non-uniform, mirroring
  or sheared ancestor transform cannot be expressed by a ``Motion`` and is refused.
* **Time.** Frames are the animation's time samples in stage time (layer offsets and
  scales of references, and the ``timeCodesPerSecond`` conversion of a referenced
  layer, already applied by USD); fps = ``timeCodesPerSecond`` / sample spacing. Uneven
  spacing is refused unless ``resample=True`` (then USD's own interpolation is sampled
  at the median spacing).
* **Several skeletons.** Without ``skeleton=`` a stage with more than one is refused
  with the list of prim paths; ``skeleton=`` takes a prim path (or an unambiguous name).
* **Several root joints.** The root with the largest subtree (the hips chain) becomes
  joint 0; every other root becomes its child, its local transform recomputed from
  world transforms per frame, so every joint keeps its world position.
* **Validation.** Every array read is checked for its length (one value per animated
  joint), finiteness and, for rotations, unit length; a failure names the file, the
  prim, the attribute and the time code. An animation without rotations or
  translations is refused (usd-core would silently show the rest pose); one without
  scales is read as scale 1.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from usdmotion.channels import trusted_layout
from usdmotion.errors import UsdMotionWarning, UsdReadError
from usdmotion.io.usd_samples import animation_arrays, blend_shape_weights, frame_times, stage_rate
from usdmotion.io.usd_skin import read_skinned_meshes
from usdmotion.motion import Motion
from usdmotion.rotations import quat_conjugate, quat_mul, quat_rotate

CUSTOM_KEY = "usdmotion"
SCALE_TOL = 1e-5        # relative: ancestor scales this close count as uniform
ORTHO_TOL = 1e-4        # an ancestor's scale-free 3×3 this far from a rotation is a shear
JOINT_SCALE_TOL = 1e-4  # joint scales this far from 1 are reported as ignored


def list_skeletons(stage) -> list[str]:
    """Prim paths of every ``UsdSkel.Skeleton`` in ``stage``, in traversal order."""
    from pxr import UsdSkel

    return [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)]


def choose_skeleton(stage, path: Path, skeleton: str | None = None):
    """The ``UsdSkel.Skeleton`` to read: the only one, or the one ``skeleton`` names.

    ``skeleton`` is a prim path (``/Root/Armature/Skel``) or a prim name that only one
    skeleton has. Several skeletons and no choice is an error listing them.
    """
    from pxr import UsdSkel

    paths = list_skeletons(stage)
    if not paths:
        raise UsdReadError(path, "no UsdSkel Skeleton in the stage")
    if skeleton is None:
        if len(paths) > 1:
            raise UsdReadError(path, f"{len(paths)} skeletons in the stage ({', '.join(paths)}); "
                                     "choose one with --skeleton PRIM_PATH")
        return UsdSkel.Skeleton(stage.GetPrimAtPath(paths[0]))
    matches = [p for p in paths if p == skeleton.rstrip("/") or p.rsplit("/", 1)[-1] == skeleton]
    if len(matches) != 1:
        why = "matches several" if matches else "is not one of"
        raise UsdReadError(path, f"--skeleton {skeleton} {why} the stage's skeletons ({', '.join(paths)})")
    return UsdSkel.Skeleton(stage.GetPrimAtPath(matches[0]))


def decompose(local: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column-vector ``(N, 4, 4)`` → ``(rotation wxyz (N, 4), translation (N, 3), scale (N, 3))``:
    rotation and scale by usd-core's ``UsdSkel.DecomposeTransforms`` (the decomposition
    UsdSkel itself uses; float32), translation exactly from the matrices."""
    from pxr import UsdSkel, Vt

    matrices = Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.swapaxes(local, -1, -2)))
    result = UsdSkel.DecomposeTransforms(matrices)
    if not result:
        raise ValueError("transforms cannot be decomposed")
    _, rotations, scales = result
    xyzw = np.array(rotations, np.float64).reshape(-1, 4)
    wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    wxyz /= np.linalg.norm(wxyz, axis=1, keepdims=True)
    return wxyz, local[:, :3, 3].copy(), np.array(scales, np.float64).reshape(-1, 3)


def uniform_scale(world: np.ndarray, path: Path, prim) -> np.ndarray:
    """Per-time uniform scale ``(T,)`` of column-vector world transforms ``(T, 4, 4)`` of ``prim``.

    Raises :class:`UsdReadError` for a non-uniform, zero, mirroring or shearing transform:
    a ``Motion`` has one length unit and rigid joints.
    """
    linear = world[:, :3, :3]
    scale = np.linalg.norm(linear, axis=-2)
    s = scale.mean(axis=-1)
    if not np.all(np.isfinite(linear)) or np.any(s <= 0):
        raise UsdReadError(path, f"{prim.GetPath()}: its world transform is degenerate (zero or non-finite scale)")
    spread = float(np.max((scale.max(axis=-1) - scale.min(axis=-1)) / s))
    if spread > SCALE_TOL:
        raise UsdReadError(path, f"{prim.GetPath()}: non-uniform scale {np.round(scale[0], 6).tolist()} above the "
                                 "skeleton is not supported (a motion has one length unit); "
                                 "apply the scale to the rig in the DCC tool first")
    rotation = linear / s[:, None, None]
    gram_error = np.abs(np.swapaxes(rotation, -1, -2) @ rotation - np.eye(3)).max()
    if gram_error > ORTHO_TOL or np.any(np.linalg.det(rotation) < 0):
        raise UsdReadError(path, f"{prim.GetPath()}: its world transform shears or mirrors the skeleton, "
                                 "which a motion cannot express")
    return s


def skeleton_world(skel, times: np.ndarray) -> np.ndarray:
    """Column-vector world transform of the Skeleton prim, ``(T, 4, 4)``, at stage ``times``
    (computed once when no ancestor transform is time-varying)."""
    from pxr import Usd, UsdGeom

    prim = skel.GetPrim()
    varying = False
    p = prim
    while p and not p.IsPseudoRoot():
        if p.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(p).TransformMightBeTimeVarying():
            varying = True
            break
        p = p.GetParent()
    codes = times if varying and len(times) else times[:1]
    codes = [Usd.TimeCode(float(t)) for t in codes] if len(codes) else [Usd.TimeCode.Default()]
    world = np.stack([np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(prim)).T for t in codes])
    return world if len(world) == max(len(times), 1) else np.broadcast_to(world, (max(len(times), 1), 4, 4))


def fold_skeleton_transform(world: np.ndarray, rotations: np.ndarray, translations: np.ndarray,
                            offsets: np.ndarray, roots: np.ndarray, path: Path, prim):
    """Fold the Skeleton prim's world transform ``(T, 4, 4)`` into the joints.

    ``rotations (T, J, 4)`` wxyz and ``translations (T, J, 3)`` (float32 or float64) are local
    (skeleton space); ``offsets (J, 3)`` rest translations. A uniform scale ``s`` multiplies
    every translation and offset; the rotation and translation apply to the ``roots``.
    Returns new arrays (float64 translations), or the same when ``world`` is the identity.
    ``world`` may be one transform broadcast over the frames (stride 0): it is checked once.
    """
    world = world[:1] if world.strides[0] == 0 else world  # one transform broadcast over the frames
    s = uniform_scale(world, path, prim)
    if np.allclose(world, np.eye(4), rtol=0, atol=1e-12):
        return rotations, translations, offsets
    q_world = decompose(np.ascontiguousarray(world))[0]
    translations = translations * s[:, None, None] if not np.all(s == 1.0) else translations.astype(np.float64)
    rotations[:, roots] = quat_mul(q_world[:, None], rotations[:, roots])
    translations[:, roots] = world[:, None, :3, 3] + quat_rotate(q_world[:, None], translations[:, roots])
    return rotations, translations, offsets * s[0]


def merge_roots(parents: np.ndarray, rotations: np.ndarray, translations: np.ndarray, offsets: np.ndarray,
                rest_rotations: np.ndarray):
    """Make a skeleton with several root joints single-rooted, keeping world transforms.

    The root with the most descendants becomes joint 0; the other roots become its
    children: ``q_local = q_main⁻¹ q_root``, ``t_local = q_main⁻¹ (t_root - t_main)`` per
    frame, and their offsets likewise from the rest transforms (``rest_rotations (J, 4)``).

    Returns ``(order (J,), parents, rotations, translations, offsets)`` with joints
    reordered by ``order`` (old indices), parents before children.
    """
    roots = np.flatnonzero(parents < 0)
    counts = np.ones(parents.size, np.int64)
    for j in range(parents.size - 1, 0, -1):   # topology pass over joints, not frames
        if parents[j] >= 0:
            counts[parents[j]] += counts[j]
    main = int(roots[np.argmax(counts[roots])])
    extra = roots[roots != main]
    rotations, translations, offsets = rotations.copy(), translations.copy(), offsets.copy()
    q_inv = quat_conjugate(rotations[:, main:main + 1])
    translations[:, extra] = quat_rotate(q_inv, translations[:, extra] - translations[:, main:main + 1])
    rotations[:, extra] = quat_mul(q_inv, rotations[:, extra])
    rest_inv = quat_conjugate(rest_rotations[main])
    offsets[extra] = quat_rotate(rest_inv, offsets[extra] - offsets[main])
    order = np.concatenate([[main], np.delete(np.arange(parents.size), main)])
    new_index = np.empty_like(order)
    new_index[order] = np.arange(order.size)
    old_parents = parents[order]
    new_parents = np.where(old_parents >= 0, new_index[np.maximum(old_parents, 0)], 0)
    new_parents[0] = -1
    return order, new_parents, rotations[:, order], translations[:, order], offsets[order]


def read_usd_skeleton(stage, path: Path, skeleton: str | None = None, resample: bool = False) -> Motion:
    """Read one skeleton of an open ``stage`` (see the module docstring) into a ``Motion``
    in stage units (``meters_per_unit``, ``up_axis`` from the stage)."""
    from pxr import UsdGeom, UsdSkel

    skel = choose_skeleton(stage, path, skeleton)
    where = skel.GetPath()
    query, parents, tokens = skeleton_topology(skel, path)
    rest = rest_transforms(skel, len(tokens), path)
    rest_q, offsets, _ = decompose(rest)

    tcps = stage_rate(stage, path)
    anim_query = query.GetAnimQuery()
    anim = UsdSkel.Animation(anim_query.GetPrim()) if anim_query else None
    times, step = frame_times(anim, path, resample)
    rotations, translations = animation_arrays(anim, tokens, times, rest_q, offsets, path)
    shape_names, shape_weights = blend_shape_weights(anim, times, path)
    roots = np.flatnonzero(parents < 0)
    rotations, translations, offsets = fold_skeleton_transform(
        skeleton_world(skel, times), rotations, translations, offsets, roots, path, skel.GetPrim())

    custom = dict(skel.GetPrim().GetCustomDataByKey(CUSTOM_KEY) or {})
    names = np.array(joint_names(skel, tokens, custom), dtype=object)
    end_sites, channels = trusted_layout(custom, parents, path, where)
    if roots.size > 1:
        translations = translations.astype(np.float64, copy=False)
        order, parents, rotations, translations, offsets = merge_roots(parents, rotations, translations, offsets, rest_q)
        names, end_sites, channels = names[order], end_sites[order], None
        warnings.warn(f"{path}: skeleton {where} has {roots.size} root joints; {names[0]} is the root and "
                      f"{', '.join(str(n) for n in names[1:][parents[1:] == 0][:5])}… become its children "
                      "(world positions kept)", UsdMotionWarning, stacklevel=3)
    names = tuple(str(n) for n in names)
    meshes = _meshes(skel, query, tokens, names, order if roots.size > 1 else None, offsets, times)
    moving = _joints_move(translations, offsets)
    root_translation = translations[:, 0].astype(np.float64)
    translations = translations.astype(np.float64, copy=False) if moving else None
    for owned in (rotations, root_translation, translations):  # handed over to the Motion without a copy
        if owned is not None:
            owned.setflags(write=False)
    return Motion(
        joint_names=names,
        parents=parents,
        offsets=offsets,
        rotations=rotations,
        root_translation=root_translation,
        fps=tcps / step,
        joint_translations=translations,
        end_sites=end_sites,
        meters_per_unit=stage_meters_per_unit(stage, path),
        up_axis="Z" if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z else "Y",
        channels=channels,
        root_offset="add" if custom.get("rootOffset") == "add" else "replace",
        meshes=meshes,
        blend_shape_names=shape_names,
        blend_shape_weights=shape_weights,
    )


def _joints_move(translations: np.ndarray, offsets: np.ndarray) -> bool:
    """Whether a non-root joint's translation ``(T, J, 3)`` leaves its offset ``(J, 3)`` by more
    than ``1e-5`` of the largest offset (or 1): from the per-joint extremes over the frames,
    no temporary of the take's size (``max |t - o|`` is ``max(max t - o, o - min t)``)."""
    if translations.shape[0] == 0 or translations.shape[1] < 2:
        return False
    rest = offsets[1:]
    high, low = translations[:, 1:].max(axis=0), translations[:, 1:].min(axis=0)
    drift = max(float(np.abs(high - rest).max()), float(np.abs(low - rest).max()))
    return drift > 1e-5 * max(1.0, float(np.abs(offsets).max(initial=0.0)))


def _meshes(skel, query, tokens, names, order, offsets, times):
    """The skinned meshes bound to ``skel`` in the Motion's space (:mod:`usdmotion.io.usd_skin`)."""
    by_token = dict(zip([tokens[i] for i in order] if order is not None else tokens, names))
    ancestor_row = skeleton_world(skel, times[:1])[0].T
    return read_skinned_meshes(skel, query, by_token, dict(zip(names, offsets)), ancestor_row)


def skeleton_topology(skel, path: Path):
    """``(UsdSkel.SkeletonQuery, parents (J,) int64, joint path tokens)``, validated."""
    from pxr import UsdSkel

    query = UsdSkel.Cache().GetSkelQuery(skel)
    if not query:
        raise UsdReadError(path, f"skeleton {skel.GetPath()} is invalid (joints, rest transforms?)")
    topology = query.GetTopology()
    ok, reason = topology.Validate()
    if not ok:
        raise UsdReadError(path, f"skeleton {skel.GetPath()}: {reason}")
    return query, np.asarray(topology.GetParentIndices(), dtype=np.int64), [str(t) for t in query.GetJointOrder()]


def rest_transforms(skel, n_joints: int, path: Path) -> np.ndarray:
    """The Skeleton's ``restTransforms`` as column-vector ``(J, 4, 4)``, checked."""
    value = skel.GetRestTransformsAttr().Get()
    where = f"{skel.GetPath()}.restTransforms"
    if value is None or len(value) != n_joints:
        raise UsdReadError(path, f"{where} has {0 if value is None else len(value)} matrices for {n_joints} joints")
    rest = np.swapaxes(np.array(value, dtype=np.float64).reshape(n_joints, 4, 4), -1, -2)
    if not np.all(np.isfinite(rest)):
        raise UsdReadError(path, f"{where} holds non-finite values")
    _, _, scale = decompose(rest)
    if np.abs(scale - 1).max(initial=0.0) > JOINT_SCALE_TOL:
        warnings.warn(f"{path}: {where}: joint scales (up to {scale.max():.4g}) are ignored",
                      UsdMotionWarning, stacklevel=4)
    return rest


def stage_meters_per_unit(stage, path: Path) -> float:
    """The stage's ``metersPerUnit``, checked positive and finite."""
    from pxr import UsdGeom

    mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    if not (np.isfinite(mpu) and mpu > 0):
        raise UsdReadError(path, f"metersPerUnit must be a positive number, the stage says {mpu}")
    return mpu


def joint_names(skel, tokens: list[str], custom: dict) -> tuple[str, ...]:
    """Joint names: ours from customData, else ``jointNames``, else unique path leaves, else paths."""
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

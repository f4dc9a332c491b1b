"""Skinned meshes bound to a UsdSkel Skeleton, carried from a USD input to a USD output.

Read (:func:`read_skinned_meshes`): every mesh bound to the chosen skeleton, through
usd-core's ``UsdSkel.SkinningQuery`` — points, topology, normals, UVs (``primvars:st``),
display colour, joint influences (remapped to joint *names*), blend shape targets —
is expressed in the ``Motion``'s space. The reader folds the skeleton's ancestor
transform ``M`` (row-vector, time 0) into the root, so the mesh is rebased with it:
``points' = points · geomBind · M``, ``bind' = bind · M``, geomBind' = identity. For any
frame, ``points' · bind'⁻¹ · W'(t)`` with ``W'(t) = W(t) · M(t)`` equals the source's
skinned points in the world: the carried mesh deforms exactly as the input's.

Write (:func:`add_skinned_meshes`): each mesh is authored under the SkelRoot, bound to
the new Skeleton, its joints found by name; the Skeleton's ``bindTransforms`` of those
joints become the meshes' bind transforms. A mesh whose joints are missing from the
motion or whose rest offsets changed (retarget, hierarchy edits) is left out with a
warning: its weights would deform the wrong bones. Blend shape targets are kept, and their
animated weights travel in ``Motion.blend_shape_weights`` (written back on the SkelAnimation);
where an operation dropped those, that is warned about.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from usdmotion.errors import UsdMotionWarning

OFFSET_TOL = 1e-6  # relative to the skeleton's extent: rest offsets that count as unchanged


@dataclass(frozen=True, eq=False)
class BlendShape:
    name: str
    offsets: np.ndarray                 # (P, 3) point offsets, Motion space
    point_indices: np.ndarray | None    # (P,) int, or None for all points


@dataclass(frozen=True, eq=False)
class SkinnedMesh:
    """One skinned mesh in the Motion's space (positions in stage units, bind pose)."""

    name: str
    points: np.ndarray                  # (V, 3) bind-pose points
    face_vertex_counts: np.ndarray      # (Fc,) int
    face_vertex_indices: np.ndarray     # (sum counts,) int
    joint_names: tuple[str, ...]        # names the influence indices refer to
    joint_indices: np.ndarray           # (V, K) int into joint_names
    joint_weights: np.ndarray           # (V, K) float
    bind_transforms: np.ndarray         # (len(joint_names), 4, 4) column-vector world bind transforms
    rest_offsets: np.ndarray            # (len(joint_names), 3) the joints' Motion offsets when read
    normals: np.ndarray | None = None   # (N, 3)
    normals_interpolation: str = "vertex"
    uvs: np.ndarray | None = None       # (U, 2)
    uv_interpolation: str = "vertex"
    uv_indices: np.ndarray | None = None
    display_color: np.ndarray | None = None  # (3,)
    blend_shapes: tuple[BlendShape, ...] = field(default=())
    animated_blend_shapes: bool = False  # the source animated blend shape weights (not carried)


def _row(matrix) -> np.ndarray:
    return np.array(matrix, dtype=np.float64).reshape(4, 4)


def read_skinned_meshes(skel, skel_query, names_by_token: dict[str, str], offsets_by_name: dict[str, np.ndarray],
                        ancestor_row: np.ndarray) -> tuple[SkinnedMesh, ...]:
    """The meshes bound to ``skel`` (``UsdSkel.Skeleton``) as :class:`SkinnedMesh`.

    ``names_by_token``: skeleton joint path token → Motion joint name; ``offsets_by_name``:
    the Motion's offsets; ``ancestor_row``: the skeleton prim's local-to-world (row-vector
    4×4) folded into the Motion.
    """
    from pxr import Usd, UsdSkel

    root = UsdSkel.Root.Find(skel.GetPrim())
    if not root:
        return ()
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.PrimDefaultPredicate)
    skel_tokens = [str(t) for t in skel_query.GetJointOrder()]
    bind = skel.GetBindTransformsAttr().Get()
    if bind is None or len(bind) != len(skel_tokens):
        return ()
    bind_rows = np.array(bind, dtype=np.float64).reshape(-1, 4, 4)
    animated = bool(skel_query.GetAnimQuery() and skel_query.GetAnimQuery().GetBlendShapeOrder())
    meshes = []
    for binding in cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate):
        if binding.GetSkeleton().GetPrim() != skel.GetPrim():
            continue
        for query in binding.GetSkinningTargets():
            mesh = _one_mesh(query, skel_tokens, bind_rows, names_by_token, offsets_by_name, ancestor_row, animated)
            if mesh is not None:
                meshes.append(mesh)
    return tuple(meshes)


def _one_mesh(query, skel_tokens, bind_rows, names_by_token, offsets_by_name, ancestor_row, animated):
    from pxr import UsdGeom

    prim = query.GetPrim()
    if not prim.IsA(UsdGeom.Mesh):
        return None
    mesh = UsdGeom.Mesh(prim)
    points = mesh.GetPointsAttr().Get()
    influences = query.ComputeJointInfluences()
    if points is None or not influences:
        return None
    points = np.array(points, np.float64).reshape(-1, 3)
    indices, weights = (np.array(a) for a in influences)
    k = query.GetNumInfluencesPerComponent()
    if query.IsRigidlyDeformed():
        indices, weights = np.tile(indices, len(points)), np.tile(weights, len(points))
    indices, weights = indices.reshape(len(points), k), weights.reshape(len(points), k).astype(np.float64)
    order = query.GetJointOrder()
    tokens = [str(t) for t in order] if order else skel_tokens
    index_in_skel = {t: i for i, t in enumerate(skel_tokens)}
    if any(t not in index_in_skel or t not in names_by_token for t in tokens):
        return None
    counts, face_indices = mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get()
    problem = _mesh_problem(points, counts, face_indices, indices, weights, len(tokens))
    if problem:
        warnings.warn(f"{prim.GetPath()}: skinned mesh not read: {problem}", UsdMotionWarning, stacklevel=4)
        return None
    geom_bind = _row(query.GetGeomBindTransform())
    to_motion = geom_bind @ ancestor_row
    homog = np.concatenate([points, np.ones((len(points), 1))], axis=1) @ to_motion
    unscale = np.diag([1.0 / np.linalg.norm(ancestor_row[0, :3])] * 3 + [1.0])  # D⁻¹: joints carry no scale
    binds = unscale @ bind_rows[[index_in_skel[t] for t in tokens]] @ ancestor_row  # row-vector D⁻¹ · bind · M
    names = tuple(names_by_token[t] for t in tokens)
    return SkinnedMesh(
        name=prim.GetName(), points=homog[:, :3], face_vertex_counts=np.array(counts, np.int64),
        face_vertex_indices=np.array(face_indices, np.int64), joint_names=names,
        joint_indices=indices, joint_weights=weights, bind_transforms=np.swapaxes(binds, -1, -2),
        rest_offsets=np.array([offsets_by_name[n] for n in names]).reshape(-1, 3),
        **_normals(mesh, to_motion), **_uvs(mesh), display_color=_colour(mesh),
        blend_shapes=_blend_shapes(query, to_motion), animated_blend_shapes=animated)


def _mesh_problem(points, counts, face_indices, indices, weights, n_joints: int) -> str | None:
    """Why a mesh's arrays cannot be carried (``None`` if they can)."""
    if counts is None or face_indices is None:
        return "no faceVertexCounts/faceVertexIndices"
    counts, face_indices = np.array(counts, np.int64), np.array(face_indices, np.int64)
    if counts.sum() != face_indices.size or np.any(counts < 0):
        return f"faceVertexCounts sum to {counts.sum()}, faceVertexIndices has {face_indices.size}"
    if face_indices.size and (face_indices.min() < 0 or face_indices.max() >= len(points)):
        return "faceVertexIndices outside the points"
    if not np.all(np.isfinite(points)) or not np.all(np.isfinite(weights)):
        return "non-finite points or joint weights"
    if indices.size and (indices.min() < 0 or indices.max() >= n_joints):
        return "joint indices outside the joint list"
    return None


def _normals(mesh, to_motion) -> dict:
    normals = mesh.GetNormalsAttr().Get()
    if normals is None or len(normals) == 0:
        return {}
    linear = to_motion[:3, :3]
    n = np.array(normals, np.float64).reshape(-1, 3) @ np.linalg.inv(linear).T  # normals: inverse transpose
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return {"normals": n, "normals_interpolation": str(mesh.GetNormalsInterpolation())}


def _uvs(mesh) -> dict:
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("st")
    if not primvar or not primvar.HasValue():
        return {}
    indices = primvar.GetIndices() if primvar.IsIndexed() else None
    return {"uvs": np.array(primvar.Get(), np.float64).reshape(-1, 2), "uv_interpolation": str(primvar.GetInterpolation()),
            "uv_indices": None if indices is None else np.array(indices)}


def _colour(mesh):
    value = mesh.GetDisplayColorPrimvar().Get() if mesh.GetDisplayColorPrimvar() else None
    return None if value is None or len(value) == 0 else np.array(value[0], np.float64)


def _blend_shapes(query, to_motion) -> tuple[BlendShape, ...]:
    from pxr import UsdSkel

    rel = query.GetBlendShapeTargetsRel()
    order = query.GetBlendShapeOrder()
    if not rel or not order:
        return ()
    shapes = []
    for name, target in zip(order, rel.GetTargets()):
        shape = UsdSkel.BlendShape(query.GetPrim().GetStage().GetPrimAtPath(target))
        offsets = shape.GetOffsetsAttr().Get() if shape else None
        if offsets is None:
            continue
        idx = shape.GetPointIndicesAttr().Get()
        shapes.append(BlendShape(str(name), np.array(offsets, np.float64).reshape(-1, 3) @ to_motion[:3, :3],
                                 None if not idx else np.array(idx)))
    return tuple(shapes)


def usable_meshes(motion, source=None, blend_shape_warning: bool = True) -> list[SkinnedMesh]:
    """The meshes of ``motion`` whose joints still exist with their rest offsets; warns
    about each one left out and (``blend_shape_warning``) about blend shape animation
    that is not carried."""
    keep = []
    index = {n: j for j, n in enumerate(motion.joint_names)}
    scale = max(float(np.abs(motion.offsets).max(initial=0.0)), 1e-12)
    for mesh in motion.meshes:
        missing = [n for n in mesh.joint_names if n not in index]
        changed = not missing and not np.allclose(motion.offsets[[index[n] for n in mesh.joint_names]],
                                                  mesh.rest_offsets, rtol=0, atol=OFFSET_TOL * scale)
        if missing or changed:
            why = f"joints {', '.join(missing[:3])} are gone" if missing else "the skeleton's rest offsets changed"
            warnings.warn(f"{source or 'output'}: skinned mesh {mesh.name} left out: {why}, so its weights would "
                          "deform the wrong bones", UsdMotionWarning, stacklevel=3)
            continue
        if mesh.animated_blend_shapes and blend_shape_warning and motion.blend_shape_weights is None:
            warnings.warn(f"{source or 'output'}: skinned mesh {mesh.name}: its blend shapes are kept but their "
                          "animated weights are not", UsdMotionWarning, stacklevel=3)
        keep.append(mesh)
    return keep


def add_skinned_meshes(stage, skeleton, motion, source=None) -> list:
    """Author :func:`usable_meshes` of ``motion`` under ``skeleton``'s SkelRoot; returns the meshes."""
    from pxr import Gf, Sdf, UsdGeom, UsdSkel, Vt

    meshes = usable_meshes(motion, source)
    if not meshes:
        return []
    index = {n: j for j, n in enumerate(motion.joint_names)}
    bind = np.swapaxes(np.array(skeleton.GetBindTransformsAttr().Get(), np.float64).reshape(-1, 4, 4), -1, -2)
    root = skeleton.GetPrim().GetParent().GetPath()
    authored, used = [], set()
    for mesh in meshes:
        joints = np.array([index[n] for n in mesh.joint_names])
        bind[joints] = mesh.bind_transforms
        name = mesh.name if mesh.name not in used and mesh.name not in ("Skeleton", "Animation") else f"{mesh.name}_{len(used)}"
        used.add(name)
        prim = UsdGeom.Mesh.Define(stage, root.AppendChild(name))
        prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(mesh.points.astype(np.float32)))
        prim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(mesh.face_vertex_counts.astype(np.int32)))
        prim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.face_vertex_indices.astype(np.int32)))
        lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
        prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
        if mesh.normals is not None:
            prim.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(mesh.normals.astype(np.float32)))
            prim.SetNormalsInterpolation(mesh.normals_interpolation)
        if mesh.uvs is not None:
            st = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         mesh.uv_interpolation)
            st.Set(Vt.Vec2fArray.FromNumpy(mesh.uvs.astype(np.float32)))
            if mesh.uv_indices is not None:
                st.SetIndices(Vt.IntArray.FromNumpy(mesh.uv_indices.astype(np.int32)))
        if mesh.display_color is not None:
            prim.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
                Vt.Vec3fArray([Gf.Vec3f(*map(float, mesh.display_color))]))
        binding = UsdSkel.BindingAPI.Apply(prim.GetPrim())
        binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
        k = mesh.joint_indices.shape[1]
        binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray.FromNumpy(joints[mesh.joint_indices].reshape(-1)
                                                                              .astype(np.int32)))
        binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray.FromNumpy(mesh.joint_weights.reshape(-1)
                                                                                .astype(np.float32)))
        binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
        _author_blend_shapes(stage, prim, binding, mesh)
        authored.append(prim)
    skeleton.GetBindTransformsAttr().Set(Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.swapaxes(bind, -1, -2))))
    return authored


def _author_blend_shapes(stage, prim, binding, mesh: SkinnedMesh) -> None:
    from pxr import UsdSkel, Vt

    if not mesh.blend_shapes:
        return
    targets = []
    for shape in mesh.blend_shapes:
        target = UsdSkel.BlendShape.Define(stage, prim.GetPath().AppendChild(shape.name))
        target.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(shape.offsets.astype(np.float32)))
        if shape.point_indices is not None:
            target.CreatePointIndicesAttr(Vt.IntArray.FromNumpy(shape.point_indices.astype(np.int32)))
        targets.append(target.GetPath())
    binding.CreateBlendShapesAttr(Vt.TokenArray([s.name for s in mesh.blend_shapes]))
    binding.CreateBlendShapeTargetsRel().SetTargets(targets)

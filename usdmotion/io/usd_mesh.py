"""A skinned body ``Mesh`` bound to a UsdSkel ``Skeleton`` (``usdmotion convert --mesh``).

Layout added under the SkelRoot written by :func:`usdmotion.io.usd.write_usd`::

    /<Name>/Body    Mesh, SkelBindingAPI
        points, faceVertexCounts, faceVertexIndices, normals (vertex), extent: bind pose
        primvars:skel:jointIndices  int[]   (vertex, elementSize 4)
        primvars:skel:jointWeights  float[] (vertex, elementSize 4, rows sum to 1)
        primvars:skel:geomBindTransform = identity (points are in skeleton space)
        rel skel:skeleton = </<Name>/Skeleton>

The Skeleton's ``bindTransforms`` are set to the body's bind pose (the rest pose, or
the frame :func:`usdmotion.skin.bind_pose` chose), so UsdSkel's linear blend skinning
— ``points · geomBindTransform · bindTransform⁻¹ · jointWorldTransform`` — is exactly
:func:`usdmotion.skin.lbs`.
"""

from __future__ import annotations

import numpy as np

from usdmotion.io.usd import _usd_matrices
from usdmotion.skin import INFLUENCES, Body


def add_body_mesh(stage, skeleton, body: Body, name: str = "Body", color=(0.80, 0.62, 0.52)):
    """Author ``body`` as a skinned ``UsdGeom.Mesh`` beside ``skeleton``; returns the mesh."""
    from pxr import Gf, UsdGeom, UsdSkel, Vt

    root = skeleton.GetPrim().GetParent().GetPath()
    mesh = UsdGeom.Mesh.Define(stage, root.AppendChild(name))
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(body.vertices.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(body.faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(body.faces.reshape(-1).astype(np.int32)))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(body.normals.astype(np.float32)))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    lo, hi = body.vertices.min(axis=0), body.vertices.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(*color)]))

    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    binding.CreateJointIndicesPrimvar(False, INFLUENCES).Set(
        Vt.IntArray.FromNumpy(body.joint_indices.reshape(-1).astype(np.int32)))
    binding.CreateJointWeightsPrimvar(False, INFLUENCES).Set(
        Vt.FloatArray.FromNumpy(body.joint_weights.reshape(-1).astype(np.float32)))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    skeleton.GetBindTransformsAttr().Set(_usd_matrices(body.bind_transforms))
    mesh.GetPrim().SetCustomDataByKey("usdmotion", {"body": "usdmotion.skin.build_body", "size": body.size})
    return mesh


def body_decorator(body: Body):
    """A ``decorate(stage, skeleton)`` callable for :func:`usdmotion.io.usd.write_usd`."""

    def decorate(stage, skeleton):
        add_body_mesh(stage, skeleton, body)

    return decorate

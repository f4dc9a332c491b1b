"""What DCC tools and AR viewers expect of a written stage, and AR Quick Look's rules.

Authored by :func:`finish_stage` (every USD output):

* ``kind = "component"`` on the SkelRoot (the default prim), as DCC exporters do;
* ``extent`` and ``extentsHint`` on the SkelRoot: the bounds of every joint over every
  frame (the rest pose for a motion without frames), grown by the farthest bind-pose
  mesh vertex from its main joint (a box that holds the skinned meshes unless blending
  carries a vertex farther from its joint than at bind time; the tests check it against usd-core's skinning);
* a ``UsdPreviewSurface`` material bound to every mesh that has none (its display
  colour, else a neutral grey), so viewers do not show it flat white.

Checked by :func:`ar_quick_look_problems` (``.usdz`` output warns when not compliant):
usd-core no longer ships ``UsdUtils.ComplianceChecker``; its rules are checked with the
``pxr.UsdValidation`` validators that exist (:data:`VALIDATORS`) and, where none does,
here: ``upAxis`` Y, prim types (``ARKitPrimTypeChecker``), shader ids
(``ARKitShaderChecker``), a ``.usdc`` root layer in the package (``ARKitRootLayerChecker``).
:data:`UNCHECKED` lists the rules that remain unchecked.
"""

from __future__ import annotations

import numpy as np

from usdmotion.io.usd_schema import schema_attribute
from usdmotion.kinematics import position_bounds, rest_pose

VALIDATORS = (
    "usdUtilsValidators:FileExtensionValidator", "usdUtilsValidators:MissingReferenceValidator",
    "usdUtilsValidators:PackageEncapsulationValidator", "usdUtilsValidators:RootPackageValidator",
    "usdUtilsValidators:UsdzPackageValidator", "usdValidation:StageMetadataChecker",
    "usdGeomValidators:StageMetadataChecker", "usdSkelValidators:SkelBindingApiAppliedValidator",
    "usdSkelValidators:SkelBindingApiValidator", "usdShadeValidators:MaterialBindingApiAppliedValidator",
    "usdShadeValidators:MaterialBindingRelationships", "usdShadeValidators:ShaderSdrCompliance",
)
AR_PRIM_TYPES = frozenset({"", "Scope", "Xform", "Camera", "Shader", "Material", "Mesh", "Sphere", "Cube", "Cylinder",
                           "Cone", "Capsule", "GeomSubset", "Points", "SkelRoot", "Skeleton", "SkelAnimation",
                           "BlendShape", "SpatialAudio"})
AR_SHADER_IDS = frozenset({"UsdPreviewSurface", "UsdUVTexture", "UsdTransform2d"})
UNCHECKED = (
    "ARKitTextureChecker (texture formats/sizes: usdmotion writes no textures)",
    "ByteAlignmentChecker and CompressionChecker beyond what the usdz package validators check",
    "ARKitMaterialBindingChecker's collection-based bindings (usdmotion binds directly)",
)
DEFAULT_COLOR = (0.62, 0.62, 0.62)


def finish_stage(layer, root_path: str, motion, bounds: tuple[np.ndarray, np.ndarray] | None = None,
                 stage=None) -> None:
    """Author ``kind``, ``extent``/``extentsHint`` and materials (see the module docstring).

    ``layer``: the ``Sdf.Layer`` written; ``root_path``: its SkelRoot. ``bounds``: ``position_bounds``
    of the animation when ``motion`` holds only its skeleton. ``stage``: the ``Usd.Stage`` on
    ``layer`` when meshes were added (their reach grows the extent, and they get materials); a
    skeleton-only layer is finished without importing ``pxr.Usd``, ``UsdGeom`` or ``UsdSkel`` (start-up)."""
    root = layer.GetPrimAtPath(root_path)
    root.SetInfo("kind", "component")  # Usd.ModelAPI(root).SetKind(Kind.Tokens.component)
    meshes = _meshes(stage.GetPrimAtPath(root_path)) if stage is not None else []
    _extent(stage, root, motion, meshes, bounds)
    if meshes:
        _materials(stage, stage.GetPrimAtPath(root_path), meshes)


def _meshes(root) -> list:
    """The ``Usd.Prim`` children of ``root`` that are ``UsdGeom.Mesh`` prims (``IsA`` through the
    type's name: no ``pxr.UsdGeom`` import)."""
    from pxr import Tf

    mesh = Tf.Type.FindByName("UsdGeomMesh")
    return [prim for prim in root.GetChildren() if prim.IsA(mesh)]


def _extent(stage, root, motion, meshes: list, bounds) -> None:
    """``extent`` and ``extentsHint`` on ``root`` (``Sdf.PrimSpec``); ``meshes``: ``Usd.Prim`` of ``stage``."""
    from pxr import Gf, Sdf, Vt

    if bounds is not None:
        lo, hi = bounds
    elif motion.n_frames:
        lo, hi = position_bounds(motion)
    else:  # no time samples: the stage shows the rest pose (define_skeleton's defaults)
        rest = rest_pose(motion)[1]
        lo, hi = rest.min(axis=0), rest.max(axis=0)
    reach = 0.0
    if meshes:
        from pxr import UsdGeom, UsdSkel  # stages with meshes only
    for prim in meshes:
        points = np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(), np.float64).reshape(-1, 3)
        bind = np.array(UsdSkel.Skeleton(stage.GetPrimAtPath(
            UsdSkel.BindingAPI(prim).GetSkeletonRel().GetTargets()[0])).GetBindTransformsAttr().Get())
        joints = np.array(UsdSkel.BindingAPI(prim).GetJointIndicesPrimvar().Get()).reshape(len(points), -1)[:, 0]
        reach = max(reach, float(np.linalg.norm(points - bind[joints, 3, :3], axis=1).max(initial=0.0)))
    box = Vt.Vec3fArray([Gf.Vec3f(*map(float, lo - reach)), Gf.Vec3f(*map(float, hi + reach))])
    schema_attribute(root, "extent", Sdf.ValueTypeNames.Float3Array, box)       # UsdGeom.Boundable.CreateExtentAttr
    schema_attribute(root, "extentsHint", Sdf.ValueTypeNames.Float3Array, box)  # UsdGeom.ModelAPI.SetExtentsHint


def _materials(stage, root, meshes: list) -> None:
    from pxr import Gf, Sdf, UsdGeom, UsdShade  # only here: UsdShade imports Sdr (skeleton-only stages need neither)

    for prim in meshes:
        if UsdShade.MaterialBindingAPI(prim).GetDirectBindingRel().GetTargets():
            continue
        color = UsdGeom.Mesh(prim).GetDisplayColorPrimvar().Get() if UsdGeom.Mesh(prim).GetDisplayColorPrimvar() else None
        rgb = tuple(map(float, color[0])) if color else DEFAULT_COLOR
        material = UsdShade.Material.Define(stage, root.GetPath().AppendPath(Sdf.Path(f"Materials/{prim.GetName()}")))
        shader = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("Surface"))
        shader.CreateIdAttr("UsdPreviewSurface")
        shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*rgb))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.6)
        shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
        material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)


def ar_quick_look_problems(path) -> list[str]:
    """AR Quick Look (ARKit) rule violations of the stage at ``path`` (see the module docstring)."""
    from pxr import Sdf, Usd, UsdGeom, UsdShade, UsdValidation

    stage = Usd.Stage.Open(str(path))
    registry = UsdValidation.ValidationRegistry()
    validators = [registry.GetOrLoadValidatorByName(n) for n in VALIDATORS if registry.HasValidator(n)]
    problems = [f"{e.GetName()}: {e.GetMessage()}" for e in UsdValidation.ValidationContext(validators).Validate(stage)
                if e.GetType() == UsdValidation.ValidationErrorType.Error]
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y:
        problems.append(f"upAxis is {UsdGeom.GetStageUpAxis(stage)}: AR Quick Look needs Y (convert with --to-up-axis Y)")
    for prim in stage.Traverse():
        if prim.GetTypeName() not in AR_PRIM_TYPES:
            problems.append(f"{prim.GetPath()}: prim type {prim.GetTypeName()} is not supported by ARKit")
        if prim.IsA(UsdShade.Shader):
            shader_id = UsdShade.Shader(prim).GetShaderId() or ""
            if shader_id not in AR_SHADER_IDS and not shader_id.startswith("UsdPrimvarReader_"):
                problems.append(f"{prim.GetPath()}: shader {shader_id!r} is not one ARKit supports")
    if str(path).lower().endswith(".usdz"):
        names = Sdf.ZipFile.Open(str(path)).GetFileNames()
        if not names or not names[0].lower().endswith(".usdc"):
            problems.append(f"the package's root layer is {names[0] if names else 'missing'}, ARKit needs a .usdc")
    return problems

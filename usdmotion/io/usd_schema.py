"""Prims and schema attributes authored straight into an ``Sdf.Layer``, as ``Usd.Stage.DefinePrim``
and the generated schema classes' ``Create<Name>Attr`` author them, so writing a skeleton imports
neither ``pxr.Usd`` (with ``Pcp``, the schema registry and every plugin's schemas: 0.03 s of every
``usdmotion convert`` to USD) nor ``pxr.UsdSkel``/``pxr.UsdGeom`` (``benchmarks/startup.py``). The
written layer is the same, byte for byte (``tests/test_usd.py`` compares it with the schema classes').
"""

from __future__ import annotations


def define_prim(layer, path: str, type_name: str):
    """The ``Sdf.PrimSpec`` at ``path`` defined with ``type_name``, as ``UsdStage::DefinePrim``
    authors it (``SdfCreatePrimInLayer``, then the specifier, then the type name)."""
    from pxr import Sdf

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = type_name
    return spec


def schema_attribute(prim, name: str, type_name, value=None, uniform: bool = False):
    """The ``Sdf.AttributeSpec`` ``name`` of ``prim`` (an ``Sdf.PrimSpec``) as ``Create<Name>Attr(value)``
    authors it (``UsdSchemaBase::_CreateAttr``: not custom, the schema's variability, ``value`` as its
    default when given); ``type_name`` an ``Sdf.ValueTypeNames`` member."""
    from pxr import Sdf

    path = prim.path.AppendProperty(name)
    Sdf.JustCreatePrimAttributeInLayer(prim.layer, path, type_name,
                                       Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying, False)
    attr = prim.layer.GetAttributeAtPath(path)
    if value is not None:
        attr.default = value
    return attr


def schema_relationship(prim, name: str, targets: list) -> None:
    """``prim``'s relationship ``name`` targeting ``targets`` (``Sdf.Path`` list) as
    ``Create<Name>Rel().SetTargets(targets)`` authors it (not custom, explicit targets)."""
    from pxr import Sdf

    path = prim.path.AppendProperty(name)
    Sdf.JustCreateRelationshipInLayer(prim.layer, path, Sdf.VariabilityUniform, False)
    prim.layer.GetRelationshipAtPath(path).targetPathList.explicitItems = targets

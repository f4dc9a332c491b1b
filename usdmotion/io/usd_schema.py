"""Schema attributes authored through the generic ``Usd.Prim`` API, as the generated schema
classes author them, so writing a skeleton imports neither ``pxr.UsdSkel`` nor ``pxr.UsdGeom``
(0.015 s of every ``usdmotion convert`` to USD; ``benchmarks/startup.py``). The written
layer is the same, byte for byte (``tests/test_usd.py`` compares it with the schema classes')."""

from __future__ import annotations


def schema_attribute(prim, name: str, type_name, value=None, uniform: bool = False):
    """The attribute ``name`` of ``prim``'s schema as ``Create<Name>Attr(value)`` authors it
    (``UsdSchemaBase::_CreateAttr``: not custom, the schema's variability, ``value`` as its
    default when given); ``type_name`` an ``Sdf.ValueTypeNames`` member."""
    from pxr import Sdf

    attr = prim.CreateAttribute(name, type_name, False, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    if value is not None:
        attr.Set(value)
    return attr

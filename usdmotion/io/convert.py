"""Write a read motion to another format (BVH, UsdSkel, glTF): the core of ``usdmotion convert`` and ``batch convert``.

Both front ends call :func:`convert_motion` after ``read_motion``, so one take converted
either way gives byte-identical files.
"""

from __future__ import annotations

import os
from pathlib import Path

from usdmotion.errors import OutputError
from usdmotion.io import write_motion
from usdmotion.motion import Motion

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
GLTF_SUFFIXES = (".glb", ".gltf")


def check_convert_paths(source: str | os.PathLike, output: str | os.PathLike, mesh: bool = False) -> None:
    """``OutputError`` when ``output`` would overwrite ``source`` or ``mesh`` asks for a non-USD output."""
    source, output = Path(source), Path(output)
    if source.resolve() == output.resolve():
        raise OutputError(f"{output}: output would overwrite the input")
    if mesh and output.suffix.lower() not in USD_SUFFIXES + GLTF_SUFFIXES:
        raise OutputError(f"{output}: --mesh needs a USD or glTF output (.usd, .usda, .usdc, .usdz, .glb, .gltf)")


def kept_for(motion: Motion, output: str | os.PathLike) -> Motion:
    """``motion`` less what the ``output`` format does not write: ``source_channels`` (the
    Euler hint of a BVH write-back; an ``(F, C)`` float64 array as large as a BVH take's
    data) for any output but BVH. A caller that drops its own reference frees it before
    the write, whose peak memory then holds one copy of the take less."""
    import dataclasses

    if motion.source_channels is None or Path(output).suffix.lower() == ".bvh":
        return motion
    return dataclasses.replace(motion, source_channels=None)


def convert_motion(motion: Motion | list[Motion], output: str | os.PathLike, mesh: bool = False,
                   validate: bool = False) -> None:
    """Write ``motion`` to ``output`` (format by extension, atomically).

    Args:
        motion: the motion, or a one-item list holding the caller's only reference: handed
            over, a long take's arrays are freed while its samples are written (USD output,
            see :func:`usdmotion.io.usd.write_usd`).
        mesh: add a volumetric body mesh skinned to the skeleton (USD and glTF outputs).
        validate: run ``pxr.UsdValidation`` on a USD output before it replaces ``output``; an
            error raises ``OutputError`` and nothing is written (every USD output gets the
            writer's structural check: :mod:`usdmotion.io.usd_check`).
    """
    output = Path(output)
    options = {}
    if mesh:
        from usdmotion.skin import build_body  # --mesh only

        body = build_body(motion[0] if isinstance(motion, list) else motion)
        if output.suffix.lower() in GLTF_SUFFIXES:
            options["body"] = body
        else:
            from usdmotion.io.usd_mesh import body_decorator  # --mesh only

            options["decorate"] = body_decorator(body)
    if validate and output.suffix.lower() in USD_SUFFIXES:
        options["validate"] = True
    write_motion(motion, output, **options)

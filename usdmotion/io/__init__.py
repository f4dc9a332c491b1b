"""File formats: extension → reader / writer registry.

``read_motion(path, **options)`` and ``write_motion(motion, path, **options)`` dispatch on
the extension; options a format does not use are ignored (e.g. ``root_offset`` for USD).
"""

from __future__ import annotations

import os
from pathlib import Path

from usdmotion.errors import InputError, OutputError
from usdmotion.motion import Motion

BVH_EXTENSIONS = (".bvh",)
USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
GLTF_EXTENSIONS = (".glb", ".gltf")
KNOWN = f".bvh, {', '.join(USD_EXTENSIONS)}, {', '.join(GLTF_EXTENSIONS)}"


def _kind(path: Path) -> str | None:
    ext = path.suffix.lower()
    if ext in BVH_EXTENSIONS:
        return "bvh"
    if ext in USD_EXTENSIONS:
        return "usd"
    if ext in GLTF_EXTENSIONS:
        return "gltf"
    return None


def read_motion(path: str | os.PathLike, root_offset: str = "auto", units: str | float | None = None,
                up_axis: str | None = None, lenient: bool = False, ignore_joint_positions: bool = False,
                skin: int | None = None) -> Motion:
    """Read a BVH, UsdSkel or glTF 2.0 (.glb/.gltf) file.

    For BVH, ``units`` (default ``"cm"``) and ``up_axis`` (default ``"Y"``) state what the
    file does not; for USD they come from the stage and, if given, override it.
    """
    import dataclasses

    path = Path(path)
    kind = _kind(path)
    if kind == "bvh":
        from usdmotion.io.bvh import read_bvh

        return read_bvh(path, root_offset=root_offset, units="cm" if units is None else units,
                        up_axis=up_axis or "Y", lenient=lenient, ignore_joint_positions=ignore_joint_positions)
    if kind == "usd":
        from usdmotion.io.bvh import resolve_units
        from usdmotion.io.usd import read_usd

        motion = read_usd(path)
        changes = {}
        if units is not None:
            changes["meters_per_unit"] = resolve_units(units)
        if up_axis is not None:
            changes["up_axis"] = up_axis
        return dataclasses.replace(motion, **changes) if changes else motion
    if kind == "gltf":
        from usdmotion.io.gltf_read import read_gltf

        return read_gltf(path, skin=skin)
    raise InputError(path, f"unknown input format {path.suffix!r} (use {KNOWN})")


def write_motion(motion: Motion, path: str | os.PathLike, **options) -> Path:
    """Write ``motion`` as BVH, USD or glTF, chosen by the extension of ``path`` (atomically)."""
    path = Path(path)
    kind = _kind(path)
    if kind == "bvh":
        from usdmotion.io.bvh import write_bvh

        return write_bvh(motion, path, **{k: v for k, v in options.items() if k in ("decimals",)})
    if kind == "usd":
        from usdmotion.io.usd import write_usd

        return write_usd(motion, path, **{k: v for k, v in options.items() if k in ("name", "decorate")})
    if kind == "gltf":
        from usdmotion.io.gltf import write_gltf

        return write_gltf(motion, path, **{k: v for k, v in options.items() if k in ("name", "mesh", "fps", "body")})
    raise OutputError(f"{path}: unknown output format {path.suffix!r} (use {KNOWN})")

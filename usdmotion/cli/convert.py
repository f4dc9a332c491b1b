"""``usdmotion convert IN OUT``: BVH ⇄ UsdSkel (.usda/.usdc/.usdz), BVH → BVH, USD → USD."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, UpAxisChoice, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def convert(
    source: InputPath,
    output: Annotated[Path, typer.Argument(help="Output: .usda, .usdc, .usdz, .usd or .bvh.", show_default=False)],
    validate: Annotated[bool, typer.Option(help="Run pxr.UsdValidation on a USD output.")] = True,
    mesh: Annotated[bool, typer.Option("--mesh", help="Add a volumetric body Mesh skinned to the Skeleton "
                                                      "(USD output only).")] = False,
    to_up_axis: Annotated[UpAxisChoice | None, typer.Option(
        "--to-up-axis", help="Turn the output to this up axis (Y for AR Quick Look); default: keep the input's.",
        case_sensitive=False, show_default=False)] = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Convert a motion between BVH and OpenUSD (UsdSkel)."""
    from usdmotion.cli._progress import progress
    from usdmotion.errors import OutputError
    from usdmotion.io import write_motion

    if source.resolve() == output.resolve():
        raise OutputError(f"{output}: output would overwrite the input")
    start = time.perf_counter()
    motion = read.read(source)
    if to_up_axis is not None and to_up_axis.value != "auto":
        from usdmotion.ops.up_axis import convert_up_axis

        motion = convert_up_axis(motion, to_up_axis.value)
    options = {}
    if mesh:
        from usdmotion.io.usd_mesh import body_decorator
        from usdmotion.skin import build_body

        if output.suffix.lower() not in (".usd", ".usda", ".usdc", ".usdz"):
            raise OutputError(f"{output}: --mesh needs a USD output (.usd, .usda, .usdc, .usdz)")
        with progress("building the body mesh"):
            options["decorate"] = body_decorator(build_body(motion))
    with progress(f"writing {output.name}"):
        write_motion(motion, output, **options)
    problems = []
    if validate and output.suffix.lower() in (".usd", ".usda", ".usdc", ".usdz"):
        from usdmotion.io.usd import validate_stage

        problems = validate_stage(str(output))
        for problem in problems:
            typer.echo(f"usdmotion: warning: {output}: {problem}", err=True)
    typer.echo(f"wrote {output}: {int((~motion.end_sites).sum())} joints (+{int(motion.end_sites.sum())} end sites), "
               f"{motion.n_frames} frames at {motion.fps:.6g} fps ({motion.duration:.2f} s), "
               f"{motion.meters_per_unit:g} m/unit, {motion.up_axis}-up, root offset {motion.root_offset} "
               f"[{time.perf_counter() - start:.2f} s]")

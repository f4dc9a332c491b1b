"""``usdmotion convert IN OUT``: between BVH, UsdSkel (.usda/.usdc/.usdz) and glTF 2.0 (.glb/.gltf)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, UpAxisChoice, reads_motion
from usdmotion.cli._progress import progress
from usdmotion.cli.app import app


@app.command()
@reads_motion
def convert(
    source: InputPath,
    output: Annotated[Path, typer.Argument(help="Output: .usda, .usdc, .usdz, .usd, .bvh, .glb or .gltf.",
                                           show_default=False)],
    validate: Annotated[bool, typer.Option(help="Also run every pxr.UsdValidation validator on a USD output (an "
                                                "error: exit 2, nothing written); the writer's own structural "
                                                "check runs either way.")] = False,
    mesh: Annotated[bool, typer.Option("--mesh", help="Add a volumetric body mesh skinned to the skeleton "
                                                      "(USD and glTF outputs).")] = False,
    fps: Annotated[float | None, typer.Option("--fps", help="Resample to this frame rate first (e.g. 30 for a "
                                                            "smaller file).", show_default=False)] = None,
    to_up_axis: Annotated[UpAxisChoice | None, typer.Option(
        "--to-up-axis", help="Turn the output to this up axis (Y for AR Quick Look); default: keep the input's.",
        case_sensitive=False, show_default=False)] = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Convert a motion between BVH, OpenUSD (UsdSkel) and glTF 2.0 (GLB)."""
    from usdmotion.io.convert import check_convert_paths, convert_motion, kept_for

    check_convert_paths(source, output, mesh)
    start = time.perf_counter()
    motion = kept_for(read.read(source), output)
    if fps is not None:
        from usdmotion.ops.edit.timewarp import resample

        motion = resample(motion, fps)
    if to_up_axis is not None and to_up_axis.value != "auto":
        from usdmotion.ops.up_axis import convert_up_axis

        motion = convert_up_axis(motion, to_up_axis.value)
    summary = (f"{int((~motion.end_sites).sum())} joints (+{int(motion.end_sites.sum())} end sites), "
               f"{motion.n_frames} frames at {motion.fps:.6g} fps ({motion.duration:.2f} s), "
               f"{motion.meters_per_unit:g} m/unit, {motion.up_axis}-up, root offset {motion.root_offset}")
    handed_over = [motion]
    del motion  # the writer holds the only reference: a long take's arrays are freed while it writes
    with progress(f"writing {output.name}"):
        convert_motion(handed_over, output, mesh, validate)
    typer.echo(f"wrote {output}: {summary} [{time.perf_counter() - start:.2f} s]")

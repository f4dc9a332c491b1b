"""``usdmotion batch convert|analyze|segment|retarget|render SRC_DIR OUT_DIR``: a whole library on Dask."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import ReadOptions, reads_motion
from usdmotion.cli.app import app

batch_app = typer.Typer(name="batch", no_args_is_help=True, help="Process a whole motion library (resumable, "
                        "catalogue.parquet) on a local Dask cluster or an existing one.")
app.add_typer(batch_app, name="batch", rich_help_panel="Convert and inspect")

SrcDir = Annotated[Path, typer.Argument(help="Folder of motion files (searched recursively).", show_default=False)]
OutDir = Annotated[Path, typer.Argument(help="Output folder: mirrors the source tree; holds catalogue.parquet.",
                                        show_default=False)]
Include = Annotated[list[str] | None, typer.Option(help="Glob(s) of takes to process, relative to SRC_DIR "
                                                        "(default: every .bvh/.amc/.usd*/.glb/.gltf file). Repeatable.",
                                                   show_default=False)]
Workers = Annotated[int | None, typer.Option(help="Worker processes of the local cluster (default: one per core).",
                                             show_default=False, min=1)]
Scheduler = Annotated[str | None, typer.Option(help="Run on an existing Dask cluster: tcp://HOST:8786 (workers need "
                                                    "usdmotion installed and the same paths).", show_default=False)]
Force = Annotated[bool, typer.Option("--force", help="Redo takes that are up to date.")]


class ConvertTo(str, Enum):
    usdc = "usdc"
    usdz = "usdz"
    usda = "usda"
    glb = "glb"
    bvh = "bvh"


def _read_options(read: ReadOptions) -> dict:
    """``read_motion`` keyword arguments from the shared reading options."""
    import dataclasses

    return dataclasses.asdict(read)


def _run(operation: str, src_dir: Path, out_dir: Path, read_options: dict, params: dict, include, force: bool,
         workers, scheduler) -> None:
    """Run the batch with a progress bar (takes/s, ETA), print the summary and failures; exit 1 if any failed."""
    from usdmotion.batch import run_batch
    from usdmotion.batch.plan import DEFAULT_INCLUDE
    from usdmotion.cli._progress import progress

    # redrawn twice a second, not rich's 10: the bar's process shares the cores with the workers
    # (a redraw rate of 10 costs ~8 ms of CPU a second more, measured with rich's own bar)
    with progress(f"batch {operation}", unit="takes", refresh_per_second=2) as update:
        result = run_batch(operation, src_dir, out_dir, read_options, params,
                           tuple(include) if include else DEFAULT_INCLUDE, force, workers, scheduler, progress=update)
    if result.total == 0:
        import warnings

        from usdmotion.errors import UsdMotionWarning

        globs = ", ".join(include) if include else "the motion files' extensions"
        warnings.warn(UsdMotionWarning(f"{src_dir}: no takes found (include: {globs}): nothing to do"), stacklevel=1)
    for row in result.failed:
        where = "" if row["error"].startswith(row["source"]) else f"{row['source']}: "
        typer.echo(f"usdmotion: error: {where}{row['error']}", err=True)
    typer.echo(result.summary_line(operation))
    if result.failed:
        raise typer.Exit(1)


@batch_app.command("convert")
@reads_motion
def convert(src_dir: SrcDir, out_dir: OutDir,
            to: Annotated[ConvertTo, typer.Option("--to", help="Output format.")] = ConvertTo.usdc,
            mesh: Annotated[bool, typer.Option("--mesh", help="Add a skinned body mesh (USD and GLB outputs).")] = False,
            include: Include = None, workers: Workers = None, scheduler: Scheduler = None, force: Force = False,
            read: ReadOptions = ReadOptions()) -> None:
    """Convert every take (like 'usdmotion convert')."""
    if mesh and to == ConvertTo.bvh:
        raise ValueError("--mesh needs a USD or glTF output (--to usdc, usdz, usda or glb)")
    _run("convert", src_dir, out_dir, _read_options(read),
         {"to": to.value, "mesh": mesh}, include, force, workers, scheduler)


@batch_app.command("analyze")
@reads_motion
def analyze(src_dir: SrcDir, out_dir: OutDir, include: Include = None, workers: Workers = None,
            scheduler: Scheduler = None, force: Force = False, read: ReadOptions = ReadOptions()) -> None:
    """Kinematics of every take (like 'usdmotion analyze --summary S --out F.parquet'): summaries,
    catalogue columns, per-frame tables in OUT_DIR/frames/ (partitioned by take)."""
    _run("analyze", src_dir, out_dir, _read_options(read), {}, include, force, workers, scheduler)


@batch_app.command("segment")
@reads_motion
def segment(src_dir: SrcDir, out_dir: OutDir,
            export_clips: Annotated[bool, typer.Option("--export-clips", help="Also write one BVH per segment.")]
            = False, include: Include = None, workers: Workers = None, scheduler: Scheduler = None,
            force: Force = False, read: ReadOptions = ReadOptions()) -> None:
    """Segment every take into actions (like 'usdmotion segment --out')."""
    _run("segment", src_dir, out_dir, _read_options(read),
         {"export_clips": export_clips}, include, force, workers, scheduler)


@batch_app.command("retarget")
@reads_motion
def retarget(src_dir: SrcDir, out_dir: OutDir,
             target: Annotated[Path, typer.Option(help="Target skeleton (BVH or UsdSkel).", show_default=False)],
             to: Annotated[ConvertTo, typer.Option("--to", help="Output format.")] = ConvertTo.usdc,
             include: Include = None, workers: Workers = None, scheduler: Scheduler = None, force: Force = False,
             read: ReadOptions = ReadOptions()) -> None:
    """Retarget every take onto one rig (like 'usdmotion retarget --target --report')."""
    from usdmotion.errors import InputError

    if not target.is_file():
        raise InputError(target, "target skeleton not found")
    _run("retarget", src_dir, out_dir, _read_options(read),
         {"to": to.value, "target": str(target.absolute())}, include, force, workers, scheduler)


@batch_app.command("render")
@reads_motion
def render(src_dir: SrcDir, out_dir: OutDir,
           size: Annotated[str, typer.Option(help="Preview size WIDTHxHEIGHT.")] = "640x360",
           include: Include = None, workers: Workers = None, scheduler: Scheduler = None, force: Force = False,
           read: ReadOptions = ReadOptions()) -> None:
    """A preview MP4 of every take (like 'usdmotion render --size')."""
    from usdmotion.cli.render import _size
    from usdmotion.render import RenderOptions, check_options

    width, height = _size(size)
    check_options(RenderOptions(width=width, height=height))  # refused once, not as a failed row per take
    _run("render", src_dir, out_dir, _read_options(read), {"size": [width, height]},
         include, force, workers, scheduler)

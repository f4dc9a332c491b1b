"""``usdmotion segment IN``: cut a long take into primitive actions (bone-angle feature)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, Json, ReadOptions, reads_motion
from usdmotion.cli._progress import progress
from usdmotion.cli._segment_options import DetectorOptions, Method, MethodChoice, detects_segments, print_segments
from usdmotion.cli.app import app


class ClipFormat(str, Enum):
    bvh = "bvh"
    usda = "usda"
    usdc = "usdc"


@app.command()
@reads_motion
@detects_segments
def segment(
    source: InputPath,
    method: Method = MethodChoice.kcpd,
    out: Annotated[Path | None, typer.Option(help="Write the segments as JSON here.", show_default=False)] = None,
    plot: Annotated[Path | None, typer.Option(help="Plot the signal and the cuts (.png, .svg, .pdf).",
                                              show_default=False)] = None,
    export_clips: Annotated[Path | None, typer.Option(help="Write one clip per segment into this folder.",
                                                      show_default=False)] = None,
    clip_format: Annotated[ClipFormat, typer.Option("--format", help="Clip format.")] = ClipFormat.bvh,
    at: Annotated[int | None, typer.Option(help="Keep only the action containing this frame (0-based).",
                                           show_default=False)] = None,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
    detector: DetectorOptions = DetectorOptions(),
) -> None:
    """Segment a motion into primitive actions; export the segments, a plot and clips."""
    from usdmotion.ops.segment.files import export_clips as write_clips
    from usdmotion.ops.segment.files import plot_segmentation, write_segments_json

    motion = read.read(source)
    seg = detector.run(motion, source, method)
    chosen = None if at is None else seg.segment_at(at, str(source))
    if out is not None:
        write_segments_json(seg, out, str(source), chosen)
    if plot is not None:
        plot_segmentation(seg, plot, f"{source.name}: {seg.method}, {len(seg.bounds())} segments", chosen)
    clips = []
    if export_clips is not None:
        with progress("writing clips", unit="clips") as update:
            clips = write_clips(motion, seg, export_clips, clip_format.value, source.stem,
                                None if chosen is None else [chosen], progress=update)
    print_segments(seg, source, chosen, as_json, clips)

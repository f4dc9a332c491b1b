"""Options and output shared by ``segment`` and ``segment-eval``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import option_group
from usdmotion.cli._progress import progress


class MethodChoice(str, Enum):
    kcpd = "kcpd"
    heuristic = "heuristic"


Method = Annotated[MethodChoice, typer.Option(
    help="kcpd: kernel change points on the 8 bone angles and their speeds; heuristic: the paper's swing-ratio "
         "candidates on the low-passed norm signal.", case_sensitive=False)]
Param = Annotated[float, typer.Option(min=0.0, max=1.0, help="heuristic: swing-ratio threshold (paper: 0.5).")]
Cutoff = Annotated[float, typer.Option(help="Low-pass cut-off of the norm signal, Hz, from 0.1 to half the frame rate (heuristic, plot).")]
Penalty = Annotated[float | None, typer.Option(
    help="kcpd: cost of one cut (larger: fewer cuts); default: ln N for N samples at 10 Hz (grows with the "
         "take's length, no labels needed).", show_default=False)]
MinLength = Annotated[float, typer.Option(help="kcpd: shortest segment, seconds.")]
Refine = Annotated[bool, typer.Option(
    "--refine/--no-refine", help="kcpd: move each cut to the quietest frame (least bone energy) of its own "
                                 "change region.")]
Roles = Annotated[list[str] | None, typer.Option(
    "--role", help="Name a role's joint, e.g. --role chest=Spine2 (repeatable). Roles: root, chest, "
                   "left_/right_ shoulder, elbow, wrist, hip, knee, ankle.", show_default=False)]
Preset = Annotated[str | None, typer.Option(
    help="Role preset: cgspeed-mb, cgspeed-max, daz, bandai, mixamo, asf, character-creator, unreal, rigify, "
         "biped, smpl (default: detect, else guess by name).",
    show_default=False)]


@dataclass(frozen=True)
class DetectorOptions:
    """The detector options of ``segment`` and ``segment-eval``, declared once (:func:`detects_segments`)."""

    param: float = 0.5
    cutoff: float = 2.0
    penalty: float | None = None
    min_length: float = 1.0
    refine: bool = True
    role: list[str] | None = None
    preset: str | None = None

    def run(self, motion, source: Path, method: MethodChoice):
        """Find roles and cut ``motion`` with ``method`` (errors name ``source``)."""
        # Deferred so that loading the CLI does not import NumPy.
        from usdmotion.ops.segment.detect import segment
        from usdmotion.ops.segment.roles import parse_role_overrides

        with progress(f"segmenting {source.name}"):
            return segment(motion, method=method.value, param=self.param, cutoff_hz=self.cutoff,
                           penalty=self.penalty, min_length_s=self.min_length, refine=self.refine,
                           roles=parse_role_overrides(self.role), preset=self.preset, source=str(source))


#: The parameters :func:`detects_segments` adds to a command: (name, annotation, default).
DETECTOR_PARAMETERS = (("param", Param, 0.5), ("cutoff", Cutoff, 2.0), ("penalty", Penalty, None),
                       ("min_length", MinLength, 1.0), ("refine", Refine, True), ("role", Roles, None),
                       ("preset", Preset, None))


#: Gives ``segment`` and ``segment-eval`` the detector options as ``detector: DetectorOptions``.
detects_segments = option_group(DETECTOR_PARAMETERS, "detector", DetectorOptions)


def _setting(key: str, value) -> str:
    if isinstance(value, str):
        return f"{key}={value}"
    return key if value is True else f"no {key}" if value is False else f"{key}={value:.4g}"


def print_segments(seg, source: Path, chosen: int | None, as_json: bool, clips: list[Path]) -> None:
    """Table (or JSON) of the segments; only ``chosen`` when given."""
    doc = seg.to_dict()
    rows = doc["segments"] if chosen is None else [doc["segments"][chosen]]
    if as_json:
        typer.echo(json.dumps({"file": str(source), **doc, "segments": rows,
                               "clips": [str(c) for c in clips]}, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    details = {d["frame"]: d for d in doc.get("cut_details", [])}
    columns = ["#", "first frame", "last frame", "frames", "start (s)", "end (s)", "duration (s)"]
    if details:
        columns.append("cut confidence")
    table = Table(*columns, title=f"{source.name}: {len(doc['segments'])} segments ({seg.method}, "
                                  f"{', '.join(_setting(k, v) for k, v in seg.params.items())})")
    for s in rows:
        cells = [str(s["index"]), str(s["start_frame"]), str(s["end_frame"]), str(s["frames"]),
                 f"{s['start_time']:.3f}", f"{s['end_time']:.3f}", f"{s['frames'] / seg.fps:.3f}"]
        if details:
            cut = details.get(s["start_frame"])
            flag = " check" if cut is not None and cut["low_confidence"] else ""
            cells.append("" if cut is None else f"{cut['confidence']:.2f}{flag}")
        table.add_row(*cells)
    console = Console(width=120)
    console.print(table)
    for c in clips:
        console.print(f"wrote {c}")

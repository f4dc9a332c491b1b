"""``usdmotion contacts IN``: the frames each heel/ankle and toe is planted on the floor."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


def _number(help_text: str):
    return Annotated[float | None, typer.Option(help=help_text, show_default=False)]


@app.command()
@reads_motion
def contacts(
    source: InputPath,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the contacts JSON here ('-': print it "
                                                  "instead of the table).", show_default=False)] = None,
    plot: Annotated[Path | None, typer.Option(help="Plot heights and speeds with contact bands (.png, .svg, .pdf).",
                                              show_default=False)] = None,
    floor: _number("Floor height along the up axis, m (default: estimated from the feet).") = None,
    height_enter: _number("Enter height above the planted level, m (default 0.03).") = None,
    height_exit: _number("Exit height above the planted level, m (default 0.05).") = None,
    speed_enter: _number("Enter speed, m/s (default 0.25).") = None,
    speed_exit: _number("Exit speed, m/s (default 0.45).") = None,
    min_duration: _number("Shortest contact, s (default 0.05).") = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Detect foot contacts (heel/ankle and toe per side) from height above the floor and speed."""
    import json

    from usdmotion.errors import OutputError
    from usdmotion.ops.contacts import ContactThresholds, detect_contacts, motion_foot_metrics
    from usdmotion.ops.contacts.files import (contacts_document, plot_contacts, plot_path, summary_table,
                                              write_contacts_json)

    given = {"height_enter": height_enter, "height_exit": height_exit, "speed_enter": speed_enter,
             "speed_exit": speed_exit, "min_duration": min_duration}
    if plot is not None:
        plot_path(plot)  # refused before any work
    for out in (json_out, plot):
        if out is not None and str(out) != "-" and out.resolve() == source.resolve():
            raise OutputError(f"{out}: output would overwrite the input")
    thresholds = ContactThresholds(**{k: v for k, v in given.items() if v is not None})
    motion = read.read(source)
    found = detect_contacts(motion, floor=floor, thresholds=thresholds, source=str(source))
    if json_out is not None and str(json_out) != "-":
        write_contacts_json(found, json_out, str(source))
    if plot is not None:
        plot_contacts(motion, found, plot, f"{source.name}: foot contacts, floor {found.floor:.3f} m")
    if json_out is not None and str(json_out) == "-":
        typer.echo(json.dumps(contacts_document(found, str(source)), indent=1))
        return
    typer.echo(summary_table(found, str(source)))
    typer.echo(motion_foot_metrics(motion, found).describe())

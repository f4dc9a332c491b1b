"""``usdmotion contacts IN``: the frames each heel/ankle and toe is planted on the floor."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, reads_motion
from usdmotion.cli.app import app


def _metres(help_text: str):
    return Annotated[float | None, typer.Option(help=help_text, show_default=False)]


@app.command()
@reads_motion
def contacts(
    source: InputPath,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the contacts JSON here ('-': print it "
                                                  "instead of the table).", show_default=False)] = None,
    plot: Annotated[Path | None, typer.Option(help="Plot heights and speeds with contact bands (.png, .svg, .pdf).",
                                              show_default=False)] = None,
    floor: _metres("Floor height along the up axis, m (default: estimated from the feet).") = None,
    height_enter: _metres("Enter height above the planted level, m (default 0.03).") = None,
    height_exit: _metres("Exit height above the planted level, m (default 0.05).") = None,
    speed_enter: _metres("Enter speed, m/s (default 0.25).") = None,
    speed_exit: _metres("Exit speed, m/s (default 0.45).") = None,
    min_duration: _metres("Shortest contact, s (default 0.05).") = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Detect foot contacts (heel/ankle and toe per side) from height above the floor and speed."""
    import json

    from usdmotion.ops.contacts import ContactThresholds, detect_contacts
    from usdmotion.ops.contacts.files import (contact_summary, contacts_document, plot_contacts, plot_path,
                                              write_contacts_json)

    given = {"height_enter": height_enter, "height_exit": height_exit, "speed_enter": speed_enter,
             "speed_exit": speed_exit, "min_duration": min_duration}
    if plot is not None:
        plot_path(plot)  # refused before any work
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
    typer.echo(f"{source}: {motion.n_frames} frames at {motion.fps:g} fps, floor {found.floor:.3f} m "
               f"({motion.up_axis}-up)")
    typer.echo(f"{'joint':<24} {'part':<12} {'contacts':>8} {'time s':>8} {'mean s':>8}")
    for row in contact_summary(found):
        typer.echo(f"{row['name']:<24} {row['part']:<12} {row['contacts']:>8} {row['contact_time_s']:>8.3f} "
                   f"{row['mean_duration_s']:>8.3f}")

"""Terminal rendering of analysis summaries and constraint violations (rich tables)."""

from __future__ import annotations


def _peak(entry: dict | None, digits: int = 3) -> str:
    if not entry or entry.get("value") is None:
        return "-"
    return f"{entry['value']:.{digits}f} @ {entry['time']:.2f}s"


def print_summary(data: dict, title: str) -> None:
    """Per-joint peaks and ranges, then the centre of mass."""
    from rich.console import Console
    from rich.table import Table

    meta = data["meta"]
    units = meta["units"]
    table = Table(title=f"{title}: {meta['frames']} frames, {meta['fps']:g} fps, filter "
                        f"{meta['filter']['method']}" + (f" {meta['filter']['cutoff_hz']:g} Hz"
                                                           if "cutoff_hz" in meta["filter"] else ""))
    for column in ("joint", f"peak speed ({units['speed']})", f"peak acc ({units['acceleration']})",
                   "bend range (deg)", "angle ranges x/y/z (deg)", "peak rel. ang. speed (deg/s)"):
        table.add_column(column, justify="left" if column == "joint" else "right")
    for name, row in data["joints"].items():
        rom = row.get("range_of_motion")
        ranges = "/".join(f"{rom[a]['range']:.0f}" for a in "xyz") + f" {rom['euler_order']}" if rom else "-"
        bend = f"{row['bend']['min']:.0f}..{row['bend']['max']:.0f}" if "bend" in row else "-"
        table.add_row(name, _peak(row["peak_speed"]), _peak(row["peak_acceleration"], 1), bend, ranges,
                      _peak(row.get("peak_relative_angular_speed"), 0))
    console = Console()
    console.print(table)
    com = data.get("com")
    if com:
        v = com["vertical"]
        console.print(f"centre of mass ({com['model']}): height {v['min']:.3f}..{v['max']:.3f} "
                      f"(range {v['range']:.3f}) {units['position']}, mean horizontal speed "
                      f"{com['mean_horizontal_speed']:.3f} {units['speed']}, peak speed {_peak(com['peak_speed'])}"
                      + (f", peak momentum {_peak(com['peak_momentum'], 1)} kg m/s" if "peak_momentum" in com else ""))
        for note in com["notes"]:
            console.print(f"  note: {note}")


def print_violations(violations, title: str) -> None:
    """One row per violation run."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if not violations:
        console.print(f"{title}: no limit violated")
        return
    table = Table(title=f"{title}: {len(violations)} violation(s)")
    for column in ("joint", "quantity", "frames", "time (s)", "worst", "limit"):
        table.add_column(column, justify="left" if column in ("joint", "quantity") else "right")
    for v in violations:
        op = "<" if v.bound == "min" else ">"
        table.add_row(v.joint, v.quantity, f"{v.first_frame}-{v.last_frame}", f"{v.start_time:.3f}-{v.end_time:.3f}",
                      f"{v.value:g} {v.unit} (frame {v.worst_frame})", f"{op} {v.limit:g}")
    console.print(table)

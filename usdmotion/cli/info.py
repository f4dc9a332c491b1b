"""``usdmotion info FILE``: joints, hierarchy, frames, fps, channels, units, duration."""

from __future__ import annotations

import contextlib
import json
import warnings

import typer

from usdmotion.cli._options import InputPath, Json, ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def info(
    source: InputPath,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Describe a motion file: skeleton, timing, channels and units."""
    from usdmotion.summary import describe

    is_usd = source.suffix.lower() in (".usd", ".usda", ".usdc", ".usdz")
    with _one_stage(is_usd):  # a USD file is opened once: read, then its skeletons listed
        motion = read.read(source)
        skeletons = _skeletons(source) if is_usd else None
    summary = {"file": str(source), **describe(motion)}
    guessed = [o for o, v in (("units", read.units), ("up_axis", read.up_axis)) if v is None or v == "auto"]
    if source.suffix.lower() == ".bvh" and guessed:  # BVH states neither: say what the body says
        from usdmotion.units_guess import guess_body

        guess = guess_body(motion, up="up_axis" in guessed)
        summary["guessed"] = {o: {"value": getattr(guess, o), "reason": getattr(guess, f"{o.split('_')[0]}_reason")}
                              for o in guessed}
    if is_usd:
        summary["skeletons"] = skeletons
        summary["meshes"] = [{"name": m.name, "points": len(m.points), "blend_shapes": [b.name for b in m.blend_shapes]}
                             for m in motion.meshes]
    if as_json:
        typer.echo(json.dumps(summary, indent=2))
        return
    _print_summary(summary)


def _one_stage(is_usd: bool):
    """A context in which opening the same USD file again finds the stage already open
    (``Usd.StageCacheContext``), or nothing to do for other formats."""
    if not is_usd:
        return contextlib.nullcontext()
    from pxr import Usd

    return Usd.StageCacheContext(Usd.StageCache())


def _skeletons(source) -> list[str]:
    """The Skeleton prim paths of the stage at ``source`` (the one ``read`` opened, in the cache)."""
    from usdmotion.io.usd import _open_stage
    from usdmotion.io.usd_read import list_skeletons
    from usdmotion.usd_diagnostics import usd_diagnostics

    with warnings.catch_warnings(), usd_diagnostics(source):  # what USD says was said by read()
        warnings.simplefilter("ignore")
        return list_skeletons(_open_stage(source))


def _print_summary(s: dict) -> None:
    from rich.console import Console
    from rich.tree import Tree

    console = Console()
    unit = f"1 {s['units']}" if s["units"] else f"{s['meters_per_unit']:g} m"
    console.print(f"[bold]{s['file']}[/bold]")
    console.print(f"  joints      {s['joints']} (+{s['end_sites']} end sites), {s['channels']} channels, "
                  f"rotation orders {', '.join(f'{k}×{v}' for k, v in s['rotation_orders'].items()) or '-'}")
    console.print(f"  frames      {s['frames']} at {s['fps']:.6g} fps (frame time {s['frame_time']:.6g} s), "
                  f"duration {s['duration_s']:.3f} s")
    console.print(f"  units       1 unit = {unit.removeprefix('1 ')} ({s['meters_per_unit']:g} m), {s['up_axis']}-up, "
                  f"root offset {s['root_offset']}, rest extent {s['rest_extent']:.4g} units "
                  f"({s['rest_extent_m']:.3g} m)")
    for option, g in s.get("guessed", {}).items():
        what = "units" if option == "units" else "up axis"
        console.print(f"  guessed     {what} {g['value'] or 'none (kept)'}: {g['reason']}", highlight=False)
    if len(s.get("skeletons", [])) > 1:
        console.print(f"  skeletons   {', '.join(s['skeletons'])} (choose with --skeleton)")
    for m in s.get("meshes", []):
        shapes = f", blend shapes {', '.join(m['blend_shapes'])}" if m["blend_shapes"] else ""
        console.print(f"  mesh        {m['name']}: {m['points']} points skinned to the skeleton{shapes}")
    if s["joints_with_position_channels"]:
        names = s["joints_with_position_channels"]
        console.print(f"  positions   on {len(names)} non-root joints: {', '.join(names[:6])}"
                      + (" …" if len(names) > 6 else ""))
    nodes: dict[str, Tree] = {}
    tree = None
    for joint in s["hierarchy"]:
        label = joint["name"] + (" [dim](end site)[/dim]" if joint["end_site"] else
                                 f" [dim]{' '.join(c[:4] for c in joint['channels'])}[/dim]")
        if joint["parent"] is None:
            tree = nodes[joint["name"]] = Tree(label)
        else:
            nodes[joint["name"]] = nodes[joint["parent"]].add(label)
    console.print(tree)

"""``usdmotion retarget SOURCE OUT``: move a motion onto another joint hierarchy."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import InputPath, ReadOptions, UpAxisChoice, reads_motion
from usdmotion.cli._progress import progress
from usdmotion.cli.app import app


class Method(str, Enum):
    lm = "lm"
    adam = "adam"


class Lengths(str, Enum):
    source = "source"
    target = "target"


class Directions(str, Enum):
    auto = "auto"
    mean = "mean"
    rest = "rest"


class RootScale(str, Enum):
    off = "off"
    legs = "legs"


class Init(str, Enum):
    auto = "auto"
    copy = "copy"
    compose = "compose"
    aim = "aim"


def _names(values: list[str] | None) -> list[str]:
    return [n.strip() for v in values or [] for n in v.split(",") if n.strip()]


@app.command()
@reads_motion
def retarget(
    source: InputPath,
    output: Annotated[Path, typer.Argument(help="Output: .bvh, .usda, .usdc, .usdz or .usd.", show_default=False)],
    target: Annotated[Path | None, typer.Option(help="Target skeleton: a BVH or UsdSkel file (its motion is ignored).",
                                                show_default=False)] = None,
    remove: Annotated[list[str] | None, typer.Option(
        help="Joint(s) to remove; children move to the parent. Repeat or separate with commas.",
        show_default=False)] = None,
    add: Annotated[list[str] | None, typer.Option(help="Joint to add: NAME:PARENT:X,Y,Z[:CHILD,...] (offset in target "
                                                       "units; listed children of PARENT move under it). Repeatable.",
                                                  show_default=False)] = None,
    map_file: Annotated[Path | None, typer.Option("--map", help="Joint map JSON (schemas/jointmap.schema.json). "
                                                               "Default: automatic.", show_default=False)] = None,
    method: Annotated[Method, typer.Option(help="lm: batched Levenberg-Marquardt (default); adam: the paper's "
                                                "per-frame Adam, lr 0.1, 500 iterations (reference).")] = Method.lm,
    iterations: Annotated[int | None, typer.Option(help="lm: at most this many (default 100; stops when converged; "
                                                        "with contacts: after the plain solve); "
                                                        "adam: exactly this many (default 500).",
                                                   show_default=False, min=0)] = None,
    lengths: Annotated[Lengths, typer.Option(help="Bone lengths: 'source' (mean source distance, the paper's step 1) "
                                                  "or 'target' (keep the target rig's).")] = Lengths.source,
    directions: Annotated[Directions, typer.Option(help="Bone directions of a derived rig: 'mean' source direction in "
                                                        "the new parent's frame (auto) or 'rest' pose (the paper).")]
    = Directions.auto,
    scale: Annotated[str, typer.Option(help="Source size: 'units' (physical size; checks the units agree), 'auto' "
                                            "(fit to the target's size) or a factor (within 2x of auto's).")] = "units",
    init: Annotated[Init, typer.Option(help="Initial rotations: copied/composed from the source, or aimed at it.")]
    = Init.auto,
    local: Annotated[bool, typer.Option(help="Optimise only joints around changed bones (derived rigs).")] = False,
    report: Annotated[Path | None, typer.Option(help="Write the JSON report here.", show_default=False)] = None,
    contacts: Annotated[str | None, typer.Option(
        help="Foot contacts for the contact-aware solve: 'auto' (detected in the source; the default with "
             "--target), 'off' (the default for --remove/--add) or a contacts JSON (usdmotion contacts --json).",
        show_default=False)] = None,
    root_scale: Annotated[RootScale, typer.Option(help="Scale the root trajectory by the target/source leg-length "
                                                       "ratio (with contacts).")] = RootScale.off,
    compare: Annotated[bool, typer.Option(help="With contacts, also solve without them and add the plain solve's "
                                               "and rotation copying's figures to the report.")] = True,
    target_units: Annotated[str | None, typer.Option(help="Length unit of a BVH target (default cm).",
                                                     show_default=False)] = None,
    target_up_axis: Annotated[UpAxisChoice | None, typer.Option(help="Vertical axis of a BVH target (default Y).",
                                                                show_default=False, case_sensitive=False)] = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Retarget a motion onto a target skeleton, or onto its own with joints removed/added."""
    from usdmotion.ops.retarget.files import retarget_files
    from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache

    enable_compilation_cache()
    motion = drop_meshes(read.read(source), source)
    target_motion = None if target is None else ReadOptions(target_units, None if target_up_axis is None else target_up_axis.value).read(target)
    with progress("retargeting", total=motion.n_frames, unit="frames") as update:
        line = retarget_files(motion, source, output, target_motion, target, _names(remove), add or [], map_file,
                              method.value, iterations, lengths.value, directions.value, scale, init.value, local,
                              report, update, contacts=contacts, root_scale=root_scale.value,
                              compare=compare and report is not None)
    typer.echo(line)


def drop_meshes(motion, source):
    """``motion`` without its skinned meshes, said in a warning: retarget changes the
    skeleton they are bound to (a target USD's own meshes are kept with its skeleton)."""
    if not motion.meshes:
        return motion
    import dataclasses
    import warnings

    from usdmotion.errors import UsdMotionWarning

    warnings.warn(f"{source}: skinned meshes ({', '.join(m.name for m in motion.meshes)}) left out: retarget "
                  "changes the skeleton they are bound to", UsdMotionWarning, stacklevel=2)
    return dataclasses.replace(motion, meshes=())

"""``usdmotion positions FILE``: world joint positions from our forward kinematics."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Annotated

import typer

from usdmotion.cli._options import InputPath, Json, ReadOptions, reads_motion
from usdmotion.cli.app import app

if TYPE_CHECKING:
    import numpy as np


def parse_frames(spec: str, n_frames: int) -> np.ndarray:
    """Frame indices from ``"all"``, ``"0,10,20"``, ``"100:200"`` or ``"0:100:10"`` (end exclusive)."""
    import numpy as np  # deferred: loading the CLI (every command, --version) must not import NumPy

    spec = spec.strip().lower()
    if spec == "all":
        return np.arange(n_frames)
    frames: list[int] = []
    for part in spec.split(","):
        part = part.strip()
        try:
            if ":" in part:
                bits = [int(b) if b.strip() else None for b in part.split(":")]
                frames.extend(range(n_frames)[slice(*bits)])
            else:
                frames.append(int(part))
        except ValueError:
            raise ValueError(f"--frames: {part!r} is not a frame number, a range a:b[:step] or 'all'") from None
    bad = [f for f in frames if not 0 <= f < n_frames]
    if bad:
        raise ValueError(f"--frames: frame {bad[0]} is outside 0..{n_frames - 1}")
    return np.asarray(frames, dtype=np.int64)


@app.command()
@reads_motion
def positions(
    source: InputPath,
    frames: Annotated[str, typer.Option(help="Frames: 'all', '0,10,20', '100:200' or '0:1000:10'.")] = "0",
    joints: Annotated[str | None, typer.Option(help="Comma-separated joint names (default: all).")] = None,
    as_json: Json = False,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Print world joint positions (file units; stage units for USD) at chosen frames."""
    import numpy as np  # deferred, see parse_frames

    from usdmotion.kinematics import joint_positions

    motion = read.read(source)
    selected = parse_frames(frames, motion.n_frames)
    names = list(motion.joint_names) if joints is None else [n.strip() for n in joints.split(",")]
    index = [motion.joint_index(n) for n in names]
    world = joint_positions(motion)[selected][:, index]
    if as_json:
        typer.echo(json.dumps({"file": str(source), "meters_per_unit": motion.meters_per_unit,
                               "up_axis": motion.up_axis, "frames": selected.tolist(), "joints": names,
                               "positions": np.round(world, 9).tolist()}))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table("frame", "joint", "x", "y", "z", title=f"{source.name}: world positions "
                                                          f"({motion.meters_per_unit:g} m/unit)")
    for i, f in enumerate(selected):
        for k, name in enumerate(names):
            table.add_row(str(f), name, *(f"{v:.4f}" for v in world[i, k]))
    Console().print(table)

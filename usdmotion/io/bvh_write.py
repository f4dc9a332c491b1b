"""BVH writing: ``Motion`` → channel values → text (the inverse of :mod:`usdmotion.io.bvh`).

A motion read from BVH is written back with the channel layout and Euler orders it was
read with; other motions get :func:`usdmotion.channels.default_channels`.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import numpy as np

from usdmotion.channels import channel_columns, default_channels, euler_columns, rotation_order
from usdmotion.errors import UsdMotionWarning
from usdmotion.io.atomic import atomic_output
from usdmotion.io.bvh_header import frame_time_text
from usdmotion.motion import POSITION_CHANNELS, ROTATION_CHANNELS, Motion
from usdmotion.rotations import quat_to_euler



def channel_values(motion: Motion, channels: tuple[tuple[str, ...], ...]) -> np.ndarray:
    """Channel values ``(F, C)`` (degrees, file units) of a motion for a channel layout.

    Euler angles take the branch closest to ``motion.source_channels`` when it matches
    the layout (lossless round trips), else are unwrapped over time.
    """
    columns = channel_columns(channels)
    n_channels = sum(len(c) for c in channels)
    out = np.zeros((motion.n_frames, n_channels))
    translations = motion.joint_translations
    for j, names in enumerate(channels):
        if not any(n in POSITION_CHANNELS for n in names):
            continue
        if j == 0:
            pos = motion.root_translation - (motion.offsets[0] if motion.root_offset == "add" else 0.0)
        else:
            pos = motion.offsets[j][None] if translations is None else translations[:, j]
        for axis, name in enumerate(POSITION_CHANNELS):
            if name in columns[j]:
                out[:, columns[j][name]] = np.broadcast_to(pos[:, axis] if pos.ndim == 2 else pos[0, axis],
                                                           (motion.n_frames,))
    reference = motion.source_channels
    if reference is not None and (motion.channels != channels or reference.shape[1] != n_channels):
        reference = None
    groups: dict[str, list[int]] = {}
    for j, names in enumerate(channels):
        if any(n in ROTATION_CHANNELS for n in names):
            groups.setdefault(rotation_order(names), []).append(j)
    for order, joints in groups.items():
        cols = np.stack([euler_columns(columns[j], order, -1) for j in joints])  # (G, 3)
        ref = None
        if reference is not None:
            ref = np.deg2rad(np.where(cols[None] >= 0, reference[:, np.maximum(cols, 0)], 0.0))
        angles = np.rad2deg(quat_to_euler(motion.rotations[:, joints], order, reference=ref))
        present = cols >= 0
        frame_idx = np.arange(motion.n_frames)[:, None]
        for g in range(len(joints)):
            out[frame_idx, cols[g][present[g]][None]] = angles[:, g][:, present[g]]
    return out


def _dfs_order(parents: np.ndarray) -> list[int]:
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(int(p), []).append(j)
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children.get(j, [])))
    return order


def _fmt(x: float, decimals: int = 9) -> str:
    """Shortest text that reads back as ``x`` rounded to ``decimals`` (no ``-0``)."""
    return repr(round(float(x), decimals) + 0.0)


def bvh_text(motion: Motion, decimals: int = 9) -> str:
    """The BVH file for a motion, as text (``\\n`` line ends).

    A motion read from BVH is written with its own layout and root-offset convention. A
    motion without a layout (USD, synthesis) gets :func:`default_channels` and a zero
    root OFFSET with absolute root positions, which readers of either root-offset
    convention interpret the same way.
    """
    if motion.channels is None:
        offsets = motion.offsets.copy()
        offsets[0] = 0.0
        motion = dataclasses.replace(motion, offsets=offsets, root_offset="add",
                                     channels=default_channels(motion), source_channels=None)
    channels = motion.channels
    order = _dfs_order(motion.parents)
    lines = ["HIERARCHY"]
    depth_of = {0: 0}
    open_stack: list[int] = []
    column_order: list[int] = []
    starts = np.cumsum([0] + [len(c) for c in channels])
    for j in order:
        parent = int(motion.parents[j])
        while open_stack and open_stack[-1] != parent:
            open_stack.pop()
            lines.append("  " * len(open_stack) + "}")
        depth = len(open_stack)
        depth_of[j] = depth
        pad = "  " * depth
        offset = " ".join(_fmt(v, decimals) for v in motion.offsets[j])
        if motion.end_sites[j] and not channels[j]:
            lines += [f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {offset}"]
        else:
            keyword = "ROOT" if j == 0 else "JOINT"
            lines += [f"{pad}{keyword} {motion.joint_names[j]}", f"{pad}{{", f"{pad}  OFFSET {offset}"]
            if channels[j] or j == 0:
                lines.append(f"{pad}  CHANNELS {len(channels[j])} {' '.join(channels[j])}".rstrip())
            column_order.extend(range(starts[j], starts[j + 1]))
        open_stack.append(j)
    while open_stack:
        open_stack.pop()
        lines.append("  " * len(open_stack) + "}")
    values = channel_values(motion, channels)[:, column_order]
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {frame_time_text(motion.fps)}"]
    return "\n".join(lines) + "\n" + _rows_text(np.round(values, decimals) + 0.0)


def _rows_text(values: np.ndarray) -> str:
    """Rows of space-separated shortest round-trip floats (pyarrow's CSV writer)."""
    if values.size == 0:
        return ""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    # Arrays built from the columns' buffers: pa.table(numpy columns) would import pandas.
    columns = [np.ascontiguousarray(values[:, k], dtype=np.float64) for k in range(values.shape[1])]
    table = pa.Table.from_arrays([pa.Array.from_buffers(pa.float64(), len(c), [None, pa.py_buffer(c)]) for c in columns],
                                 names=[f"c{k}" for k in range(len(columns))])
    sink = pa.BufferOutputStream()
    pcsv.write_csv(table, sink, write_options=pcsv.WriteOptions(include_header=False, delimiter=" ",
                                                                 quoting_style="none"))
    return sink.getvalue().to_pybytes().decode("ascii")


def bvh_names(names: tuple[str, ...]) -> tuple[str, ...]:
    """``names`` as a BVH file can hold them: a name reads back as its words joined by one
    space up to a brace, so runs of whitespace become one space, braces ``_``, and an empty
    name ``joint<J>``; a name that then repeats another gets ``_<J>``."""
    out: list[str] = []
    for j, name in enumerate(names):
        text = " ".join(name.replace("{", "_").replace("}", "_").split()) or f"joint{j}"
        out.append(f"{text}_{j}" if text != name and text in names or text in out else text)
    return tuple(out)


def write_bvh(motion: Motion, path: str | os.PathLike, decimals: int = 9) -> Path:
    """Write ``motion`` as BVH (atomically: temp file, then rename).

    Uses the channel layout the motion was read with (``motion.channels``), else
    :func:`default_channels`; joints are written in depth-first order. Values are
    rounded to ``decimals`` decimals. Joint names a BVH file cannot hold (from USD or
    glTF: empty, braces, line breaks) are written as :func:`bvh_names` makes them, with a warning.
    """
    path = Path(path)
    names = bvh_names(motion.joint_names)
    if names != motion.joint_names:
        changed = [f"{old!r} -> {new!r}" for old, new in zip(motion.joint_names, names) if old != new]
        warnings.warn(f"{path}: {len(changed)} joint names written as BVH can hold them: {', '.join(changed[:3])}"
                      f"{' …' if len(changed) > 3 else ''}", UsdMotionWarning, stacklevel=2)
        motion = dataclasses.replace(motion, joint_names=names)
    text = bvh_text(motion, decimals=decimals)
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path

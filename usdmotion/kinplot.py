"""Figures where people look rather than read (matplotlib, Agg, no pyplot state).

* :func:`plot_kinematics` — joint-angle curves, speed curves, and top and side views of
  joint and COM trajectories, in one PNG/PDF/SVG.
* :func:`plot_strip` — a stick figure over time: all frames overlaid ("chronophotograph")
  plus a strip of small multiples, e.g. the synthesised giant swing.

Views: "top" looks down the up axis; "side" plots the forward direction (the principal
horizontal direction of the motion) against height.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError
from usdmotion.io.atomic import atomic_output
from usdmotion.kinematics import joint_positions
from usdmotion.motion import Motion
from usdmotion.ops.analyse.measures import Kinematics

IMAGE_FORMATS = (".png", ".pdf", ".svg")


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def image_path(path: str | os.PathLike) -> Path:
    """``path`` if its extension is an image format we write, else ``OutputError``."""
    path = Path(path)
    if path.suffix.lower() not in IMAGE_FORMATS:
        raise OutputError(f"{path}: unknown image format {path.suffix!r} (use {', '.join(IMAGE_FORMATS)})")
    return path


def _save(make_figure, path: str | os.PathLike) -> Path:
    path = image_path(path)
    fig = make_figure()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lower()[1:])
    return path


def view_axes(points: np.ndarray, up_axis: str) -> tuple[np.ndarray, int]:
    """``(forward (3,), up index)``: the principal horizontal direction of ``points (N, 3)``."""
    up = 1 if up_axis == "Y" else 2
    horizontal = [a for a in range(3) if a != up]
    flat = points.reshape(-1, 3)[:, horizontal]
    flat = flat[np.all(np.isfinite(flat), axis=1)]
    forward = np.zeros(3)
    if len(flat) > 1 and np.ptp(flat, axis=0).max() > 0:
        _, _, vt = np.linalg.svd(flat - flat.mean(axis=0), full_matrices=False)
        direction = vt[0]
        if direction[np.argmax(np.abs(direction))] < 0:
            direction = -direction
        forward[horizontal] = direction
    else:
        forward[horizontal[0]] = 1.0
    return forward, up


def default_plot_joints(kin: Kinematics) -> tuple[list[int], list[int]]:
    """``(angle joints, speed/trajectory joints)`` for a figure.

    Knees and elbows (their bend is the flexion angle) and wrists and ankles when the
    body model found them; otherwise the four joints with the largest bend range and the
    four non-end-site joints with the highest peak speed.
    """
    names = kin.joint_names
    if kin.body is not None and "left_knee" in kin.body.landmarks:
        marks = kin.body.landmarks
        angle = [names.index(marks[k]) for k in ("left_knee", "right_knee", "left_elbow", "right_elbow")]
        moving = [names.index(marks[k]) for k in ("left_wrist", "right_wrist", "left_ankle", "right_ankle")]
        return angle, moving
    with np.errstate(invalid="ignore"):
        bend_range = np.where(np.all(np.isfinite(kin.bend), axis=0), np.ptp(np.nan_to_num(kin.bend), axis=0), -1)
    angle = [int(j) for j in np.argsort(-bend_range)[:4] if bend_range[j] >= 0]
    speed = np.linalg.norm(kin.velocities, axis=-1).max(axis=0)
    speed[kin.end_sites] = -1
    moving = [int(j) for j in np.argsort(-speed)[:4]]
    return angle, moving


def plot_kinematics(kin: Kinematics, path: str | os.PathLike, joints: list[int] | None = None,
                    title: str | None = None) -> Path:
    """Joint angles, speeds and trajectories of ``kin`` in one figure (PNG/PDF/SVG)."""
    return _save(lambda: kinematics_figure(kin, joints, title), path)


def kinematics_figure(kin: Kinematics, joints: list[int] | None = None, title: str | None = None):
    """The figure of :func:`plot_kinematics` (a ``matplotlib.figure.Figure``; axes: angles,
    speed, top view, side view)."""
    angle_joints, moving = default_plot_joints(kin) if not joints else (list(joints), list(joints))
    fig = _figure(12, 10)
    grid = fig.add_gridspec(3, 2, height_ratios=[1.2, 1, 1])
    ax_angle, ax_speed = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])
    ax_top, ax_side = fig.add_subplot(grid[1, :]), fig.add_subplot(grid[2, :])
    unit = kin.length_unit
    for j in angle_joints:
        if np.all(np.isfinite(kin.bend[:, j])):
            ax_angle.plot(kin.time, kin.bend[:, j], label=f"{kin.joint_names[j]} bend")
        elif not kin.end_sites[j]:
            for k, axis in enumerate("XYZ"):
                ax_angle.plot(kin.time, kin.euler[:, j, k], ls="--", lw=1, label=f"{kin.joint_names[j]} {axis}")
    ax_angle.set(title="joint angles", xlabel="time (s)", ylabel="angle (deg)")
    for j in moving:
        ax_speed.plot(kin.time, np.linalg.norm(kin.velocities[:, j], axis=1), label=kin.joint_names[j])
    tracks = [(kin.joint_names[j], kin.positions[:, j]) for j in moving]
    if kin.com is not None:
        ax_speed.plot(kin.time, np.linalg.norm(kin.com_velocity, axis=1), color="k", lw=2, label="COM")
        tracks.append(("COM", kin.com))
    ax_speed.set(title="speed", xlabel="time (s)", ylabel=f"speed ({unit}/s)")
    forward, up = view_axes(np.stack([t for _, t in tracks], axis=1), kin.up_axis)
    lateral = np.cross(np.eye(3)[up], forward)
    for name, track in tracks:
        style = dict(color="k", lw=2) if name == "COM" else dict(lw=1)
        ax_top.plot(track @ forward, track @ lateral, label=name, **style)
        ax_side.plot(track @ forward, track[:, up], label=name, **style)
    ax_top.set(title="top view", xlabel=f"forward ({unit})", ylabel=f"lateral ({unit})")
    ax_side.set(title="side view", xlabel=f"forward ({unit})", ylabel=f"height ({unit})")
    for ax in (ax_top, ax_side):
        ax.set_aspect("equal", adjustable="datalim")
    for ax in (ax_angle, ax_speed, ax_top, ax_side):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title)
    return fig


def _bones(motion: Motion, positions: np.ndarray) -> list[tuple[int, int]]:
    rest = positions[0]
    return [(int(p), j) for j, p in enumerate(motion.parents) if p >= 0
            and np.linalg.norm(rest[j] - rest[p]) > 0]


def plot_strip(motion: Motion, path: str | os.PathLike, frames: list[int] | None = None, columns: int = 12,
               title: str | None = None, mark_origin: bool = False) -> Path:
    """Stick figure of ``motion``: every frame overlaid, then a strip of small multiples.

    Side view (forward direction against height, see :func:`view_axes`). ``mark_origin``
    draws a dot at the world origin (the bar of the giant swing).
    """
    return _save(lambda: strip_figure(motion, frames, columns, title, mark_origin), path)


def strip_figure(motion: Motion, frames: list[int] | None = None, columns: int = 12, title: str | None = None,
                 mark_origin: bool = False):
    """The figure of :func:`plot_strip`; its first axes hold one line per bone and frame
    (in frame order), then one dotted trajectory per leaf joint."""
    from matplotlib import cm

    positions = joint_positions(motion)
    forward, up = view_axes(positions, motion.up_axis)
    u, v = positions @ forward, positions[..., up]
    bones = _bones(motion, positions)
    picked = list(range(motion.n_frames)) if frames is None else list(frames)
    shown = picked if len(picked) <= columns else [picked[int(round(i))] for i in np.linspace(0, len(picked) - 1,
                                                                                              columns)]
    fig = _figure(max(8.0, 1.1 * len(shown)), 7.5)
    grid = fig.add_gridspec(2, len(shown), height_ratios=[3, 1])
    ax = fig.add_subplot(grid[0, :])
    colors = cm.viridis(np.linspace(0, 1, len(picked)))
    for color, f in zip(colors, picked):
        for a, b in bones:
            ax.plot([u[f, a], u[f, b]], [v[f, a], v[f, b]], color=color, lw=1.5, alpha=0.8)
    leaves = [j for j in range(motion.n_joints) if j not in motion.parents]
    for j in leaves:
        ax.plot(u[picked, j], v[picked, j], color="0.4", lw=0.8, ls=":")
    if mark_origin:
        ax.plot([0], [0], "ko", ms=6)
    unit = f"{motion.meters_per_unit:g} m"
    ax.set(aspect="equal", xlabel=f"forward (units of {unit})", ylabel=f"height (units of {unit})",
           title=title or f"{motion.n_frames} frames at {motion.fps:g} fps (colour = time)")
    ax.grid(alpha=0.3)
    span = max(np.ptp(u), np.ptp(v)) * 0.55 + 1e-9
    cu, cv = 0.5 * (u.max() + u.min()), 0.5 * (v.max() + v.min())
    for k, f in enumerate(shown):
        small = fig.add_subplot(grid[1, k])
        for a, b in bones:
            small.plot([u[f, a], u[f, b]], [v[f, a], v[f, b]], color=colors[picked.index(f)], lw=2)
        if mark_origin:
            small.plot([0], [0], "k.", ms=4)
        small.set(xlim=(cu - span, cu + span), ylim=(cv - span, cv + span), aspect="equal", xticks=[], yticks=[])
        small.set_title(f"{f / motion.fps:.2f} s", fontsize=7)
    return fig

"""Foot contacts as files: the JSON form (``schemas/contacts.schema.json``), the summary
table and the plot of heights and speeds with contact bands."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from usdmotion.constants import MAX_FRAMES
from usdmotion.errors import InputError, OutputError
from usdmotion.io.atomic import atomic_output
from usdmotion.motion import Motion
from usdmotion.ops.contacts.detect import ContactThresholds, FootContacts, check_floor_below_feet, contact_signals

#: Image formats of the plot.
IMAGE_FORMATS = (".png", ".pdf", ".svg")


def contact_summary(contacts: FootContacts) -> list[dict]:
    """Per contact joint: ``name``, ``part``, ``contacts`` (intervals), ``contact_time_s``,
    ``mean_duration_s``, ``intervals`` (``[start, stop)`` frame lists)."""
    rows = []
    for c, (name, part) in enumerate(zip(contacts.joints, contacts.parts)):
        spans = contacts.intervals(c)
        frames = int((spans[:, 1] - spans[:, 0]).sum())
        rows.append({"name": name, "part": part, "contacts": int(len(spans)),
                     "contact_time_s": frames / contacts.fps,
                     "mean_duration_s": frames / contacts.fps / len(spans) if len(spans) else 0.0,
                     "intervals": spans.tolist()})
    return rows


def summary_table(contacts: FootContacts, file: str) -> str:
    """The table ``usdmotion contacts`` prints: a header line, then joint, part, contacts,
    total and mean contact time per contact joint."""
    lines = [f"{file}: {contacts.n_frames} frames at {contacts.fps:g} fps, floor {contacts.floor:.3f} m "
             f"({contacts.up}-up)", f"{'joint':<24} {'part':<12} {'contacts':>8} {'time s':>8} {'mean s':>8}"]
    lines += [f"{r['name']:<24} {r['part']:<12} {r['contacts']:>8} {r['contact_time_s']:>8.3f} "
              f"{r['mean_duration_s']:>8.3f}" for r in contact_summary(contacts)]
    return "\n".join(lines)


def contacts_document(contacts: FootContacts, file: str | None = None) -> dict:
    """The JSON document of ``contacts`` (valid against the ``contacts`` schema)."""
    joints = [{"name": r["name"], "part": r["part"], "clearance_m": float(contacts.clearance[c]),
               "intervals": r["intervals"], "contacts": r["contacts"],
               "contact_time_s": round(r["contact_time_s"], 6), "mean_duration_s": round(r["mean_duration_s"], 6)}
              for c, r in enumerate(contact_summary(contacts))]
    doc = {"format": "usdmotion-contacts", "version": 1, "file": file, "fps": contacts.fps,
           "frames": contacts.n_frames, "up_axis": contacts.up, "floor_m": contacts.floor, "joints": joints}
    if contacts.thresholds is not None:
        doc["thresholds"] = contacts.thresholds.as_dict()
    return doc


def write_contacts_json(contacts: FootContacts, path: str | os.PathLike, file: str | None = None) -> None:
    """Write the contacts JSON atomically."""
    text = re.sub(r"\[\s*(\d+),\s*(\d+)\s*\]", r"[\1, \2]", json.dumps(contacts_document(contacts, file), indent=1))
    with atomic_output(path) as tmp:
        Path(tmp).write_text(text + "\n", encoding="utf-8")


def read_contacts_json(path: str | os.PathLike, motion: Motion | None = None) -> FootContacts:
    """Contacts from a JSON file; with ``motion``, checked against it (joint names, frame count).

    Raises:
        InputError: unreadable or invalid file, intervals out of order or past the last
            frame, joints or frame counts that do not fit ``motion``.
    """
    from usdmotion.schemas import load_document

    doc = load_document(path, "contacts")
    frames, joints = int(doc["frames"]), doc["joints"]  # JSON Schema's integers include 480.0
    names = tuple(j["name"] for j in joints)
    if len(set(names)) != len(names):
        raise InputError(path, "/joints: a joint is listed twice")
    if motion is not None:
        _check_fits(path, doc, names, motion)
    elif frames > MAX_FRAMES:
        raise InputError(path, f"/frames: {frames} frames; at most {MAX_FRAMES} are supported")
    contact = np.zeros((frames, len(joints)), bool)
    for c, joint in enumerate(joints):
        last = 0
        for k, (start, stop) in enumerate((int(a), int(b)) for a, b in joint["intervals"]):
            if not last <= start < stop <= frames:
                raise InputError(path, f"/joints/{c}/intervals/{k}: [{start}, {stop}] is not a sorted, "
                                       f"non-overlapping frame range within 0..{frames}")
            contact[start:stop, c] = True
            last = stop
    clearance = np.array([j["clearance_m"] for j in joints], float)
    if motion is not None:
        indices = np.array([motion.joint_names.index(n) for n in names], np.int64)
        _check_levels(path, float(doc["floor_m"]), clearance, names, indices, motion)
    else:
        indices = np.full(len(names), -1, np.int64)
    try:
        thresholds = ContactThresholds(**doc["thresholds"]) if "thresholds" in doc else None
    except ValueError as exc:
        raise InputError(path, f"/thresholds: {exc}") from None
    return FootContacts(names, indices, tuple(j["part"] for j in joints), contact, float(doc["floor_m"]),
                        clearance, doc["up_axis"], float(doc["fps"]), thresholds)


def _check_fits(path, doc: dict, names: tuple[str, ...], motion: Motion) -> None:
    missing = [n for n in names if n not in motion.joint_names]
    if missing:
        raise InputError(path, f"/joints: the motion has no joint named {missing[0]!r}")
    if doc["frames"] != motion.n_frames:
        raise InputError(path, f"/frames: the contacts are for {doc['frames']} frames, the motion has "
                               f"{motion.n_frames}")
    if doc["up_axis"] != motion.up_axis:
        raise InputError(path, f"/up_axis: the contacts are {doc['up_axis']}-up, the motion is {motion.up_axis}-up")


def _check_levels(path, floor: float, clearance: np.ndarray, names: tuple[str, ...], indices: np.ndarray,
                  motion: Motion) -> None:
    """The file's floor (m) and planted levels (``floor + clearance (C,)``) against where
    ``motion``'s contact joints ``indices`` go."""
    from usdmotion.kinematics import joint_positions

    heights, _ = contact_signals(joint_positions(motion)[:, indices] * motion.meters_per_unit, motion.fps,
                                 motion.up_axis)
    # a floor_m of 1e20 planted the retarget's feet 1e20 m up (exit 0, a warning); each joint's planted
    # level (floor + clearance) likewise must not lie above everywhere that joint goes
    check_floor_below_feet(heights, floor, motion.up_axis, str(path), "/floor_m:")
    level = floor + clearance
    above = np.flatnonzero(~(level <= heights.max(axis=0)))
    if above.size:
        c = int(above[0])
        raise InputError(path, f"/joints/{c}/clearance_m: planted at {level[c]:g} m, above everywhere "
                               f"{names[c]} goes (at most {heights[:, c].max():.3f} m)")


def plot_path(path: str | os.PathLike) -> Path:
    """``path`` if its extension is an image format the plot is written in, else ``OutputError``."""
    path = Path(path)
    if path.suffix.lower() not in IMAGE_FORMATS:
        raise OutputError(f"{path}: unknown image format {path.suffix!r} (use {', '.join(IMAGE_FORMATS)})")
    return path


def plot_contacts(motion: Motion, contacts: FootContacts, path: str | os.PathLike, title: str = "") -> None:
    """Heights above the floor (cm) and speeds (m/s) of the contact joints over time, with
    their contact frames as bands (one row per joint); PNG, SVG or PDF."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from usdmotion.kinematics import joint_positions

    path = plot_path(path)
    positions = joint_positions(motion)[:, contacts.indices] * motion.meters_per_unit
    heights, speeds = contact_signals(positions, motion.fps, contacts.up)
    t = np.arange(motion.n_frames) / motion.fps
    n = len(contacts.joints)
    fig = Figure(figsize=(10, 1.6 * n + 0.8), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    for c, ax in enumerate(axes):
        ax.plot(t, (heights[:, c] - contacts.floor) * 100.0, color="tab:blue", lw=1)
        ax.set_ylabel(f"{contacts.joints[c]}\nheight cm", fontsize=8, color="tab:blue")
        speed_ax = ax.twinx()
        speed_ax.plot(t, speeds[:, c], color="tab:orange", lw=0.8)
        speed_ax.set_ylabel("m/s", fontsize=8, color="tab:orange")
        speed_ax.set_ylim(0, 1.2 * max(float(np.percentile(speeds[:, c], 98)), 2 * (contacts.thresholds or
                                                                                 ContactThresholds()).speed_exit))
        for start, stop in contacts.intervals(c):
            ax.axvspan(start / motion.fps, stop / motion.fps, color="tab:green", alpha=0.25, lw=0)
    axes[-1].set_xlabel("time (s); green: contact")
    fig.suptitle(title or f"foot contacts (floor {contacts.floor:.3f} m)", fontsize=10)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lower().lstrip("."))

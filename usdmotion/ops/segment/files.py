"""Outputs of a segmentation: ``segments.json``, the signal plot, and one clip per segment.

Every file goes through :func:`usdmotion.io.atomic.atomic_output` (or the atomic
motion writers), so a failure never leaves a partial file.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError
from usdmotion.io import write_motion
from usdmotion.io.atomic import atomic_output
from usdmotion.motion import Motion
from usdmotion.ops.segment.roles import LIMB_BONES
from usdmotion.ops.segment.detect import LOW_CONFIDENCE, Segmentation, clip
from usdmotion.progress import Progress, no_progress

CLIP_FORMATS = ("bvh", "usda", "usdc")
#: Longest segment label kept in a segments file (characters).
MAX_LABEL_CHARS = 200


def edited(seg: Segmentation, cuts: Sequence[int]) -> Segmentation:
    """``seg`` with the cuts a person placed: ``cuts`` must be increasing frames in ``1 .. n_frames-1``.

    The detector's per-cut confidence and change regions describe its own cuts, so they are
    dropped; ``edited`` is set and ``method``/``params`` keep the run the edit started from.

    Raises:
        ValueError: a cut that is not a whole frame inside the take, or cuts out of order.
    """
    values = list(cuts)
    if not all(isinstance(c, (int, np.integer)) and not isinstance(c, bool) for c in values):
        raise ValueError("cuts must be whole frame numbers")
    if not all(1 <= c <= seg.n_frames - 1 for c in values):  # before int64: 2**63 would overflow it
        raise ValueError(f"cuts must be frames within 1..{seg.n_frames - 1}")
    array = np.asarray(values, dtype=np.int64).reshape(-1)
    if np.any(np.diff(array) <= 0):
        raise ValueError("cuts must be increasing, at most one per frame")
    return dataclasses.replace(seg, cuts=array, confidence=None, regions=None, edited=True)


def segments_document(seg: Segmentation, source: str | None = None, selected: int | None = None,
                      labels: Sequence[str] | None = None) -> dict:
    """The segments JSON (``schemas/segments.schema.json``): ``seg.to_dict()`` with the input
    ``file``, the ``selected`` segment and one ``label`` per segment (empty labels left out).

    Raises:
        ValueError: ``labels`` not one single-line string per segment.
    """
    doc = {"file": source, **seg.to_dict()}
    if labels is not None:
        labels = list(labels)
        if len(labels) != len(doc["segments"]) or not all(isinstance(x, str) for x in labels):
            raise ValueError(f"need one label (text) per segment: {len(doc['segments'])} segments, "
                             f"{len(labels)} labels")
        for row, label in zip(doc["segments"], labels):
            label = " ".join(label.split())
            if len(label) > MAX_LABEL_CHARS:
                raise ValueError(f"segment {row['index']}: label longer than {MAX_LABEL_CHARS} characters")
            if label:
                row["label"] = label
    if selected is not None:
        doc["selected"] = selected
    return doc


def write_segments_json(seg: Segmentation, path: str | os.PathLike, source: str | None = None,
                        selected: int | None = None, labels: Sequence[str] | None = None) -> Path:
    """Write :func:`segments_document` as JSON (atomically)."""
    doc = segments_document(seg, source, selected, labels)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    return Path(path)


def plot_segmentation(seg: Segmentation, path: str | os.PathLike, title: str = "",
                      highlight: int | None = None) -> Path:
    """PNG/SVG/PDF: the norm signal, its low-passed version, the paper's candidates, the cuts
    (dashed; low-confidence cuts dotted purple) over shaded segments; below, the bone energy the
    cuts settle on, and the eight bone angles."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    t = np.arange(seg.n_frames) / seg.fps
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    top, middle, bottom = fig.subplots(3, 1, sharex=True, height_ratios=[3, 1.2, 2])
    for i, (a, b) in enumerate(seg.bounds()):
        color = "tab:orange" if i == highlight else ("0.92" if i % 2 else "white")
        top.axvspan(a / seg.fps, (b + 1) / seg.fps, color=color, alpha=0.35 if i == highlight else 1, lw=0)
    top.plot(t, np.degrees(seg.signal), color="0.65", lw=0.8, label="Q = ‖θ‖ (deg)")
    top.plot(t, np.degrees(seg.filtered), color="tab:blue", lw=1.4, label="low-passed Q")
    if seg.candidates is not None and seg.candidates.size:
        c = seg.candidates
        top.plot(c / seg.fps, np.degrees(seg.filtered[c]), "v", color="tab:green", ms=4,
                 label=f"paper candidates ({c.size})")
    low = np.zeros(seg.cuts.size, bool) if seg.confidence is None else seg.confidence < LOW_CONFIDENCE
    for k, c in enumerate(seg.cuts):
        top.axvline(c / seg.fps, color="tab:purple" if low[k] else "tab:red", ls=":" if low[k] else "--", lw=1.2,
                    label=f"cuts ({seg.cuts.size})" if k == 0 else None)
    if low.any():
        top.plot([], [], color="tab:purple", ls=":", label=f"low confidence ({int(low.sum())}): check")
    top.set_ylabel("norm signal (deg)")
    top.legend(loc="lower left", bbox_to_anchor=(0, 1.0), fontsize=8, ncol=4, frameon=False)
    fig.suptitle(title or f"{seg.method}: {len(seg.bounds())} segments", fontsize=10)
    if seg.energy is not None:
        middle.semilogy(t, np.maximum(seg.energy, 1e-6), color="tab:purple", lw=1)
        for c in seg.cuts:
            middle.axvline(c / seg.fps, color="tab:red", ls="--", lw=1)
    middle.set_ylabel("bone energy\n(rad²/s²)", fontsize=8)
    image = bottom.imshow(np.degrees(seg.angles.T), aspect="auto", cmap="viridis", interpolation="nearest",
                          extent=(0, seg.n_frames / seg.fps, len(LIMB_BONES) - 0.5, -0.5))
    bottom.set_yticks(range(len(LIMB_BONES)), [b[0].replace("_", " ") for b in LIMB_BONES], fontsize=7)
    for c in seg.cuts:
        bottom.axvline(c / seg.fps, color="white", ls="--", lw=1)
    bottom.set_xlabel("time (s)")
    fig.colorbar(image, ax=bottom, label="bone angle (deg)", pad=0.01)
    path = Path(path)
    with atomic_output(path) as tmp:
        try:
            fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".").lower() or "png")
        except ValueError as exc:
            raise OutputError(f"{path}: cannot write a plot: {exc}") from None
    return path


def clip_paths(seg: Segmentation, folder: Path, stem: str, fmt: str, indices: Sequence[int]) -> list[Path]:
    """File names ``<stem>_<index>_<first>-<last>.<fmt>`` of the clips of ``indices``."""
    bounds = seg.bounds()
    width = max(3, len(str(len(bounds) - 1)))
    return [folder / f"{stem}_{i:0{width}d}_{bounds[i][0]}-{bounds[i][1]}.{fmt}" for i in indices]


def export_clips(motion: Motion, seg: Segmentation, folder: str | os.PathLike, fmt: str = "bvh",
                 stem: str = "clip", indices: Sequence[int] | None = None,
                 progress: Progress = no_progress) -> list[Path]:
    """Write one motion file per segment (or per segment in ``indices``); returns the paths.

    ``progress(written, clips, message)`` after each clip."""
    if fmt not in CLIP_FORMATS:
        raise OutputError(f"unknown clip format {fmt!r} (use {', '.join(CLIP_FORMATS)})")
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{folder}: cannot create the clip folder: {exc.strerror or exc}") from None
    indices = range(len(seg.bounds())) if indices is None else indices
    paths = clip_paths(seg, folder, stem, fmt, indices)
    bounds = seg.bounds()
    for k, (i, path) in enumerate(zip(indices, paths)):
        progress(k, len(paths), f"writing {path.name}")
        write_motion(clip(motion, int(bounds[i][0]), int(bounds[i][1])), path)
    progress(len(paths), len(paths), f"wrote {len(paths)} clips")
    return paths

"""Which takes a batch processes, where their outputs go, and which are already up to date."""

from __future__ import annotations

import functools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from usdmotion.errors import InputError

#: Operation → what it writes per take (see :func:`outputs_for`).
OPERATIONS = ("convert", "analyze", "segment", "retarget", "render")
#: Take files a batch finds (an ``.amc`` motion reads its skeleton from the ``.asf`` beside it).
MOTION_SUFFIXES = (".bvh", ".amc", ".usd", ".usda", ".usdc", ".usdz", ".glb", ".gltf")
DEFAULT_INCLUDE = tuple(f"**/*{suffix}" for suffix in MOTION_SUFFIXES)
#: ``read_motion`` keyword arguments a job starts from (what the single-file commands default to).
DEFAULT_READ_OPTIONS = {"units": None, "up_axis": None, "root_offset": "auto", "lenient": False,
                        "ignore_joint_positions": False, "skeleton": None}
#: Per-operation parameters a job starts from.
DEFAULT_PARAMS = {"convert": {"to": "usdc", "mesh": False}, "analyze": {}, "segment": {"export_clips": False},
                  "retarget": {"to": "usdc"}, "render": {"size": [640, 360]}}
#: Source bytes one Dask task should hold per operation: several short takes share a task (4 MB:
#: ~27 of the 150 kB, 160-frame BVH takes of ``benchmarks/batch.py``, about 0.4 s of work on one
#: core for ``convert``, 1.1 s for ``analyze``), so the scheduler, the client and the worker's
#: event loop handle tens of tasks, not thousands: a task costs ~7 ms of CPU across the processes
#: (measured under load 3), as much as half a convert take.
#: ``0``: one take per task (the operations whose takes take seconds).
TASK_BYTES = {"convert": 4 << 20, "analyze": 4 << 20, "segment": 1 << 20, "retarget": 0, "render": 0}
FRAMES_DIR = "frames"
CATALOGUE = "catalogue.parquet"


@dataclass(frozen=True)
class Job:
    """One take to process: everything a worker needs, as plain picklable values.

    ``outputs`` maps an output role (``"motion"``, ``"summary"``, ``"frames"``...) to an
    absolute path; ``params`` are the operation's options; ``read_options`` are
    ``read_motion`` keyword arguments.
    """

    operation: str
    take: str
    source: str
    relpath: str
    outputs: dict = field(hash=False)
    read_options: dict = field(hash=False)
    params: dict = field(hash=False)

    @property
    def options_key(self) -> str:
        """The options that shape the outputs, as canonical JSON (a changed option redoes the take)."""
        return json.dumps({"read": _non_default_read_options(self.read_options), "params": self.params},
                          sort_keys=True, default=str)


def _non_default_read_options(read_options: dict) -> dict:
    """``read_options`` less those equal to ``read_motion``'s defaults (stated or not, the take reads alike)."""
    defaults = _read_motion_defaults()
    return {k: v for k, v in read_options.items() if k not in defaults or defaults[k] != v}


@functools.cache
def _read_motion_defaults() -> dict:
    import inspect

    from usdmotion.io import read_motion

    return {name: p.default for name, p in inspect.signature(read_motion).parameters.items()
            if p.default is not inspect.Parameter.empty}


def take_id(relpath: str) -> str:
    """Partition-safe id of a take: its path relative to the source folder, ``/`` → ``__``."""
    return relpath.replace("/", "__")


def find_sources(src_dir: Path, include: tuple[str, ...] = DEFAULT_INCLUDE, exclude: Path | None = None) -> list[Path]:
    """Motion files under ``src_dir`` matching any ``include`` glob, sorted; ``exclude`` (the
    output folder, when inside the source) is skipped."""
    if not src_dir.is_dir():
        raise InputError(src_dir, "source folder does not exist (or is not a folder)")
    skip = exclude.resolve() if exclude is not None else None
    suffixes = _suffix_globs(include)
    if suffixes is not None:  # the default: one walk of the tree, not one glob per suffix
        return sorted(p for p in _files_ending_with(src_dir, suffixes, skip) if p.suffix.lower() in MOTION_SUFFIXES)
    found = {p for pattern in include for p in src_dir.glob(pattern)}
    files = [p for p in found if p.is_file() and p.suffix.lower() in MOTION_SUFFIXES
             and (skip is None or not p.resolve().is_relative_to(skip))]
    return sorted(files)


def _suffix_globs(include: tuple[str, ...]) -> tuple[str, ...] | None:
    """The suffixes of ``include`` when every glob is ``**/*SUFFIX`` (a plain suffix), else ``None``."""
    import re

    matches = [re.fullmatch(r"\*\*/\*(\.[A-Za-z0-9_]+)", pattern) for pattern in include]
    return tuple(m.group(1) for m in matches) if matches and all(matches) else None


def _files_ending_with(src_dir: Path, suffixes: tuple[str, ...], skip: Path | None) -> list[Path]:
    """The files ``src_dir.glob(f"**/*{suffix}")`` finds for the ``suffixes`` (case-sensitive;
    symlinked folders not entered, as pathlib's ``**``), less those whose real path lies in
    ``skip``: one ``scandir`` walk, the real path resolved once per folder (and for symlinked
    files), not once per file (a 500-take library: 5 ms instead of 17)."""
    found, folders = [], [src_dir]
    while folders:
        folder = folders.pop()
        try:
            with os.scandir(folder) as it:
                entries = list(it)
        except OSError:
            continue
        real = Path(os.path.realpath(folder)) if skip is not None else None
        for entry in entries:
            try:
                if entry.is_dir() and not entry.is_symlink():
                    folders.append(folder / entry.name)
                if not entry.name.endswith(suffixes) or not entry.is_file():
                    continue
                if skip is not None:
                    inside = Path(os.path.realpath(entry.path)) if entry.is_symlink() else real / entry.name
                    if inside.is_relative_to(skip):
                        continue
            except OSError:
                continue
            found.append(folder / entry.name)
    return found


def outputs_for(operation: str, out_dir: Path, relpath: str, params: dict) -> dict[str, str]:
    """Output paths of one take, mirroring the source tree under ``out_dir``."""
    base = out_dir / Path(relpath).parent / Path(relpath).stem
    if operation == "convert":
        return {"motion": f"{base}.{params['to']}"}
    if operation == "analyze":
        return {"summary": f"{base}.summary.json",
                "frames": str(out_dir / FRAMES_DIR / f"take={take_id(relpath)}" / "part-0.parquet")}
    if operation == "segment":
        outs = {"segments": f"{base}.segments.json"}
        if params.get("export_clips"):
            outs["clips"] = f"{base}_clips"
        return outs
    if operation == "retarget":
        return {"motion": f"{base}.{params['to']}", "report": f"{base}.retarget.json"}
    if operation == "render":
        return {"video": f"{base}.mp4"}
    raise ValueError(f"unknown batch operation {operation!r} (use {', '.join(OPERATIONS)})")


def plan_jobs(operation: str, src_dir: Path, out_dir: Path, read_options: dict, params: dict,
              include: tuple[str, ...] = DEFAULT_INCLUDE) -> list[Job]:
    """One :class:`Job` per source file (absolute paths, sorted); options not given take
    :data:`DEFAULT_READ_OPTIONS` and :data:`DEFAULT_PARAMS`."""
    if operation not in OPERATIONS:
        raise ValueError(f"unknown batch operation {operation!r} (use {', '.join(OPERATIONS)})")
    read_options = {**DEFAULT_READ_OPTIONS, **read_options}
    params = {**DEFAULT_PARAMS[operation], **params}
    src_dir, out_dir = Path(src_dir).absolute(), Path(out_dir).absolute()
    if src_dir.is_dir() and src_dir.resolve().is_relative_to(out_dir.resolve()):
        # outputs mirror the source tree: in the source folder or above it they would land among the
        # takes (a BVH on its source, other outputs read as takes by the next run)
        where = "is" if src_dir.resolve() == out_dir.resolve() else "contains"
        raise InputError(out_dir, f"the output folder {where} the source folder: choose one outside the source tree "
                                  "(or inside it: it is then skipped)")
    # the output folder inside the source one is skipped
    inside = src_dir.is_dir() and out_dir.resolve().is_relative_to(src_dir.resolve())
    jobs = []
    for path in find_sources(src_dir, include, out_dir if inside else None):
        rel = path.relative_to(src_dir).as_posix()
        jobs.append(Job(operation, take_id(rel), str(path), rel, outputs_for(operation, out_dir, rel, params),
                        read_options, params))
    return jobs


def up_to_date(job: Job, previous: dict | None) -> bool:
    """True when the last catalogue row is ok with the same options and every output exists
    and is newer than the source."""
    if previous is None or previous.get("status") != "ok" or previous.get("options") != job.options_key:
        return False
    try:
        source_mtime = os.stat(job.source).st_mtime
        return all(os.stat(p).st_mtime >= source_mtime for p in job.outputs.values())
    except OSError:
        return False


def group_jobs(jobs: list[Job], slots: int, task_bytes: int) -> list[tuple[Job, ...]]:
    """Consecutive groups of ``jobs`` (one Dask task each), in the jobs' order, for ``slots``
    worker threads: at most ``task_bytes`` source bytes a group (or one job), and smaller
    towards the end ("guided" sizes: a quarter of what remains per slot, down to
    ``task_bytes / 16``), so the workers finish together instead of one waiting for the
    last big group. ``task_bytes <= 0``: one job per group.
    """
    if task_bytes <= 0:
        return [(job,) for job in jobs]
    sizes = [max(1, _size(job.source)) for job in jobs]
    remaining = sum(sizes)
    groups, current, filled = [], [], 0
    for job, size in zip(jobs, sizes):
        if current and filled + size > max(task_bytes // 16, min(task_bytes, remaining // (4 * max(1, slots)))):
            groups.append(tuple(current))
            remaining -= filled
            current, filled = [], 0
        current.append(job)
        filled += size
    if current:
        groups.append(tuple(current))
    return groups


def _size(path: str) -> int:
    try:
        return os.stat(path).st_size
    except OSError:
        return 0

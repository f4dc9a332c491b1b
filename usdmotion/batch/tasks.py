"""One take, run on a Dask worker: read, the operation's library call, atomic outputs, a catalogue row.

Every operation calls the functions the single-file command calls (``read_motion``,
``convert_motion``, ``analyse`` + ``write_summary``/``write_kinematics``, ``segment`` +
``write_segments_json``, ``retarget_files``, ``render_motion``) with the same defaults, so
a take's outputs are byte-identical to the single-file command's. A bad take never
raises: it returns a row with ``status="error"`` and the one-line message.
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings
from pathlib import Path

from usdmotion.batch.plan import Job


def run_group(jobs: tuple[Job, ...]) -> list[dict]:
    """Process several takes one after another in one Dask task; one catalogue row each.

    Temporaries that a killed worker left for these takes' outputs are removed first (the
    takes are being redone, so nothing else writes them).
    """
    _remove_stale_temporaries(jobs)
    worker = _worker_name()
    return [run_job(job, worker) for job in jobs]


def run_job(job: Job, worker: str | None = None) -> dict:
    """Process one take; return its catalogue row (never raises for bad input). ``worker``:
    the Dask worker's address for the row (``run_group`` looks it up once per task)."""
    from usdmotion.errors import UsdMotionError

    start, cpu = time.perf_counter(), time.process_time()
    row = {"operation": job.operation, "take": job.take, "source": job.source, "relpath": job.relpath,
           "options": job.options_key, "outputs": [], "status": "ok", "error": None, "worker": worker}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            row.update(_file_facts(job.source))
            created = _make_folders(job)
            row.update(OPERATION_TASKS[job.operation](job, row))
            row["outputs"] = sorted(job.outputs.values())
        except (UsdMotionError, ValueError, KeyError, OSError, MemoryError) as exc:
            row.update(status="error", error=_first_line(exc))
        except Exception as exc:  # noqa: BLE001 - a bug in one take must not stop the batch
            row.update(status="error", error=f"internal error ({type(exc).__name__}: {_first_line(exc)})")
        if row["status"] != "ok":
            _remove_empty(created if "created" in locals() else [])
    row["warnings"] = "\n".join(dict.fromkeys(str(w.message).splitlines()[0] for w in caught)) or None
    row["seconds"] = time.perf_counter() - start
    row["cpu_seconds"] = time.process_time() - cpu  # the worker process's CPU time during the take
    return row


def _make_folders(job: Job) -> list[Path]:
    """Create the output folders; return those that did not exist (deepest first)."""
    created = []
    for folder in sorted({Path(p).parent for p in job.outputs.values()}):
        if folder.is_dir():  # the usual case after a folder's first take: one stat, not one per parent
            continue
        missing = [f for f in (folder, *folder.parents) if not f.exists()]
        folder.mkdir(parents=True, exist_ok=True)
        created.extend(missing)
    return sorted(set(created), key=lambda f: len(f.parts), reverse=True)


def _remove_stale_temporaries(jobs: tuple[Job, ...]) -> None:
    """Remove the temporary files a killed worker left beside the jobs' outputs: those of
    ``atomic_output`` (``.STEM.XXXXXXXX.tmpSUFFIX``, Python's ``mkstemp``) and usd-core's own,
    which it writes beside that before renaming it (``.STEM.XXXXXXXX.tmp.XXXXXX``). One
    folder listing per output folder."""
    import re

    wanted: dict[str, list[Path]] = {}
    for out in (Path(p) for job in jobs for p in job.outputs.values()):
        wanted.setdefault(str(out.parent), []).append(out)
    for folder, outs in wanted.items():
        try:
            names = [e.name for e in os.scandir(folder) if e.name.startswith(".") and ".tmp" in e.name]
        except OSError:  # not made yet: nothing to remove
            continue
        if not names:  # the usual case: no pattern to build
            continue
        patterns = [re.compile(rf"\.{re.escape(out.stem)}\.[a-z0-9_]{{8}}\.tmp(?:{re.escape(out.suffix)}|\.[A-Za-z0-9]{{6}})")
                    for out in outs]
        for name in names:
            if any(pattern.fullmatch(name) for pattern in patterns):
                Path(folder, name).unlink(missing_ok=True)


def _remove_empty(folders: list[Path]) -> None:
    """Remove the folders a failed take created, where they are still empty."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            pass


def _first_line(exc: BaseException) -> str:
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    return str(text).splitlines()[0] if str(text) else type(exc).__name__


def _worker_name() -> str | None:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return None


def _file_facts(path: str) -> dict:
    """Size, mtime and SHA-256 of the source file."""
    stat = os.stat(path)
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return {"size_bytes": stat.st_size, "mtime": stat.st_mtime, "sha256": digest.hexdigest()}


def _read(job: Job):
    from usdmotion.io import read_motion

    return read_motion(job.source, **job.read_options)


def motion_facts(motion) -> dict:
    """Catalogue columns describing a motion (joints, frames, rig family, units...). The rig family
    is the Studio library's (:func:`usdmotion.skeleton_names.rig_family`: CMU ASF takes are ``asf``)."""
    import numpy as np

    from usdmotion.skeleton_names import rig_family
    from usdmotion.summary import unit_name

    real = tuple(n for n, end in zip(motion.joint_names, motion.end_sites) if not end)
    return {"rig_family": rig_family(real), "joints": len(real),
            "end_sites": int(np.count_nonzero(motion.end_sites)),
            "frames": motion.n_frames, "fps": float(motion.fps), "duration_s": float(motion.duration),
            "meters_per_unit": float(motion.meters_per_unit), "units": unit_name(motion.meters_per_unit),
            "up_axis": motion.up_axis}


def convert_task(job: Job, row: dict) -> dict:
    """``usdmotion convert SRC OUT [--mesh]``, USD outputs validated (a problem fails the take, nothing written)."""
    from usdmotion.io.convert import check_convert_paths, convert_motion, kept_for

    out = job.outputs["motion"]
    check_convert_paths(job.source, out, job.params.get("mesh", False))
    motion = kept_for(_read(job), out)
    convert_motion(motion, out, job.params.get("mesh", False), job.params.get("validate", True))
    return motion_facts(motion)


def analyze_task(job: Job, row: dict) -> dict:
    """``usdmotion analyze SRC --summary S --out F.parquet`` (defaults) plus catalogue columns."""
    from usdmotion.anthropometry import body_model
    from usdmotion.errors import InputError
    from usdmotion.ops.analyse import analyse
    from usdmotion.ops.analyse.report import summary, write_kinematics, write_summary
    from usdmotion.ops.analyse.smoothing import FilterSpec

    motion = _read(job)
    try:
        body = body_model(motion, "male", None, source=job.source)
    except InputError as exc:
        warnings.warn(f"no centre of mass: {exc}", stacklevel=1)
        body = None
    kin = analyse(motion, FilterSpec(job.params.get("filter", "butter"), job.params.get("cutoff", 6.0)),
                  None, body, None, True, 0, job.source)
    chosen = list(range(len(kin.joint_names)))
    data = summary(kin, chosen, job.source)
    write_summary(data, job.outputs["summary"])
    write_kinematics(kin, job.outputs["frames"], chosen, job.source)
    return {**motion_facts(motion), **analyze_columns(data)}


def analyze_columns(data: dict) -> dict:
    """Catalogue columns from an analysis summary: the fastest joint and the COM figures (SI units)."""
    peaks = [(j["peak_speed"]["value"], name, j["peak_speed"]["time"]) for name, j in data["joints"].items()
             if j["peak_speed"]["value"] is not None]
    best = max(peaks, key=lambda p: p[0]) if peaks else (None, None, None)  # first joint on a tie
    out = {"peak_joint_speed": best[0], "peak_joint_speed_joint": best[1], "peak_joint_speed_time_s": best[2]}
    com = data.get("com")
    if com:
        out.update(com_peak_speed=com["peak_speed"]["value"], com_mean_horizontal_speed=com["mean_horizontal_speed"],
                   com_vertical_min=com["vertical"]["min"], com_vertical_max=com["vertical"]["max"],
                   com_vertical_range=com["vertical"]["range"])
    return out


def segment_task(job: Job, row: dict) -> dict:
    """``usdmotion segment SRC --out J [--export-clips DIR]`` with the default detector."""
    from usdmotion.ops.segment import segment
    from usdmotion.ops.segment.files import export_clips, write_segments_json

    motion = _read(job)
    seg = segment(motion, source=job.source)
    write_segments_json(seg, job.outputs["segments"], job.source)
    if "clips" in job.outputs:
        export_clips(motion, seg, job.outputs["clips"], job.params.get("clip_format", "bvh"), Path(job.source).stem)
    return motion_facts(motion)


def retarget_task(job: Job, row: dict) -> dict:
    """``usdmotion retarget SRC OUT --target RIG --report R`` (defaults); JAX keeps its compile
    cache in the worker process and on disk across takes."""
    from usdmotion.io import read_motion
    from usdmotion.ops.retarget.files import retarget_files
    from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache

    enable_compilation_cache()
    motion = _read(job)
    target = Path(job.params["target"])
    target_motion = read_motion(target, **job.params.get("target_read_options", {}))
    retarget_files(motion, Path(job.source), Path(job.outputs["motion"]), target_motion, target,
                   report_path=Path(job.outputs["report"]))
    return motion_facts(motion)


def render_task(job: Job, row: dict) -> dict:
    """``usdmotion render SRC OUT.mp4 --size WxH`` (other options default): a preview video."""
    from usdmotion.render import RenderOptions, render_motion

    motion = _read(job)
    width, height = job.params.get("size", (640, 360))
    render_motion(motion, job.outputs["video"], RenderOptions(width=width, height=height,
                                                              labels=(Path(job.source).name, "")))
    return motion_facts(motion)


OPERATION_TASKS = {"convert": convert_task, "analyze": analyze_task, "segment": segment_task,
                   "retarget": retarget_task, "render": render_task}

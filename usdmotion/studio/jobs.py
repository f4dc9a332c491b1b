"""Long work off the request path: the Studio's jobs (retarget, render, clip export, detectors).

A panel's POST route calls :meth:`Jobs.submit` with the files the job will write and a
``work(progress, outputs) -> dict`` function; the job runs on a worker thread and the page
polls ``GET /api/jobs/{id}``. ``progress`` is the library's one progress type
(:class:`usdmotion.progress.Progress`): once the job is cancelled, its next call raises
:class:`JobCancelled`, so every library operation that reports progress stops within a step.

Outputs are claimed at submit (two jobs on one file are refused with one line), written by
the work atomically (:mod:`usdmotion.io.atomic`), and a job that fails or is cancelled leaves
none of them behind. A failed job keeps its one-line error exactly as the CLI prints it
(``usdmotion: error: FILE[:LINE]: message``).

:func:`output_path` is the one naming rule for every file the Studio writes.
"""

from __future__ import annotations

import contextlib
import itertools
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from usdmotion.errors import error_line
from usdmotion.progress import Progress
from usdmotion.studio.errors import StudioError

#: Jobs running at once (more wait, ``queued``); finished jobs kept for the page to read.
MAX_RUNNING = 2
KEEP_FINISHED = 200
STATES = ("queued", "running", "done", "failed", "cancelled")

Work = Callable[[Progress, list[Path]], dict]


class JobCancelled(Exception):
    """Raised by a cancelled job's ``progress`` callback: unwinds the work (atomic writes clean up)."""


@dataclass
class Job:
    """One unit of work and what the page sees of it (:meth:`as_dict`)."""

    id: int
    kind: str
    outputs: list[Path]
    state: str = "queued"
    current: float = 0.0
    total: float | None = None
    message: str = ""
    error: str | None = None
    result: dict | None = None
    created: float = field(default_factory=time.time)
    ended: int = -1  # order in which jobs ended: the first forgotten are the first ended, not the first started
    cancelled: threading.Event = field(default_factory=threading.Event)
    existed: list[bool] = field(default_factory=list)
    thread: threading.Thread | None = None

    def progress(self, current: float, total: float | None, message: str = "") -> None:
        """The job's :class:`~usdmotion.progress.Progress`: records the report; raises
        :class:`JobCancelled` once the job was cancelled."""
        if self.cancelled.is_set():
            raise JobCancelled
        self.current = float(current)
        if total is not None:
            self.total = float(total)
        if message:
            self.message = message

    @property
    def active(self) -> bool:
        return self.state in ("queued", "running")

    def as_dict(self) -> dict:
        return {"id": self.id, "kind": self.kind, "state": self.state, "current": self.current,
                "total": self.total, "message": self.message, "error": self.error, "result": self.result}


class Jobs:
    """The Studio's jobs, writing under ``out`` (``None``: a Studio that may not write)."""

    def __init__(self, out: Path | None, max_running: int = MAX_RUNNING) -> None:
        self.out = None if out is None else Path(out)
        self._jobs: OrderedDict[int, Job] = OrderedDict()
        self._ids = itertools.count(1)
        self._ends = itertools.count()
        self._lock = threading.Lock()
        self._slots = threading.Semaphore(max_running)

    def submit(self, kind: str, outputs: list[Path], work: Work, names: dict[str, str] | None = None) -> Job:
        """Start ``work(progress, outputs)`` on a worker thread; ``names`` maps full paths to the
        names the page shows in an error line.

        Raises:
            StudioError: 409 if an output is claimed by a queued or running job; 403 if an
                output is outside the output folder (or the Studio has none).
        """
        outputs = [Path(p).resolve() for p in outputs]
        for path in outputs:
            self._check_inside(path)
        with self._lock:
            claimed = {p: job for job in self._jobs.values() if job.active for p in job.outputs}
            for path in outputs:
                if path in claimed:
                    other = claimed[path]
                    raise StudioError(409, f"{self.shown(path)} is already being written by job {other.id} "
                                           f"({other.kind}); wait for it or cancel it")
            job = Job(next(self._ids), kind, outputs, existed=[p.exists() for p in outputs])
            self._jobs[job.id] = job
            self._forget_old()
        job.thread = threading.Thread(target=self._run, args=(job, work, names or {}), name=f"studio-job-{job.id}",
                                      daemon=True)
        job.thread.start()
        return job

    def get(self, job_id: int) -> Job:
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise StudioError(404, f"no job {job_id}")
        return job

    def list(self) -> list[Job]:
        with self._lock:
            return list(self._jobs.values())

    def cancel(self, job_id: int) -> Job:
        """Ask the job to stop: a queued job never starts, a running one stops at its next report."""
        job = self.get(job_id)
        job.cancelled.set()
        with self._lock:
            if job.state == "queued":
                job.state, job.ended = "cancelled", next(self._ends)
        return job

    def output_path(self, source: str, suffix: str, ext: str) -> Path:
        """:func:`output_path` under this Studio's output folder, skipping files claimed by active jobs."""
        if self.out is None:
            raise StudioError(403, "this studio was started without an output folder (--out): it writes nothing")
        with self._lock:
            taken = {p for job in self._jobs.values() if job.active for p in job.outputs}
        return output_path(self.out, source, suffix, ext, taken)

    def shutdown(self, timeout_s: float = 20.0) -> None:
        """Cancel every queued or running job and wait (up to ``timeout_s``) for them to stop,
        so a server that stops leaves no partial file."""
        active = [job for job in self.list() if job.active]
        for job in active:
            self.cancel(job.id)
        deadline = time.monotonic() + timeout_s
        for job in active:
            if job.thread is not None:
                job.thread.join(max(0.0, deadline - time.monotonic()))

    def shown(self, path: Path) -> str:
        """``path`` as the page shows it: relative to the output folder, under its name."""
        if self.out is not None:
            with contextlib.suppress(ValueError):
                return (Path(self.out.name) / path.relative_to(self.out.resolve())).as_posix()
        return str(path)

    def _check_inside(self, path: Path) -> None:
        if self.out is None:
            raise StudioError(403, "this studio was started without an output folder (--out): it writes nothing")
        if not path.is_relative_to(self.out.resolve()):
            raise StudioError(403, f"{path.name}: the studio writes only under its output folder")

    def _run(self, job: Job, work: Work, names: dict[str, str]) -> None:
        with self._slots:
            with self._lock:
                if job.state != "queued":  # cancelled while waiting
                    return
                job.state = "running"
            state, result, error = "done", None, None
            try:
                result = work(job.progress, list(job.outputs)) or {}
                if job.cancelled.is_set():  # cancelled after its last report: keep nothing
                    raise JobCancelled
            except JobCancelled:
                self._remove_outputs(job)
                state, result = "cancelled", None
            except BaseException as exc:  # noqa: BLE001 - every failure is the job's one line
                self._remove_outputs(job)
                error = error_line(exc)
                if isinstance(exc, StudioError):  # the work's own refusal (a take that does not read): its line
                    error = str(exc) if str(exc).startswith("usdmotion: error: ") else f"usdmotion: error: {exc}"
                for full, name in sorted(names.items(), key=lambda kv: -len(kv[0])):
                    error = error.replace(full, name)
                state, result = "failed", None
            with self._lock:
                job.result, job.error, job.state, job.ended = result, error, state, next(self._ends)

    def _remove_outputs(self, job: Job) -> None:
        """Delete what the job wrote (outputs that did not exist when it was submitted)."""
        for path, existed in zip(job.outputs, job.existed):
            if not existed:
                with contextlib.suppress(OSError):
                    path.unlink()

    def _forget_old(self) -> None:
        """Keep the :data:`KEEP_FINISHED` jobs that ended last: a long job that ends after many
        short ones is kept for the page that polls it."""
        finished = sorted((job.ended, i) for i, job in self._jobs.items() if not job.active)
        for _, job_id in finished[:max(0, len(finished) - KEEP_FINISHED)]:
            del self._jobs[job_id]


def output_path(out: Path, source: str, suffix: str, ext: str, taken=frozenset()) -> Path:
    """Where the Studio writes a file made from the take ``source`` (its library name, e.g.
    ``"session2/walk.bvh"`` of root ``lab``): ``out/<root name>/<subdirs>/<stem>.<suffix>.<ext>``,
    with ``-2``, ``-3``... before the extension rather than overwriting an existing file.

    ``source`` is ``"<root name>/<relative path>"``; ``suffix`` says what was done ("edit",
    "retarget", "video"), ``ext`` the format ("bvh", "usda", "mp4"); paths in ``taken`` (claimed
    by running jobs) are skipped like existing files. The folder is created.
    """
    rel = PurePosixPath(source)
    if rel.is_absolute() or any(p in ("..", ".") for p in rel.parts) or not rel.parts:
        raise StudioError(400, f"{source}: not a library name")
    stem = rel.stem
    folder = Path(out).joinpath(*rel.parent.parts)
    ext = ext.lstrip(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StudioError(507, f"cannot write in the output folder {out}: {exc.strerror or exc}") from None
    n = 1
    path = folder / f"{stem}.{suffix}.{ext}"
    while path.exists() or path.resolve() in taken:
        n += 1
        path = folder / f"{stem}.{suffix}-{n}.{ext}"
    return path


class Kept:
    """The last ``size`` results a panel computed (edited motions, retarget results), by key,
    for the page's follow-up requests."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._items: OrderedDict[str, object] = OrderedDict()
        self._lock = threading.Lock()

    def put(self, key: str, value) -> None:
        with self._lock:
            self._items[key] = value
            self._items.move_to_end(key)
            while len(self._items) > self.size:
                self._items.popitem(last=False)

    def get(self, key: str):
        """The value kept under ``key``, or ``None``."""
        with self._lock:
            return self._items.get(key)


def library_name(library, out: Path | None, entry) -> str:
    """``"<root name>/<relative path>"`` of a take for :func:`output_path`; a take already in the
    output folder keeps its place there (an edit of an edit is written beside it)."""
    if out is not None and entry.path.is_relative_to(Path(out).resolve()):
        return entry.path.relative_to(Path(out).resolve()).as_posix()
    index, _, rel = entry.id.partition("/")
    root = library.roots[int(index)]
    return f"{(root.parent if root.is_file() else root).name}/{rel}"


def saved(api, path) -> dict:
    """What a job that wrote ``path`` answers: the path as shown and its library id (the
    output folder is listed as a root, so the new file is in the library)."""
    path = path.resolve()
    for index, root in enumerate(api.library.roots):
        if root.is_dir() and path.is_relative_to(root):
            return {"output": api.jobs.shown(path), "id": f"{index}/{path.relative_to(root).as_posix()}"}
    return {"output": api.jobs.shown(path), "id": None}

def submit_save(api, kind: str, entry, suffix: str, fmt: str, formats: tuple[str, ...], work) -> dict:
    """Save as through a job: ``fmt`` checked against ``formats``, the output named by
    :meth:`Jobs.output_path` from ``entry`` (``<stem>.<suffix>.<fmt>`` in the output folder),
    ``work(progress, outputs)`` run as the job; answers ``{"job", "output"}``."""
    if fmt not in formats:
        raise StudioError(400, f"format must be one of {', '.join(formats)}")
    path = api.jobs.output_path(library_name(api.library, api.out, entry), suffix, fmt)
    job = api.jobs.submit(kind, [path], work, names={str(entry.path): entry.name})
    return {"job": job.id, "output": api.jobs.shown(path)}


async def json_body(request, max_bytes: int = 64 * 1024) -> dict:
    """The request's JSON object (400 with one line if it is not one)."""
    import json

    data = await request.body()
    if len(data) > max_bytes:
        raise StudioError(413, "request too large")
    try:  # NaN is let through to the field checks, which name the field
        body = json.loads(data or b"{}")
    except (ValueError, UnicodeDecodeError, RecursionError):  # 64 kB of '[' nests deeper than Python recurses
        raise StudioError(400, "the request body is not JSON") from None
    if not isinstance(body, dict):
        raise StudioError(400, "the request body must be a JSON object")
    return body


def routes(jobs: Jobs) -> list:
    """``GET /api/jobs``, ``GET /api/jobs/{id}``, ``DELETE /api/jobs/{id}``."""
    from starlette.requests import Request
    from starlette.responses import JSONResponse
    from starlette.routing import Route

    def job_id(request: Request) -> int:
        text = request.path_params["id"]
        if not text.isdigit() or len(text) > 12:
            raise StudioError(404, f"no job {text[:20]}")
        return int(text)

    def list_jobs(request: Request) -> JSONResponse:
        return JSONResponse({"jobs": [job.as_dict() for job in jobs.list()]})

    def one_job(request: Request) -> JSONResponse:
        if request.method == "DELETE":
            return JSONResponse(jobs.cancel(job_id(request)).as_dict())
        return JSONResponse(jobs.get(job_id(request)).as_dict())

    return [Route("/api/jobs", list_jobs, methods=["GET"]),
            Route("/api/jobs/{id}", one_job, methods=["GET", "DELETE"])]

"""The Dask side: a local cluster (processes) or a connection to an existing scheduler,
and the loop that submits jobs and yields their rows as they finish."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import uuid
from collections.abc import Iterable, Iterator

from usdmotion.batch.plan import Job
from usdmotion.errors import InputError


def default_workers() -> int:
    """One worker process per core the process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None,
                memory_limit: str | int = "auto") -> Iterator:
    """A ``distributed.Client``: on ``scheduler`` (``tcp://HOST:PORT``) if given, else on a
    ``LocalCluster`` of ``workers`` single-threaded processes (default: one per core; inside a
    take usdmotion, NumPy and Arrow use one thread),
    each limited to ``memory_limit`` (``"auto"``: the machine's memory shared equally).

    The cluster and client are always closed on exit.
    """
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL)  # shutdown races and lost workers are reported as rows, not log noise
    try:
        with _client(workers, scheduler, memory_limit) as client:
            yield client
    finally:
        logger.setLevel(level)


@contextlib.contextmanager
def _client(workers: int | None, scheduler: str | None, memory_limit: str | int) -> Iterator:
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise InputError(scheduler, f"cannot connect to the Dask scheduler ({exc})") from None
        with client:
            yield client
        return
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    with _interrupts_ignored():  # the worker processes start ignoring Ctrl-C (see _interrupts_ignored)
        cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                               memory_limit=memory_limit, dashboard_address=None, worker_dashboard_address=None,
                               # no dashboard; its HTTP server on any free port, not 8787 (no "port in use" warning)
                               scheduler_kwargs={"dashboard_address": ":0"},
                               env={"USDMOTION_THREADS": "1"},  # one take per core: no threads inside a take
                               silence_logs=logging.CRITICAL)
    with cluster, Client(cluster) as client:
        client.register_plugin(_ignore_interrupts_plugin())  # workers the nanny restarts later
        yield client


@contextlib.contextmanager
def _interrupts_ignored() -> Iterator[None]:
    """SIGINT ignored while the local workers are spawned: they inherit the disposition (Python
    and asyncio leave an ignored SIGINT ignored), so a terminal's Ctrl-C, sent to the whole
    process group, reaches only this process, which cancels the batch and closes the cluster,
    instead of every worker printing a KeyboardInterrupt traceback. A Ctrl-C within this
    second of start-up is not seen."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _ignore_interrupts_plugin():
    """A worker plugin that ignores SIGINT in each worker process, restarted ones included."""
    from distributed import WorkerPlugin

    class IgnoreInterrupts(WorkerPlugin):
        name = "usdmotion-ignore-interrupts"

        def setup(self, worker) -> None:
            import signal
            import threading

            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return IgnoreInterrupts()


#: Modules each operation's tasks import (loaded once per worker by :func:`warm_up`).
OPERATION_MODULES = {
    "convert": ("usdmotion.io.convert", "usdmotion.io.usd", "usdmotion.io.bvh", "usdmotion.skeleton_names"),
    "analyze": ("usdmotion.io", "usdmotion.ops.analyse", "usdmotion.ops.analyse.report", "usdmotion.anthropometry",
                "pyarrow.parquet"),
    "segment": ("usdmotion.io", "usdmotion.ops.segment", "usdmotion.ops.segment.files"),
    "retarget": ("usdmotion.io", "usdmotion.ops.retarget.files", "usdmotion.ops.retarget.solve"),
    "render": ("usdmotion.io", "usdmotion.render"),
}


def _import_modules(names: tuple[str, ...]) -> None:
    import importlib

    from usdmotion.batch import tasks  # noqa: F401 - the task module itself

    for name in names:
        importlib.import_module(name)


def warm_up(client, operation: str) -> None:
    """Import the operation's modules on every worker now, so the first takes do not pay for it
    one after another (workers that join later import on their first take)."""
    client.run(_import_modules, OPERATION_MODULES.get(operation, ()))


def run_jobs(client, jobs: Iterable[Job]) -> Iterator[dict]:
    """Submit every job (one task per take) and yield catalogue rows in completion order.

    A task whose worker dies is re-run on another worker by the scheduler; one that fails
    anyway (e.g. it kills every worker it lands on) yields an error row.
    """
    from distributed import as_completed

    from usdmotion.batch.tasks import run_job

    run = uuid.uuid4().hex[:8]
    futures = {client.submit(run_job, job, key=f"usdmotion-{job.operation}-{job.take}-{run}", pure=False): job
               for job in jobs}
    try:
        for future in as_completed(futures):
            job = futures.pop(future)
            try:
                row = future.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, lost scheduler: an error row
                row = _failed_row(job, exc)
            # released before the row is handed on: a worker lost afterwards holds nothing this
            # client still wants, so the scheduler never recomputes (and rewrites) a finished take
            future.release()
            del future
            yield row
    finally:
        for future in futures:
            future.cancel()


def _failed_row(job: Job, exc: BaseException) -> dict:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return {"operation": job.operation, "take": job.take, "source": job.source, "relpath": job.relpath,
            "options": job.options_key, "outputs": [], "status": "error",
            "error": f"task failed on the cluster ({type(exc).__name__}: {text})"}

"""The Dask side: a local cluster (processes) or a connection to an existing scheduler,
and the loop that submits jobs and yields their rows as they finish."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import uuid
from collections.abc import Iterator

from usdmotion.batch.plan import Job
from usdmotion.errors import InputError


def default_workers() -> int:
    """One worker process per core the process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


#: Dask settings of the local cluster (taken by its nannies and workers when they start).
LOCAL_CLUSTER_CONFIG = {
    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which also turns off glibc's
    # adaptive mmap threshold: every NumPy temporary over 128 kB is then mapped and unmapped, and a
    # 160-frame take page-faults 3-5x as often (+2 ms system CPU per convert take, +3.5 ms per
    # analyze take, measured). A take's memory is freed when it ends; glibc's defaults keep RSS flat.
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    # the statistical profiler interrupts the task thread every 10 ms for a dashboard nobody opens
    "distributed.worker.profile.enabled": False,
    # event-loop health ticks (default 20 ms) and system samples (500 ms) in the scheduler and each
    # worker: an idle 2-worker cluster used 7 % of a core with the defaults, 3 % with these
    "distributed.admin.tick.interval": "200ms",
    "distributed.admin.system-monitor.interval": "2s",
    # the memory checks of each worker and of its nanny (in the client's process), 100 ms by default:
    # 500 ms still pauses or restarts a worker long before a take (0.02-1 s) can fill its memory
    "distributed.worker.memory.monitor-interval": "500ms",
    # the client process's own periodic work (the cluster's repr for notebook widgets, scheduler info
    # every 2 s, host-wide disk counters in every system sample); the client and scheduler share
    # the two cores with the workers. An idle 2-worker cluster: ~40 -> ~27 ms of CPU a second.
    "distributed.deploy.cluster-repr-interval": "10s",
    "distributed.client.scheduler-info-interval": "10s",
    "distributed.admin.system-monitor.disk": False,
    # tasks are independent and queued on the scheduler (a worker holds at most two): nothing to steal
    "distributed.scheduler.work-stealing": False,
}


#: Environment of the local cluster's worker processes, besides what Dask's nanny sets
#: (``OMP_NUM_THREADS=1``, which BLAS and Arrow's thread pool follow, and the same for MKL and
#: OpenBLAS): one thread inside a take. usdmotion's own threads (``usdmotion.parallel``) and
#: USD's work pool (TBB, a thread per core by default: its threads of two workers on two cores
#: took turns with the takes), set before USD loads; USD's banner about an overridden setting off.
WORKER_ENV = {"USDMOTION_THREADS": "1", "PXR_WORK_THREAD_LIMIT": "1", "TF_ENV_SETTING_ALERTS_ENABLED": "0"}


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
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise InputError(scheduler, f"cannot connect to the Dask scheduler ({exc})") from None
        except Exception as exc:  # noqa: BLE001 - distributed's refusals of the address: ValueError, TypeError (tls)
            message = str(exc).splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise InputError(scheduler, f"not a Dask scheduler address like tcp://HOST:8786 (Dask: {message})") from None
        with client:
            yield client
        return
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    with _interrupts_ignored(), dask.config.set(LOCAL_CLUSTER_CONFIG):  # workers ignore Ctrl-C; our settings
        cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                               memory_limit=memory_limit, dashboard_address=None, worker_dashboard_address=None,
                               # no dashboard; its HTTP server on any free port, not 8787 (no "port in use" warning)
                               scheduler_kwargs={"dashboard_address": ":0"},
                               env=WORKER_ENV,  # one take per core: no threads inside a take
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


#: Modules each operation's tasks import (loaded once per worker, on its first task: :func:`run_task`).
OPERATION_MODULES = {
    "convert": ("usdmotion.io.convert", "usdmotion.io.usd", "usdmotion.io.bvh", "usdmotion.skeleton_names"),
    "analyze": ("usdmotion.io", "usdmotion.ops.analyse", "usdmotion.ops.analyse.report", "usdmotion.anthropometry",
                "pyarrow.parquet"),
    "segment": ("usdmotion.io", "usdmotion.ops.segment", "usdmotion.ops.segment.files"),
    "retarget": ("usdmotion.io", "usdmotion.ops.retarget.files", "usdmotion.ops.retarget.solve"),
    "render": ("usdmotion.io", "usdmotion.render"),
}
#: Operations whose workers also run one take at start (:func:`prepare_process`): their takes
#: cost 15-50 ms of CPU, while the first take of a process costs 0.5 s (convert: USD's plug-ins
#: and validators) to 1.2 s (analyze: SciPy's filters, pandas under pyarrow) of lazy imports and
#: caches (measured under load 11). Retarget (a JAX compile per rig) and render (seconds a take) do not.
WARM_TAKE_OPERATIONS = ("convert", "analyze", "segment")


def _import_modules(names: tuple[str, ...]) -> None:
    import importlib

    from usdmotion.batch import tasks  # noqa: F401 - the task module itself

    for name in names:
        importlib.import_module(name)


def prepare_process(operation: str) -> None:
    """Make this process ready to run ``operation``'s takes at full speed from the first one:
    import its modules and run one take of the bundled walk through the same task code in a
    temporary folder (:data:`WARM_TAKE_OPERATIONS`).

    A Dask worker runs this before its first task (:func:`run_task`; :func:`warm_up` for the
    benchmark and tests); the benchmark's sequential loop runs it
    too before its clock, so both are timed warm. Once per process and operation.
    """
    if operation in _PREPARED:
        return
    _import_modules(OPERATION_MODULES.get(operation, ()))
    if operation in WARM_TAKE_OPERATIONS:
        _warm_take(operation)
    _PREPARED.add(operation)


_PREPARED: set[str] = set()


def _warm_take(operation: str) -> None:
    """Run the bundled walk (a copy, in a temporary folder) through the operation's task."""
    import shutil
    import tempfile
    from pathlib import Path

    from usdmotion.batch.plan import plan_jobs
    from usdmotion.batch.tasks import run_group
    from usdmotion.data import DEMO_BVH

    with tempfile.TemporaryDirectory(prefix="usdmotion-warm-up-") as folder:
        source = Path(folder, "take", DEMO_BVH.name)
        source.parent.mkdir()
        shutil.copyfile(DEMO_BVH, source)
        run_group(tuple(plan_jobs(operation, source.parent, Path(folder, "out"), {}, {})))  # rows: never raises


def prepare_worker(operation: str) -> None:
    """:func:`prepare_process` in a worker, then its objects so far (Dask's, the modules', the
    caches') moved out of the garbage collector's sight (``gc.freeze``): the full collections
    that the takes' allocations trigger then walk only what the takes made (an analyze take's
    share of them: 0.3 ms of 40). Once per worker and operation."""
    import gc

    if operation in _PREPARED:
        return
    prepare_process(operation)
    gc.collect()
    gc.freeze()


def run_task(jobs: tuple[Job, ...]) -> list[dict]:
    """One Dask task: :func:`prepare_worker` for the jobs' operation (at once when the worker
    is ready), then :func:`~usdmotion.batch.tasks.run_group`. A worker's first task prepares it,
    so the run needs no warm-up round trip before its first takes (every worker gets a task at
    the start and prepares itself in parallel; one started or restarted later, on its first)."""
    from usdmotion.batch.tasks import run_group

    if jobs:
        prepare_worker(jobs[0].operation)
    return run_group(jobs)


def warm_up(client, operation: str) -> None:
    """:func:`prepare_worker` on every worker now, as a task pinned to each (in the thread
    where its takes run), and wait for them: what each worker's first task would do, done
    before a clock starts (the benchmark) or a check (tests)."""
    import uuid

    from distributed import wait

    key = uuid.uuid4().hex[:8]
    futures = [client.submit(prepare_worker, operation, key=f"usdmotion-warm-up-{operation}-{i}-{key}",
                             workers=[address], allow_other_workers=True, pure=False)
               for i, address in enumerate(client.scheduler_info()["workers"])]
    wait(futures)  # a worker lost meanwhile: its task runs on another (loose restriction), not never
    for future in futures:
        future.release()


def worker_slots(client) -> int:
    """Tasks the cluster runs at once (the sum of its workers' threads; at least 1)."""
    return max(1, sum(client.nthreads().values()))


def run_jobs(client, jobs: list[Job], task_bytes: int = 0) -> Iterator[dict]:
    """Submit the jobs, grouped into tasks of about ``task_bytes`` source bytes
    (:func:`~usdmotion.batch.plan.group_jobs`; ``0``: one take per task), and yield
    catalogue rows as tasks finish.

    A task whose worker dies is re-run on another worker by the scheduler (its takes are
    redone: outputs are rewritten whole, atomically). A task that fails anyway (e.g. one of
    its takes kills every worker it lands on) is split into one task per take, so only the
    culprit becomes an error row.
    """
    from distributed import as_completed

    from usdmotion.batch.plan import group_jobs

    run = uuid.uuid4().hex[:8]

    def key(group: tuple[Job, ...]) -> str:
        return f"usdmotion-{group[0].operation}-{group[0].take}-{len(group)}-{run}"

    def submit(group: tuple[Job, ...]):
        return client.submit(run_task, group, key=key(group), pure=False)

    groups = group_jobs(list(jobs), worker_slots(client), task_bytes)
    # one graph for all the tasks: one message to the scheduler and one update of its state,
    # not one per task (the client's process shares the cores with the workers)
    futures = dict(zip(client.map(run_task, groups, key=[key(g) for g in groups], pure=False), groups))
    done = as_completed(futures)
    try:
        for future in done:
            group = futures.pop(future)
            try:
                rows = future.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, lost scheduler: error rows
                rows = [_failed_row(job, exc) for job in group] if len(group) == 1 else []
                for job in group if len(group) > 1 else ():
                    single = submit((job,))
                    futures[single] = (job,)
                    done.add(single)
            # released before the rows are handed on: a worker lost afterwards holds nothing this
            # client still wants, so the scheduler never recomputes (and rewrites) a finished take
            future.release()
            del future
            yield from rows
    finally:
        for future in futures:
            future.cancel()


def _failed_row(job: Job, exc: BaseException) -> dict:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return {"operation": job.operation, "take": job.take, "source": job.source, "relpath": job.relpath,
            "options": job.options_key, "outputs": [], "status": "error",
            "error": f"task failed on the cluster ({type(exc).__name__}: {text})"}

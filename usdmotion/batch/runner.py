"""``run_batch``: plan, skip what is up to date, run the rest on Dask, keep the catalogue."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from usdmotion.batch.catalogue import load_arrow, read_catalogue, write_catalogue
from usdmotion.batch.plan import CATALOGUE, DEFAULT_INCLUDE, TASK_BYTES, plan_jobs, up_to_date
from usdmotion.progress import Progress, no_progress

#: Seconds between catalogue saves during a run (a killed client loses at most this much).
SAVE_EVERY_S = 10.0


@dataclass
class BatchResult:
    """What a batch did. ``rows`` are this run's catalogue rows (processed takes only)."""

    total: int
    skipped: int
    rows: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    catalogue: Path | None = None

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r.get("status") != "ok"]

    @property
    def done(self) -> int:
        return len(self.rows) - len(self.failed)

    def summary_line(self, operation: str) -> str:
        rate = len(self.rows) / self.seconds if self.seconds > 0 else 0.0
        frames = sum(r.get("frames") or 0 for r in self.rows if r.get("status") == "ok")
        return (f"batch {operation}: {self.total} takes: {self.done} done, {self.skipped} up to date, "
                f"{len(self.failed)} failed; {frames} frames in {self.seconds:.1f} s ({rate:.2f} takes/s); "
                f"catalogue {self.catalogue}")


def run_batch(operation: str, src_dir: str | Path, out_dir: str | Path, read_options: dict | None = None,
              params: dict | None = None, include: tuple[str, ...] = DEFAULT_INCLUDE, force: bool = False,
              workers: int | None = None, scheduler: str | None = None, client=None,
              progress: Progress = no_progress, on_row: Callable[[dict], None] | None = None,
              task_bytes: int | None = None) -> BatchResult:
    """Run ``operation`` on every take under ``src_dir``; outputs and ``catalogue.parquet`` in ``out_dir``.

    Takes whose catalogue row is ok (same options) and whose outputs are newer than the
    source are skipped unless ``force``. ``progress(done, n, message)`` counts the takes
    that run (``n``: those not skipped), ``on_row(row)`` gets each finished row. ``client``: an open
    ``distributed.Client`` to use instead of starting a cluster (``workers``/``scheduler`` are then
    ignored). ``task_bytes``: source bytes per Dask task (default
    :data:`~usdmotion.batch.plan.TASK_BYTES` of the operation; ``0``: one take per task). The
    catalogue is saved every :data:`SAVE_EVERY_S` seconds, at the end, and on Ctrl-C
    (atomically each time).
    """
    from usdmotion.batch.engine import dask_client, run_jobs

    start = time.perf_counter()
    out_dir = Path(out_dir)
    jobs = plan_jobs(operation, Path(src_dir), out_dir, read_options or {}, params or {}, include)
    path = out_dir / CATALOGUE
    rows = read_catalogue(path)
    todo = [j for j in jobs if force or not up_to_date(j, rows.get((j.operation, j.take)))]
    result = BatchResult(total=len(jobs), skipped=len(jobs) - len(todo), catalogue=path)
    progress(0, len(todo), f"batch {operation}")
    if todo:
        with contextlib.nullcontext(client) if client is not None else dask_client(workers, scheduler) as dask:
            out_dir.mkdir(parents=True, exist_ok=True)  # only once the cluster is there (bad --scheduler: no output)
            saved, arrow = time.perf_counter(), None
            try:
                for row in run_jobs(dask, todo, TASK_BYTES[operation] if task_bytes is None else task_bytes):
                    if arrow is None:  # the workers are busy: the catalogue's imports meanwhile, not after them
                        arrow = _start_thread(load_arrow)
                    rows[(row["operation"], row["take"])] = row
                    result.rows.append(row)
                    progress(len(result.rows), len(todo), f"batch {operation}: {row['relpath']}")
                    if on_row is not None:
                        on_row(row)
                    if time.perf_counter() - saved > SAVE_EVERY_S:
                        arrow.join()
                        write_catalogue(rows, path)
                        saved = time.perf_counter()
            finally:
                if arrow is not None:
                    arrow.join()
                write_catalogue(rows, path)
    result.seconds = time.perf_counter() - start
    return result


def _start_thread(target: Callable[[], None]) -> threading.Thread:
    """``target()`` in a daemon thread; its exceptions are dropped (the work it prepares, done
    again where it is needed, reports them there)."""
    def run() -> None:
        try:
            target()
        except Exception:  # noqa: BLE001 - see above
            pass

    thread = threading.Thread(target=run, name=f"usdmotion-{target.__name__}", daemon=True)
    thread.start()
    return thread

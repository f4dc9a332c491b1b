"""A progress display that appears only when work takes longer than a second."""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def progress(description: str, total: float | None = None, delay: float = 1.0,
             unit: str = "") -> Iterator[Callable[..., None]]:
    """Yield ``update(advance=0, description=None, total=None)``; a rich bar (or spinner,
    without ``total``) is drawn on stderr once ``delay`` seconds have passed.

    Nothing is drawn when stderr is not a terminal (logs, pipes, CI) or the work is short.
    """
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)

    console = Console(file=sys.stderr)
    columns = [SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn()]
    bar = Progress(*columns, console=console, transient=True)
    task = bar.add_task(description, total=total, rate="")
    started = threading.Event()
    lock = threading.Lock()

    def start() -> None:
        with lock:
            if not started.is_set():
                started.set()
                bar.start()

    timer = threading.Timer(delay, start)
    timer.daemon = True
    if console.is_terminal:
        timer.start()
    import time

    t0 = time.perf_counter()

    def update(advance: float = 0, description: str | None = None, total: float | None = None) -> None:
        fields = {}
        done = bar.tasks[0].completed + advance
        elapsed = time.perf_counter() - t0
        if unit and elapsed > 0:
            fields["rate"] = f"{done / elapsed:.1f} {unit}/s"
        bar.update(task, advance=advance, description=description or bar.tasks[0].description,
                   total=total if total is not None else bar.tasks[0].total, **fields)

    try:
        yield update
    finally:
        timer.cancel()
        with lock:
            if started.is_set():
                bar.stop()

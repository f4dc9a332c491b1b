"""The CLI's progress display: a rich bar on stderr that appears only when work takes longer than a second.

It implements the one progress-callback type of the library (:class:`usdmotion.progress.Progress`).
rich is imported only when the bar is drawn (stderr is a terminal and a second has passed):
a short command never pays for it.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Iterator

from usdmotion.progress import Progress


@contextlib.contextmanager
def progress(description: str, total: float | None = None, delay: float = 1.0,
             unit: str = "", refresh_per_second: float = 10) -> Iterator[Progress]:
    """Yield ``report(current, total, message)`` (a :class:`~usdmotion.progress.Progress`); a rich
    bar (or spinner, while the total is unknown) is drawn on stderr once ``delay`` seconds have passed,
    redrawn ``refresh_per_second`` times a second (each redraw costs CPU in this process).

    ``description`` is shown until a report brings a message. Nothing is drawn when stderr is
    not a terminal (logs, pipes, CI) or the work is short.
    """
    state = {"completed": 0.0, "total": total, "description": description, "rate": "", "done": False}
    lock = threading.Lock()
    shown: list = []  # [bar, task] once drawn
    t0 = time.perf_counter()

    def show() -> None:
        # rich is deferred to here: importing it costs ~0.05 s of every short command's start-up
        from rich.console import Console
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress as Bar, SpinnerColumn, TextColumn,
                                   TimeElapsedColumn, TimeRemainingColumn)

        console = Console(file=sys.stderr)
        if not console.is_terminal:
            return
        columns = [SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn()]
        with lock:
            if state["done"]:  # the work finished while rich was being imported
                return
            bar = Bar(*columns, console=console, transient=True, refresh_per_second=refresh_per_second)
            task = bar.add_task(state["description"], total=state["total"], completed=state["completed"],
                                rate=state["rate"])
            shown[:] = [bar, task]
            bar.start()

    def report(current: float, total: float | None = None, message: str = "") -> None:
        with lock:
            state["completed"] = current
            if total is not None:
                state["total"] = total
            if message:
                state["description"] = message
            elapsed = time.perf_counter() - t0
            if unit and elapsed > 0:
                state["rate"] = f"{current / elapsed:.1f} {unit}/s"
            if shown:
                bar, task = shown
                bar.update(task, completed=current, total=state["total"], description=state["description"],
                           rate=state["rate"])

    timer = None
    if sys.stderr.isatty():
        timer = threading.Timer(delay, show)
        timer.daemon = True
        timer.start()
    try:
        yield report
    finally:
        if timer is not None:
            timer.cancel()
        with lock:
            state["done"] = True
            if shown:
                shown[0].stop()

"""Threads over chunks of an array: NumPy releases the GIL inside its loops, so large
element-wise work (trigonometry, products) uses every core."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

import numpy as np


def workers() -> int:
    """Threads to use: the CPUs this process may run on (``USDMOTION_THREADS`` overrides)."""
    setting = os.environ.get("USDMOTION_THREADS")
    if setting and setting.isdigit() and int(setting) > 0:
        return int(setting)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def over_slices(work: Callable[[slice], None], n: int, min_items: int) -> None:
    """Call ``work(slice)`` on contiguous slices covering ``range(n)``, in threads when there
    are at least ``2 * min_items`` items; ``work`` must write disjoint outputs."""
    count = min(workers(), max(1, n // max(min_items, 1)))
    if count <= 1:
        work(slice(0, n))
        return
    bounds = np.linspace(0, n, count + 1).astype(int)
    parts = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
    # plain threads, the calling one working too: concurrent.futures imports logging, 0.003 s
    # of every BVH read (start-up, benchmarks/startup.py)
    failed: list[BaseException] = []

    def run(part: slice) -> None:
        try:
            work(part)
        except Exception as exc:  # re-raised in the calling thread
            failed.append(exc)

    threads = [threading.Thread(target=run, args=(part,), daemon=True) for part in parts[1:]]
    for thread in threads:
        thread.start()
    try:
        work(parts[0])
    finally:
        for thread in threads:
            thread.join()
    if failed:
        raise failed[0]

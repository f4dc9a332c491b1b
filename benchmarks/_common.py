"""Helpers shared by the benchmark scripts: timing, tiled inputs, tables, JSON output."""

from __future__ import annotations

import atexit
import json
import os
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("USDMOTION_SHARED_DATA", REPO.parent / "shared" / "data"))
RESULTS = REPO / "benchmarks" / "results"


def timed(fn, repeat: int = 7, warmup: int = 1) -> dict:
    """Run ``fn`` ``warmup + repeat`` times; seconds as median/min/max of the timed runs."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times), "runs": repeat}


def scratch_folder(prefix: str) -> Path:
    """A new temporary folder, removed with everything in it when the script exits (a run can write GBs)."""
    folder = Path(tempfile.mkdtemp(prefix=prefix))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


def tiled_bvh(source: Path, frames: int, out: Path) -> Path:
    """Write ``out``: ``source`` with its motion rows repeated to exactly ``frames`` rows."""
    text = source.read_text()
    head, _, body = text.partition("MOTION")
    rows = [r for r in body.splitlines() if r.strip()]
    data = [r for r in rows if not r.lower().startswith(("frames", "frame time"))]
    frame_time = next(r for r in rows if r.lower().startswith("frame time"))
    tiled = (data * (frames // len(data) + 1))[:frames]
    out.write_text(f"{head}MOTION\nFrames: {frames}\n{frame_time}\n" + "\n".join(tiled) + "\n")
    return out


def machine() -> dict:
    return {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine()}


def print_table(title: str, header: list[str], rows: list[list]) -> None:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    print(title)
    print("  ".join(h.ljust(w) for h, w in zip(header, widths)))
    print("  ".join("-" * w for w in widths))
    for row in rows:
        print("  ".join(str(x).ljust(w) for x, w in zip(row, widths)))


def write_results(name: str, payload: dict) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps({"benchmark": name, "machine": machine(), **payload}, indent=2) + "\n")
    return path


def save_rows(name: str, rows: list[dict]) -> int:
    """:func:`write_results` of ``rows`` with the 1-minute load average, say where; exit status 0."""
    path = write_results(name, {"rows": rows, "load_1min": os.getloadavg()[0]})
    print(f"\nwrote {path.relative_to(REPO)}")
    return 0

"""Batch throughput: ``run_batch`` on a local Dask cluster (1 and 2 worker processes) against
a plain sequential loop of the same library calls, in the same run, on a library of ≥ 500
takes built from ``../shared/data`` (windows of every readable shared BVH, renamed).

Measures takes/s and frames/s for ``convert`` (to USDC) and ``analyze``, the scheduler
overhead per take (no-op tasks, and wall time not spent in takes), worker memory over the
run (RSS sampled every 0.5 s), the cluster start-up, and the 1-minute load average before
each run (the machine is shared: a loaded machine gives the batch fewer cores than it has
workers). Prints a table and writes
``benchmarks/results/batch.json``.

    .venv/bin/python benchmarks/batch.py [--takes 500] [--frames 240]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, machine, print_table, write_results  # noqa: E402


def build_library(folder: Path, takes: int, frames: int) -> tuple[int, int]:
    """Write ``takes`` BVH takes of ``frames`` frames (or the whole take when shorter):
    windows at several starts of every readable shared BVH, in per-source folders."""
    from usdmotion.errors import UsdMotionError
    from usdmotion.io import read_motion, write_motion

    motions = []
    for path in sorted(SHARED_DATA.rglob("*.bvh")):
        try:
            motions.append((path.stem, read_motion(path)))
        except UsdMotionError:
            continue
    written, total = 0, 0
    while written < takes:
        for stem, motion in motions:
            if written >= takes:
                break
            n = motion.n_frames
            start = (written * 97) % max(1, n - frames) if n > frames else 0
            clip = motion.sliced(start, start + frames) if n > frames else motion
            out = folder / stem / f"{stem}_take{written:04d}.bvh"
            out.parent.mkdir(parents=True, exist_ok=True)
            write_motion(clip, out)
            written += 1
            total += clip.n_frames
    return written, total


def sequential(library: Path, out: Path, operation: str) -> float:
    """The plain loop: the library calls the batch task makes, one take after another."""
    from usdmotion.anthropometry import body_model
    from usdmotion.errors import InputError
    from usdmotion.io import read_motion
    from usdmotion.io.convert import convert_motion
    from usdmotion.ops.analyse import analyse
    from usdmotion.ops.analyse.report import summary, write_kinematics, write_summary

    files = sorted(library.rglob("*.bvh"))
    start, cpu = time.perf_counter(), time.process_time()
    for path in files:
        dst = out / path.relative_to(library).with_suffix("")
        dst.parent.mkdir(parents=True, exist_ok=True)
        motion = read_motion(path)
        if operation == "convert":
            convert_motion(motion, f"{dst}.usdc")
            continue
        try:
            body = body_model(motion, "male", None, source=str(path))
        except InputError:
            body = None
        kin = analyse(motion, body=body, source=str(path))
        write_summary(summary(kin, None, str(path)), f"{dst}.summary.json")
        write_kinematics(kin, f"{dst}.parquet", None, str(path))
    return time.perf_counter() - start, time.process_time() - cpu


def _rss() -> int:
    import psutil

    return psutil.Process().memory_info().rss


def _noop(i: int) -> int:
    return i


def batch_run(library: Path, out: Path, operation: str, workers: int) -> dict:
    """``run_batch`` on a fresh LocalCluster; start-up timed apart; worker RSS sampled."""
    from usdmotion.batch import run_batch
    from usdmotion.batch.engine import dask_client, warm_up

    t0 = time.perf_counter()
    with dask_client(workers) as client:
        warm_up(client, operation)  # imports, once per worker (the loop below already has them)
        startup = time.perf_counter() - t0
        samples, stop = [], threading.Event()

        def sample() -> None:
            while not stop.is_set():
                try:
                    samples.append((time.perf_counter(), sum(client.run(_rss).values()) / workers))
                except Exception:  # noqa: BLE001 - a sample lost while the cluster is busy
                    pass
                stop.wait(0.5)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        result = run_batch(operation, library, out, params={"to": "usdc"} if operation == "convert" else {},
                           force=True, client=client)
        stop.set()
        sampler.join()
        overhead = None
        if workers == 2:  # scheduler round trip per take: no-op tasks through the same cluster
            n = len(result.rows)
            t1 = time.perf_counter()
            client.gather(client.map(_noop, range(n), pure=False))
            overhead = (time.perf_counter() - t1) / n
    rows = result.rows
    task_s = sum(r["seconds"] for r in rows)
    cpu_s = sum(r["cpu_seconds"] or 0 for r in rows)
    mem = [m for _, m in samples]
    tenth = max(1, len(mem) // 10)  # memory after the first tenth of the run against the last tenth
    return {"wall_s": result.seconds, "startup_s": startup, "takes": len(rows), "failed": len(result.failed),
            "frames": sum(r.get("frames") or 0 for r in rows), "task_s": task_s,
            "cpu_ms_per_take": 1000 * cpu_s / len(rows),
            "idle_per_take_ms": 1000 * (result.seconds * workers - task_s) / len(rows),
            "noop_task_ms": None if overhead is None else 1000 * overhead,
            "rss_first_mib": statistics.mean(mem[tenth:2 * tenth]) / 2**20 if len(mem) > 1 else None,
            "rss_last_mib": statistics.mean(mem[-tenth:]) / 2**20 if len(mem) > 1 else None,
            "rss_max_mib": max(mem) / 2**20 if mem else None, "rss_samples": len(mem)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=500)
    parser.add_argument("--frames", type=int, default=240, help="frames per take (shorter sources whole)")
    parser.add_argument("--operations", default="convert,analyze")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="usdmotion-batch-bench-"))
    try:
        library = work / "library"
        takes, frames = build_library(library, args.takes, args.frames)
        print(f"library: {takes} takes, {frames} frames in total ({frames / takes:.0f} per take)")
        results, table = {}, []
        for operation in args.operations.split(","):
            load = os.getloadavg()[0]
            seq, seq_cpu = sequential(library, work / f"seq-{operation}", operation)
            runs = {"sequential": {"wall_s": seq, "takes": takes, "frames": frames, "load_before": load,
                                   "cpu_ms_per_take": 1000 * seq_cpu / takes}}
            for workers in (1, 2):
                load = os.getloadavg()[0]
                runs[f"dask-{workers}"] = {**batch_run(library, work / f"dask{workers}-{operation}", operation,
                                                       workers), "load_before": load}
            results[operation] = runs
            for name, r in runs.items():
                table.append([operation, name, f"{r['wall_s']:.1f}", f"{r['takes'] / r['wall_s']:.1f}",
                              f"{r['frames'] / r['wall_s']:.0f}", f"{seq / r['wall_s']:.2f}x",
                              f"{r['cpu_ms_per_take']:.0f}", f"{r.get('startup_s', 0):.1f}",
                              _fmt(r.get("idle_per_take_ms")),
                              _fmt(r.get("noop_task_ms")),
                              f"{_fmt(r.get('rss_first_mib'), 0)} → {_fmt(r.get('rss_last_mib'), 0)}"
                              f" (max {_fmt(r.get('rss_max_mib'), 0)})" if "rss_first_mib" in r else "-",
                              f"{r['load_before']:.1f}"])
        print_table(f"usdmotion batch on {machine()['cpus']} cores ({takes} takes, {frames} frames)",
                    ["operation", "engine", "wall s", "takes/s", "frames/s", "vs loop", "CPU ms/take",
                     "start-up+imports s",
                     "idle ms/take", "no-op ms/task", "worker RSS MiB first→last", "load avg"], table)
        per_take = {op: results[op]["dask-1"]["cpu_ms_per_take"] / 1000 for op in results}
        print("on paper, from the CPU time per take on a worker: " +
              ", ".join(f"{op} {1000 * s:.0f} ms" for op, s in per_take.items()))
        paper = {}
        for op, s in per_take.items():
            bound = 1000 / max(results[op]["dask-2"]["noop_task_ms"] or 1, 0.2)  # no-op tasks/s through Dask here
            paper[op] = {"scheduler_tasks_per_s": bound,
                         **{name: min(cores / s, bound)
                            for name, cores in (("64_cores", 64), ("10_nodes_16_cores", 160))}}
            print(f"  {op}: 64 cores ≈ {64 / s:.0f} takes/s of work; 10 nodes x 16 cores ≈ {160 / s:.0f} takes/s; "
                  f"one scheduler fed from one client ran {bound:.0f} no-op tasks/s here, so ≈ "
                  f"{paper[op]['64_cores']:.0f} and {paper[op]['10_nodes_16_cores']:.0f} takes/s")
        path = write_results("batch", {"takes": takes, "frames": frames, "frames_per_take": args.frames,
                                       "results": results, "cpu_per_take_s": per_take,
                                       "on_paper_takes_per_s": paper})
        print(f"wrote {path}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _fmt(value, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


if __name__ == "__main__":
    main()

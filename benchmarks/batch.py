"""Batch throughput: ``run_batch`` on a local Dask cluster (1 and 2 worker processes) against
a plain sequential loop of the same library calls, in the same run, on a library of ≥ 500
takes built from ``../shared/data`` (windows of every readable shared BVH, renamed).

Engines, per operation, in one run:

* ``sequential``: the plain loop in this process, with the library's defaults (Arrow's CSV
  reader and ``usdmotion.parallel`` may use both cores inside a call): the headline peer;
* ``sequential-1t``: the same loop in a subprocess with one thread everywhere
  (``USDMOTION_THREADS=1``, ``OMP_NUM_THREADS=1``, so Arrow's pool and BLAS too), as each
  Dask worker runs it;
* ``dask-1``, ``dask-2``: ``run_batch`` on a LocalCluster of 1 and 2 worker processes (takes
  grouped into tasks, :data:`usdmotion.batch.plan.TASK_BYTES`);
* ``dask-2/take``: 2 workers, one take per task (``task_bytes=0``), the layout before grouping.

Measures takes/s and frames/s, the CPU per take (of the loop's process; for Dask of every
process of the run: client + scheduler, nannies, workers), the scheduler overhead per task
(no-op tasks) and the wall time not spent in takes, worker memory over the run (RSS sampled
every 0.5 s), the cluster start-up, and the 1-minute load average before each run (the
machine is shared: a loaded machine gives the batch fewer cores than it has workers).
``--pairs N`` then runs the loop and ``dask-2`` N more times, back to back (in turn first), and prints
each pair's wall-time ratio and their median: this machine's speed drifts by ±10-20 % from one
minute to the next (a pure-Python loop timed alone three times ran 708-936 iterations a second),
so one loop against one batch run minutes apart says little; pairs taken back to back do. Each
round then also runs two copies of the loop at once in two subprocesses with the workers'
one-thread environment (no Dask): what the two cores give two plain processes in that minute,
the ceiling the batch's ratio compares with. Every run also gives the share of CPU time the
hypervisor **stole** from this virtual machine meanwhile (``/proc/stat``'s steal ticks over
busy + steal ticks): the cloud host runs other guests' work on the same physical cores, and
the more cores this machine keeps busy, the more it can lose.
Warnings (e.g. IMPLAUSIBLE UNITS of the cgspeed takes read in centimetres) are collected,
as the batch collects them into its catalogue, and counted, not printed. Prints a table and
writes ``benchmarks/results/batch.json``.

    .venv/bin/python benchmarks/batch.py [--takes 500] [--frames 240] [--operations convert,analyze] [--pairs 3]
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import warnings
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
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # units guesses: the takes are written as read
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


def sequential(library: Path, out: Path, operation: str) -> dict:
    """The plain loop: the library calls the batch task makes (those of the single-file
    command: ``convert`` checks the paths and drops what a USD file does not write before
    writing), one take after another
    (warnings recorded, as the batch records them, not printed). Before the clock, the
    process is prepared as a Dask worker prepares itself (imports, one take)."""
    from usdmotion.anthropometry import body_model
    from usdmotion.errors import InputError
    from usdmotion.io import read_motion
    from usdmotion.io.convert import check_convert_paths, convert_motion, kept_for
    from usdmotion.ops.analyse import analyse
    from usdmotion.ops.analyse.report import summary, write_kinematics, write_summary

    from usdmotion.batch.engine import prepare_process

    prepare_process(operation)  # as warm_up does on the workers, before the clock
    files = sorted(library.rglob("*.bvh"))
    start, cpu, thread = time.perf_counter(), time.process_time(), time.thread_time()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for path in files:
            dst = out / path.relative_to(library).with_suffix("")
            dst.parent.mkdir(parents=True, exist_ok=True)
            if operation == "convert":  # the calls of the batch task and of `usdmotion convert`
                check_convert_paths(path, f"{dst}.usdc")
                convert_motion(kept_for(read_motion(path), f"{dst}.usdc"), f"{dst}.usdc", validate=True)
                continue
            motion = read_motion(path)
            try:
                body = body_model(motion, "male", None, source=str(path))
            except InputError:
                body = None
            kin = analyse(motion, body=body, source=str(path))
            write_summary(summary(kin, None, str(path)), f"{dst}.summary.json")
            write_kinematics(kin, f"{dst}.parquet", None, str(path))
    return {"wall_s": time.perf_counter() - start, "cpu_s": time.process_time() - cpu,
            "thread_cpu_s": time.thread_time() - thread, "warnings": len(caught)}


#: One thread everywhere, as in a worker of the local cluster (set before NumPy/Arrow/USD load).
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def sequential_one_thread(library: Path, out: Path, operation: str) -> dict:
    """:func:`sequential` in a fresh subprocess with :data:`ONE_THREAD`."""
    return sequential_processes(library, out, operation, 1)[0]


def sequential_processes(library: Path, out: Path, operation: str, copies: int) -> list[dict]:
    """``copies`` subprocesses at once, each running :func:`sequential` on the whole library
    with :data:`ONE_THREAD` (the workers' environment) into its own folder: with 2 copies,
    what this machine's two cores give two plain processes, without Dask."""
    code = ("import json, sys; sys.path.insert(0, sys.argv[1]); import batch; "
            "print(json.dumps(batch.sequential(batch.Path(sys.argv[2]), batch.Path(sys.argv[3]), sys.argv[4])))")
    from usdmotion.batch.engine import WORKER_ENV

    env = {**os.environ, **ONE_THREAD, **WORKER_ENV}
    env.pop("MALLOC_TRIM_THRESHOLD_", None)  # a LocalCluster started earlier in this process leaks Dask's setting
    procs = [subprocess.Popen([sys.executable, "-c", code, str(Path(__file__).parent), str(library),
                               str(out / f"copy{i}" if copies > 1 else out), operation],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for i in range(copies)]
    results = []
    for proc in procs:
        stdout, stderr = proc.communicate()
        if proc.returncode:
            raise subprocess.CalledProcessError(proc.returncode, proc.args, stdout, stderr)
        results.append(json.loads(stdout.strip().splitlines()[-1]))
    return results


def _tree_cpu() -> dict[int, float]:
    """CPU seconds (user + system) of this process and all its descendants, by pid."""
    import psutil

    me = psutil.Process()
    out = {}
    for proc in (me, *me.children(recursive=True)):
        try:
            times = proc.cpu_times()
            out[proc.pid] = times.user + times.system
        except psutil.Error:
            continue
    return out


def _rss(pids: list[int]) -> float:
    """Mean resident memory of the processes ``pids`` (bytes), read from /proc by psutil."""
    import psutil

    return sum(psutil.Process(pid).memory_info().rss for pid in pids) / len(pids)


def host_ticks() -> list[int] | None:
    """The whole machine's CPU ticks so far (``/proc/stat``: user, nice, system, idle, iowait,
    irq, softirq, steal), or None where there is no such file."""
    try:
        with open("/proc/stat") as f:
            return [int(x) for x in f.readline().split()[1:9]]
    except (OSError, ValueError):
        return None


def stolen_share(before: list[int] | None, after: list[int] | None) -> float | None:
    """Share of the time this machine's work wanted a CPU that the hypervisor gave to another
    guest (steal ticks over busy + steal ticks) between two :func:`host_ticks`: a virtual
    machine's two cores are two cores only when nobody else's work runs on them."""
    if before is None or after is None:
        return None
    d = [b - a for a, b in zip(before, after, strict=True)]
    busy = d[0] + d[1] + d[2] + d[5] + d[6] + d[7]
    return d[7] / busy if busy > 0 else None


def _noop(i: int) -> int:
    return i


def batch_run(library: Path, out: Path, operation: str, workers: int, task_bytes: int | None = None,
              noop: bool = False) -> dict:
    """``run_batch`` on a fresh LocalCluster; start-up timed apart; worker RSS sampled; CPU of
    every process of the run (client + scheduler, workers) over the run."""
    from usdmotion.batch import run_batch
    from usdmotion.batch.engine import dask_client, warm_up
    from usdmotion.batch.plan import TASK_BYTES, group_jobs, plan_jobs

    t0 = time.perf_counter()
    with dask_client(workers) as client:
        t1 = time.perf_counter()
        warm_up(client, operation)  # imports and one take, once per worker (as the loops before their clock)
        startup, warm = time.perf_counter() - t0, time.perf_counter() - t1
        samples, stop = [], threading.Event()
        pids = list(client.run(os.getpid).values())

        def sample() -> None:  # from /proc, not through Dask: no messages to the busy workers
            while not stop.is_set():
                try:
                    samples.append((time.perf_counter(), _rss(pids)))
                except Exception:  # noqa: BLE001 - a worker restarted meanwhile
                    pass
                stop.wait(0.5)

        sampler = threading.Thread(target=sample, daemon=True)
        cpu_before = _tree_cpu()
        sampler.start()
        result = run_batch(operation, library, out, params={"to": "usdc"} if operation == "convert" else {},
                           force=True, client=client, task_bytes=task_bytes)
        stop.set()
        sampler.join()
        cpu_after = _tree_cpu()
        client_cpu = cpu_after[os.getpid()] - cpu_before[os.getpid()]
        total_cpu = sum(t - cpu_before.get(pid, 0.0) for pid, t in cpu_after.items())
        overhead = None
        if noop:  # scheduler round trip per task: no-op tasks through the same cluster
            n = len(result.rows)
            t1 = time.perf_counter()
            client.gather(client.map(_noop, range(n), pure=False))
            overhead = (time.perf_counter() - t1) / n
    rows = result.rows
    jobs = plan_jobs(operation, library, out, {}, {})
    tasks = len(group_jobs(jobs, workers, TASK_BYTES[operation] if task_bytes is None else task_bytes))
    task_s = sum(r["seconds"] for r in rows)
    cpu_s = sum(r["cpu_seconds"] or 0 for r in rows)
    mem = [m for _, m in samples]
    tenth = max(1, len(mem) // 10)  # memory after the first tenth of the run against the last tenth
    return {"wall_s": result.seconds, "startup_s": startup, "warm_up_s": warm, "takes": len(rows), "tasks": tasks,
            "workers": workers, "result_bytes_per_take": statistics.mean(len(pickle.dumps(r)) for r in rows),
            "failed": len(result.failed),
            "frames": sum(r.get("frames") or 0 for r in rows), "task_s": task_s,
            "cpu_ms_per_take": 1000 * total_cpu / len(rows), "in_task_cpu_ms_per_take": 1000 * cpu_s / len(rows),
            "client_cpu_ms_per_take": 1000 * client_cpu / len(rows),
            "warnings": sum(bool(r.get("warnings")) for r in rows),
            "idle_per_take_ms": 1000 * (result.seconds * workers - task_s) / len(rows),
            "noop_task_ms": None if overhead is None else 1000 * overhead,
            "rss_first_mib": statistics.mean(mem[tenth:2 * tenth]) / 2**20 if len(mem) > 1 else None,
            "rss_last_mib": statistics.mean(mem[-tenth:]) / 2**20 if len(mem) > 1 else None,
            "rss_max_mib": max(mem) / 2**20 if mem else None, "rss_samples": len(mem)}


ENGINES = (("dask-1", 1, None), ("dask-2", 2, None), ("dask-2/take", 2, 0))


def run_operation(library: Path, work: Path, operation: str, takes: int, frames: int) -> dict:
    """Every engine on one operation, one after another; the 1-minute load average before each."""
    load, ticks = os.getloadavg()[0], host_ticks()
    seq = sequential(library, work / f"seq-{operation}", operation)
    runs = {"sequential": {**seq, "takes": takes, "frames": frames, "load_before": load,
                           "cpu_ms_per_take": 1000 * seq["cpu_s"] / takes, "stolen": stolen_share(ticks, host_ticks())}}
    load, ticks = os.getloadavg()[0], host_ticks()
    one = sequential_one_thread(library, work / f"seq1-{operation}", operation)
    runs["sequential-1t"] = {**one, "takes": takes, "frames": frames, "load_before": load,
                             "cpu_ms_per_take": 1000 * one["cpu_s"] / takes,
                             "stolen": stolen_share(ticks, host_ticks())}
    for name, workers, task_bytes in ENGINES:
        load, ticks = os.getloadavg()[0], host_ticks()
        runs[name] = {**batch_run(library, work / name.replace("/", "-") / operation, operation, workers, task_bytes,
                                  noop=name == "dask-2"), "load_before": load}
        runs[name]["stolen"] = stolen_share(ticks, host_ticks())  # with the no-op tasks: a second at most
    return runs


def alternated_pairs(library: Path, work: Path, operation: str, pairs: int) -> list[dict]:
    """``pairs`` rounds of the loop (in this process, as the table's) and ``dask-2`` back to back, the
    loop first in even rounds and second in odd ones (a drift of the machine's speed within a round
    then counts for the batch as often as against it): each round's wall times and ratio."""
    rounds = []

    def timed(run, *args) -> tuple[float, float | None]:
        before = host_ticks()
        wall = run(*args)
        return wall, stolen_share(before, host_ticks())

    def loop_s(out: Path) -> float:
        return sequential(library, out, operation)["wall_s"]

    def batch_s(out: Path) -> float:
        return batch_run(library, out, operation, 2)["wall_s"]

    def two_loops_s(out: Path) -> float:
        return max(r["wall_s"] for r in sequential_processes(library, out, operation, 2))

    for i in range(pairs):
        loop_out, batch_out = work / f"pair{i}-seq-{operation}", work / f"pair{i}-dask-2" / operation
        if i % 2:  # the batch first
            (batch, batch_stolen), (loop, loop_stolen) = timed(batch_s, batch_out), timed(loop_s, loop_out)
        else:
            (loop, loop_stolen), (batch, batch_stolen) = timed(loop_s, loop_out), timed(batch_s, batch_out)
        two_out = work / f"pair{i}-two-{operation}"
        two, two_stolen = timed(two_loops_s, two_out)
        rounds.append({"loop_s": loop, "dask2_s": batch, "ratio": loop / batch, "two_loops_s": two,
                       "two_loops_ratio": 2 * loop / two, "load": os.getloadavg()[0],
                       "stolen": {"loop": loop_stolen, "dask2": batch_stolen, "two_loops": two_stolen}})
        for done in (loop_out, batch_out.parent, two_out):
            shutil.rmtree(done, ignore_errors=True)  # an analyze round writes ~0.6 GB
        print(f"  {operation} pair {i + 1}: loop {loop:.1f} s, dask-2 {batch:.1f} s, {loop / batch:.2f}x; "
              f"two 1-thread loops at once {two:.1f} s, {2 * loop / two:.2f}x (load {rounds[-1]['load']:.1f}; CPU "
              f"stolen {_pct(loop_stolen)} / {_pct(batch_stolen)} / {_pct(two_stolen)})",
              flush=True)
    return rounds


def cpu_bound_ratio(runs: dict, name: str) -> float:
    """The wall-time ratio to the loop the run would give if every process had a core of its
    own (a quiet machine): the loop's main-thread CPU (its wall time there; its helper threads
    run beside it) against the CPU of every process of the run spread over its workers."""
    loop = runs["sequential"]["thread_cpu_s"] / runs["sequential"]["takes"]
    r = runs[name]
    if "thread_cpu_s" in r:  # a loop: its main thread
        return loop / (r["thread_cpu_s"] / r["takes"])
    return loop / (r["cpu_ms_per_take"] / 1000 / r["workers"])


def table_rows(operation: str, runs: dict) -> list[list]:
    seq, one = runs["sequential"]["wall_s"], runs["sequential-1t"]["wall_s"]
    rows = []
    for name, r in runs.items():
        rss = (f"{_fmt(r.get('rss_first_mib'), 0)} → {_fmt(r.get('rss_last_mib'), 0)} (max {_fmt(r.get('rss_max_mib'), 0)})"
               if "rss_first_mib" in r else "-")
        rows.append([operation, name, f"{r['wall_s']:.1f}", f"{r['takes'] / r['wall_s']:.1f}",
                     f"{r['frames'] / r['wall_s']:.0f}", f"{seq / r['wall_s']:.2f}x", f"{one / r['wall_s']:.2f}x",
                     f"{cpu_bound_ratio(runs, name):.2f}x", f"{r['cpu_ms_per_take']:.1f}", _fmt(r.get("client_cpu_ms_per_take")),
                     f"{r.get('startup_s', 0):.1f}", _fmt(r.get("idle_per_take_ms")), _fmt(r.get("noop_task_ms")),
                     rss, f"{r['load_before']:.1f}", _pct(r.get("stolen"))])
    return rows


def per_take_costs(results: dict) -> dict:
    """Where a take's time goes in a worker against the loop (ms of CPU per take unless said)."""
    costs = {}
    for op, runs in results.items():
        seq, one, d1, d2 = (runs[k] for k in ("sequential", "sequential-1t", "dask-1", "dask-2"))
        costs[op] = {"loop_main_thread": 1000 * seq["thread_cpu_s"] / seq["takes"],
                     "loop_all_threads": seq["cpu_ms_per_take"], "one_thread_loop": one["cpu_ms_per_take"],
                     "worker_in_task": d1["in_task_cpu_ms_per_take"], "dask1_all_processes": d1["cpu_ms_per_take"],
                     "dask2_all_processes": d2["cpu_ms_per_take"], "dask2_client_and_scheduler": d2["client_cpu_ms_per_take"],
                     "noop_task_round_trip_ms": d2["noop_task_ms"], "warm_up_s": d2["warm_up_s"],
                     "result_bytes_per_take": d2["result_bytes_per_take"], "takes_per_task": d2["takes"] / d2["tasks"]}
        c = costs[op]
        print(f"  {op}: loop {c['loop_main_thread']:.1f} ms main thread ({c['loop_all_threads']:.1f} all threads), "
              f"1-thread loop {c['one_thread_loop']:.1f}; in a worker {c['worker_in_task']:.1f} in-task, all processes "
              f"{c['dask1_all_processes']:.1f} (1 worker) / {c['dask2_all_processes']:.1f} (2; client + scheduler "
              f"{c['dask2_client_and_scheduler']:.1f}); per task: no-op round trip {c['noop_task_round_trip_ms']:.1f} ms, "
              f"{c['takes_per_task']:.0f} takes, {c['result_bytes_per_take']:.0f} B of result per take; "
              f"warm-up (imports + one take) {c['warm_up_s']:.1f} s per cluster")
    return costs


def on_paper(results: dict) -> dict:
    """Takes/s a 64-core machine and a 10-node x 16-core cluster would do: the CPU of a take on a
    worker (in-task, dask-1) against the cores, and the scheduler's no-op task rate measured here
    times the takes per task."""
    paper = {}
    for op, runs in results.items():
        per_take = runs["dask-1"]["in_task_cpu_ms_per_take"] / 1000
        tasks_per_s = 1000 / max(runs["dask-2"]["noop_task_ms"] or 1, 0.2)
        takes_per_task = runs["dask-2"]["takes"] / max(1, runs["dask-2"]["tasks"])
        bound = tasks_per_s * takes_per_task
        paper[op] = {"cpu_per_take_s": per_take, "scheduler_tasks_per_s": tasks_per_s,
                     "takes_per_task": takes_per_task,
                     **{name: min(cores / per_take, bound) for name, cores in (("64_cores", 64), ("10_nodes_16_cores", 160))}}
        print(f"  {op}: {1000 * per_take:.0f} ms CPU per take: 64 cores ≈ {64 / per_take:.0f} takes/s of work, "
              f"10 nodes x 16 cores ≈ {160 / per_take:.0f}; the scheduler ran {tasks_per_s:.0f} no-op tasks/s here "
              f"x {takes_per_task:.0f} takes per task ≈ {bound:.0f} takes/s, so ≈ {paper[op]['64_cores']:.0f} "
              f"and {paper[op]['10_nodes_16_cores']:.0f} takes/s (at 64 cores TASK_BYTES keeps ≥ 4 tasks per core)")
    return paper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=500)
    parser.add_argument("--frames", type=int, default=240, help="frames per take (shorter sources whole)")
    parser.add_argument("--operations", default="convert,analyze")
    parser.add_argument("--pairs", type=int, default=0,
                        help="then N rounds of the loop and dask-2 back to back: the median of their ratios")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="usdmotion-batch-bench-"))
    try:
        library = work / "library"
        takes, frames = build_library(library, args.takes, args.frames)
        print(f"library: {takes} takes, {frames} frames in total ({frames / takes:.0f} per take)")
        results, table = {}, []
        for operation in args.operations.split(","):
            results[operation] = run_operation(library, work, operation, takes, frames)
            table += table_rows(operation, results[operation])
        print_table(f"usdmotion batch on {machine()['cpus']} cores ({takes} takes, {frames} frames); CPU: of every "
                    "process of the run, ms per take", ["operation", "engine", "wall s", "takes/s", "frames/s",
                    "vs loop", "vs 1t loop", "CPU-bound vs loop", "CPU ms/take", "client CPU", "start-up+warm-up s", "idle ms/take",
                    "no-op ms/task", "worker RSS MiB first→last", "load avg", "CPU stolen"], table)
        costs = per_take_costs(results)
        paper = on_paper(results)
        pairs = {}
        for operation in args.operations.split(",") if args.pairs else ():
            pairs[operation] = alternated_pairs(library, work, operation, args.pairs)
            ratios = [r["ratio"] for r in pairs[operation]]
            ceilings = [r["two_loops_ratio"] for r in pairs[operation]]
            print(f"  {operation}: dask-2 against the loop, {args.pairs} alternated pairs: median "
                  f"{statistics.median(ratios):.2f}x (" + ", ".join(f"{r:.2f}" for r in ratios) + "); two plain "
                  f"1-thread loops at once in the same rounds: median {statistics.median(ceilings):.2f}x ("
                  + ", ".join(f"{r:.2f}" for r in ceilings) + ")")
        path = write_results("batch", {"takes": takes, "frames": frames, "frames_per_take": args.frames,
                                       "results": results, "per_take_costs": costs, "on_paper_takes_per_s": paper,
                                       "alternated_pairs": pairs})
        print(f"wrote {path}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _fmt(value, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _pct(share: float | None) -> str:
    return "-" if share is None else f"{100 * share:.0f} %"


if __name__ == "__main__":
    main()

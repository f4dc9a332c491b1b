"""Whole-process start-up: ``usdmotion --version``, ``info`` and ``convert``, against ``python -c pass``.

    .venv/bin/python benchmarks/startup.py [--repeat 5]

Each command runs as a new process running the console script's code (``usdmotion.__main__.run``:
what a user waits for, interpreter exit included), ``--repeat`` times after one warm-up,
the trees (``--tree``) taking turns; the table shows medians, each command's time over the
bare interpreter's in the same run, and its CPU time (user + system, all threads:
steadier than wall time on a loaded machine). Modules run from bytecode, as from an installed package (pip compiles it at
install): the processes write and read it under a temporary ``PYTHONPYCACHEPREFIX``, so
the warm-up compiles and ``PYTHONDONTWRITEBYTECODE`` in the caller's environment does not
make every run recompile the package (about 0.02 s; ``--no-bytecode`` measures that way).
A second table splits the ``convert`` → USDC process's import time (``-X importtime``,
self times summed by top-level package, the least of three extra runs; its total exceeds
the timed runs' because of the instrumentation), and a third the CPU time and page faults of
each step of one such convert done step by step (imports, read, write as the command does by
default; not the command-line parsing and exit). Inputs: the bundled CMU walk tiled to 1,730 frames (1.3 MB,
for ``info``) and to 5,000 frames (31 joints, for ``convert`` to .usdc and .bvh). Goals (issue 11):
``info`` ≤ 0.30 s and ``convert`` to USDC ≤ 0.40 s whole process. The modules each command
imported are listed too (``-X importtime`` would slow the run; ``sys.modules`` at exit).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, print_table, tiled_bvh, write_results  # noqa: E402

PYTHON = sys.executable
WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
HEAVY = ("jax", "pandas", "pyrender", "scipy.signal", "scipy", "pxr", "pyarrow", "matplotlib", "numpy", "pydantic", "rich")
#: Every row imports usdmotion from PYTHONPATH (this checkout's or a --tree's), not through the editable install's finder.
NO_EDITABLE = "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]"
#: The console script's own code (``usdmotion = usdmotion.__main__:run``): what a user's process runs, exit included.
CLI = f"import sys; {NO_EDITABLE}; from usdmotion.__main__ import run; sys.exit(run())"
MODULES = ("import atexit, sys\n" + NO_EDITABLE + "\n"
           "atexit.register(lambda: print('MODULES', [m for m in {heavy!r} if m in sys.modules], file=sys.stderr))\n"
           "from usdmotion.cli import main; sys.exit(main(sys.argv[1:]))")


def run_once(args: list[str], env: dict | None) -> tuple[float, float] | None:
    """``(wall s, CPU s of the process: user + system, all its threads)`` of one run, None if it failed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tempfile.gettempdir())
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        print(f"{' '.join(map(str, args))} failed: {done.stderr.strip()}", file=sys.stderr)
        return None
    return elapsed, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def whole_processes(runs: dict[str, tuple[list[str], dict]], repeat: int) -> dict[str, dict]:
    """Median/min wall and median CPU time of each labelled ``(args, env)`` as a new process, ``repeat``
    times after one warm-up, the labels taking turns (a load that drifts affects them alike)."""
    samples: dict[str, list[tuple[float, float]]] = {label: [] for label in runs}
    for i in range(repeat + 1):
        for label, (args, env) in runs.items():
            if samples[label] is None:
                continue
            sample = run_once(args, env)
            if sample is None:  # e.g. --version, which an older checkout lacks
                samples[label] = None
            elif i:
                samples[label].append(sample)
    return {label: {"median_s": statistics.median(w for w, _ in s), "min_s": min(w for w, _ in s),
                    "cpu_median_s": statistics.median(c for _, c in s), "runs": repeat}
            for label, s in samples.items() if s is not None}


def imported(cli_args: list[str], env: dict | None = None) -> list[str]:
    done = subprocess.run([PYTHON, "-c", MODULES.format(heavy=HEAVY), *cli_args], capture_output=True, text=True,
                          env=env, cwd=tempfile.gettempdir())
    line = next(line for line in done.stderr.splitlines() if line.startswith("MODULES"))
    return json.loads(line.split(" ", 1)[1].replace("'", '"'))


#: One ``convert`` → .usdc done step by step in a fresh process (the library calls the command makes),
#: printing the process's CPU time (user + system) and page faults after each step.
PHASES = """import json, resource, sys, warnings
def mark(label):
    r = resource.getrusage(resource.RUSAGE_SELF)
    marks.append((label, r.ru_utime + r.ru_stime, r.ru_minflt))
marks = []
mark("interpreter start-up")
""" + NO_EDITABLE + """
import usdmotion.__main__
getattr(usdmotion.__main__, "prepare_process", lambda: None)()  # the entry point's settings, where it has them
import typer, usdmotion.cli.convert
mark("typer and the CLI modules")
import numpy
mark("NumPy")
import usdmotion.io.convert, usdmotion.io.bvh, usdmotion.io.usd
mark("usdmotion library modules")
from pxr import Sdf
mark("pxr.Sdf (Tf, Gf, Vt, Ar, Ts, Plug: what it loads)")
from usdmotion.io import read_motion
from usdmotion.io.convert import convert_motion, kept_for
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    motion = kept_for(read_motion(sys.argv[1]), sys.argv[2])
mark("read the BVH (parse, Euler to quaternions, units guess)")
convert_motion(motion, sys.argv[2])  # a plain Motion: older trees take no handed-over list
mark("write the .usdc as convert does by default (layer, samples, extent, check, save; validation where on)")
print("PHASES " + json.dumps(marks))
"""


def phases(source: Path, output: Path, env: dict, runs: int = 3) -> list[tuple[str, float, int]]:
    """``(step, CPU s, page faults)`` of :data:`PHASES`, each the least of ``runs`` fresh processes."""
    least: dict[str, tuple[float, int]] = {}
    for _ in range(runs):
        done = subprocess.run([PYTHON, "-c", PHASES, str(source), str(output)], capture_output=True, text=True,
                              env=env, cwd=tempfile.gettempdir(), check=True)
        marks = json.loads(next(line for line in done.stdout.splitlines() if line.startswith("PHASES "))[7:])
        before = (0.0, 0)
        for label, cpu, faults in marks:
            step = (cpu - before[0], faults - before[1])
            least[label] = tuple(map(min, zip(least.get(label, step), step)))
            before = (cpu, faults)
    return [(label, cpu, faults) for label, (cpu, faults) in least.items()]


def import_breakdown(cli_args: list[str], trees: dict[str, dict], runs: int = 3) -> dict[str, dict[str, float]]:
    """Per tree: seconds of import (self times) by top-level package, the least of ``runs``
    ``-X importtime`` runs (the trees taking turns)."""
    least: dict[str, dict[str, float]] = {label: {} for label in trees}
    for _ in range(runs):
        for label, env in trees.items():
            done = subprocess.run([PYTHON, "-X", "importtime", "-c", CLI, *cli_args], capture_output=True, text=True,
                                  env=env, cwd=tempfile.gettempdir())
            totals: dict[str, float] = {}
            for line in done.stderr.splitlines():
                if line.startswith("import time:") and "|" in line and not line.rstrip().endswith("package"):
                    self_us, _, name = (part.strip() for part in line.removeprefix("import time:").split("|"))
                    top = name.split(".")[0]
                    totals[top] = totals.get(top, 0.0) + int(self_us) / 1e6
            least[label] = {k: min(v, least[label].get(k, v)) for k, v in totals.items()}
    return least


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--tree", action="append", default=[], metavar="LABEL=PATH",
                        help="also run the commands with PYTHONPATH=PATH (another checkout), labelled LABEL")
    parser.add_argument("--no-bytecode", action="store_true",
                        help="keep the caller's PYTHONDONTWRITEBYTECODE (every run compiles the package)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base_env = dict(os.environ)
        if not args.no_bytecode:
            base_env.pop("PYTHONDONTWRITEBYTECODE", None)
            base_env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        trees = {"": {**base_env, "PYTHONPATH": str(REPO)}}
        for tree in args.tree:
            label, path = tree.split("=", 1)
            trees[f"{label}: "] = {**base_env, "PYTHONPATH": path}
        info_file = tiled_bvh(WALK, 1730, tmp / "walk_1730.bvh")
        convert_file = tiled_bvh(WALK, 5000, tmp / "walk_5000.bvh")
        cases = {
            "python -c pass": [PYTHON, "-c", "pass"],
            "usdmotion --version": ["--version"],
            f"usdmotion info ({info_file.stat().st_size / 1e6:.1f} MB)": ["info", str(info_file), "--units", "asf"],
            "usdmotion convert 5000 frames -> .usdc": ["convert", str(convert_file), str(tmp / "out.usdc")],
            "usdmotion convert 5000 frames -> .bvh": ["convert", str(convert_file), str(tmp / "out.bvh")],
        }
        results = whole_processes({"python -c pass": (cases.pop("python -c pass"), base_env)}, args.repeat)
        for name, cli_args in cases.items():
            measured = whole_processes({label + name: ([PYTHON, "-c", CLI, *cli_args], env)
                                        for label, env in trees.items()}, args.repeat)
            if name not in measured:
                raise SystemExit(f"{name} failed in this tree")
            for label, env in trees.items():
                if label + name in measured:
                    results[label + name] = {**measured[label + name], "imports": imported(cli_args, env)}
        breakdown = import_breakdown(cases["usdmotion convert 5000 frames -> .usdc"], trees)
        steps = {label: phases(convert_file, tmp / "phases.usdc", env) for label, env in trees.items()}
    base = results["python -c pass"]["median_s"]
    rows = [[name, f"{r['median_s']:.3f}", f"{r['min_s']:.3f}", f"{r['median_s'] / base:.1f}x", f"{r['cpu_median_s']:.3f}",
             " ".join(r.get("imports", []))] for name, r in results.items()]
    print_table(f"whole-process time, median of {args.repeat}, {'from source' if args.no_bytecode else 'from bytecode'}, "
                f"1-min load average {os.getloadavg()[0]:.1f} (interpreter: {PYTHON})",
                ["command", "median s", "min s", "over python", "CPU s", "heavy modules imported"], rows)
    groups = sorted({g for b in breakdown.values() for g in b}, key=lambda g: -max(b.get(g, 0) for b in breakdown.values()))
    print()
    print_table("import time of convert -> .usdc by top-level package, s (self times, -X importtime)",
                ["package"] + [label.rstrip(": ") or "this tree" for label in breakdown],
                [[g] + [f"{b.get(g, 0.0):.3f}" for b in breakdown.values()] for g in groups[:12]]
                + [["all imports"] + [f"{sum(b.values()):.3f}" for b in breakdown.values()]])
    print()
    by_tree = [{step: (cpu, faults) for step, cpu, faults in tree_steps} for tree_steps in steps.values()]
    print_table("convert -> .usdc step by step in one process: CPU s (user + system) / page faults, "
                "least of 3 processes", ["step"] + [label.rstrip(": ") or "this tree" for label in steps],
                [[step] + [f"{t[step][0]:.3f} / {t[step][1]}" for t in by_tree] for step in by_tree[0]]
                + [["all"] + [f"{sum(c for c, _ in t.values()):.3f} / {sum(f for _, f in t.values())}"
                              for t in by_tree]])
    path = write_results("startup", {"repeat": args.repeat, "trees": args.tree, "bytecode": not args.no_bytecode,
                                     "load_average_1min": os.getloadavg()[0],
                                     "goals_s": {"info": 0.30, "convert_usdc": 0.40},
                                     "results": results, "convert_usdc_import_s": breakdown,
                                     "convert_usdc_steps": {label.rstrip(": ") or "this tree": t
                                                            for label, t in steps.items()}})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

"""Where the time of a cross-rig retarget goes, and the plain LM solve's variants side by side.

For every pair of ``benchmarks/retarget_contacts.py`` (issue 17's ≥ 10,000 frames/s goal):

1. **Stage profile** of the contact-aware ``retarget`` call (after a warm-up call):
   milliseconds in ``prepare`` (rig, map, targets, initial guesses), the initial-guess
   choice, the jitted LM solve, ``aim_single_points``, the leg IK (``place_legs``), the
   unmapped-joint rules, quality metrics and report; with the skeleton's size (joints,
   joints the solve needs, optimised rotations, mapped points), the chunking and the LM
   iterations. The benchmark's frames/s count the solve and the leg IK only.
2. **Solve variants**, timed in turns in one process (min of ``--repeat`` runs each, so the
   machine's load hits them alike): ``all joints`` (forward kinematics over every joint of
   the rig, as before ``solve.needed_joints``), ``needed joints``, ``nielsen`` (needed
   joints, Nielsen's damping update), all three on one CPU device, and ``nielsen, all CPU
   devices`` (the default: the frames split over one JAX CPU device per core,
   ``solve.frame_shards``). Columns: ms, frames/s, ratio to ``all joints``, LM iterations,
   the summed final loss and the largest joint-position difference from ``all joints``
   (target units); the last table gives the default's speed-up over ``nielsen`` on one device.

Run: ``python benchmarks/retarget_solve_speed.py [--pairs TEXT[,TEXT...]] [--repeat N]``.
Writes ``benchmarks/results/retarget_solve_speed.json``.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, print_table, write_results  # noqa: E402
from retarget_contacts import load_pair, pairs_with_data  # noqa: E402

STAGES = ("prepare", "_choose_init", "solve", "aim_single_points", "place_legs", "unmapped_rules",
          "continuous_hemisphere", "quality", "build")


def _instrument(pipeline, seconds: dict, captured: dict) -> None:
    """Wrap the pipeline's stages to add their wall time to ``seconds``; keep the solve's inputs."""
    owners = {"quality": pipeline.retarget_quality, "build": pipeline.retarget_report}
    for name in STAGES:
        owner = owners.get(name, pipeline)
        original = getattr(owner, name)

        @functools.wraps(original)
        def timed(*args, _original=original, _name=name, **kwargs):
            began = time.perf_counter()
            out = _original(*args, **kwargs)
            seconds[_name] += time.perf_counter() - began
            if _name == "solve":
                captured.update(args=args, solution=out)
            return out

        setattr(owner, name, timed)


def _variants(solve_module, args, repeat: int) -> dict:
    """The plain solve of captured inputs under each variant, timed in turns."""
    from usdmotion.kinematics import fk_arrays

    problem, q0, t0, targets = args[:4]
    every = lambda p: (p, np.ones(len(p.parents), bool))  # noqa: E731
    needed = solve_module.needed_joints
    variants = {"all joints": (every, "fixed", 1), "needed joints": (needed, "fixed", 1),
                "nielsen": (needed, "nielsen", 1), "nielsen, all CPU devices": (needed, "nielsen", None)}
    best, results = defaultdict(lambda: np.inf), {}
    try:
        for _ in range(repeat + 1):  # the first round compiles
            for name, (cut, damping, shards) in variants.items():
                solve_module.needed_joints = cut
                sol = solve_module.solve(problem, q0, t0, targets, damping=damping, shards=shards)
                best[name] = min(best[name], sol.run_s) if name in results else np.inf
                results[name] = sol
    finally:
        solve_module.needed_joints = needed
    base = fk_arrays(results["all joints"].q, results["all joints"].t, problem.parents)[1]
    out = {}
    for name, sol in results.items():
        moved = np.linalg.norm(fk_arrays(sol.q, sol.t, problem.parents)[1] - base, axis=-1)
        out[name] = {"ms": 1e3 * best[name], "fps": q0.shape[0] / best[name], "iterations": sol.iterations,
                     "loss": float(sol.loss.sum()), "max_position_diff": float(moved.max())}
    for name in out:
        out[name]["ratio"] = out["all joints"]["ms"] / out[name]["ms"]
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", default="", help="comma-separated texts: only the pairs whose label contains one")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of every solve variant (default 5)")
    args = parser.parse_args(argv)
    from usdmotion.ops.contacts import detect_contacts
    from usdmotion.ops.retarget import pipeline
    from usdmotion.ops.retarget.jax_runtime import device_description, enable_compilation_cache, use_cpu_cores
    from usdmotion.ops.retarget.solve import needed_joints

    solve_module = importlib.import_module("usdmotion.ops.retarget.solve")
    enable_compilation_cache()
    cpu_devices = use_cpu_cores()
    seconds, captured = defaultdict(float), {}
    _instrument(pipeline, seconds, captured)
    rows = []
    for label, source_spec, target_spec, target_kw in pairs_with_data(args.pairs):
        source, target, path, _, options = load_pair(source_spec, target_spec, target_kw)
        contacts = detect_contacts(source, source=path)
        call = functools.partial(pipeline.retarget, source, target, contacts=contacts, source_path=path, **options)
        call()  # compiles
        seconds.clear()
        began = time.perf_counter()
        result = call()
        total = time.perf_counter() - began
        stages = {k: 1e3 * seconds[k] for k in STAGES}
        solution, problem = captured["solution"], captured["args"][0]
        row = {"pair": label, "frames": source.n_frames, "joints": len(problem.parents),
               "needed_joints": int(needed_joints(problem)[1].sum()), "rotations": len(problem.rot_joints),
               "mapped": len(problem.mapped), "chunk": solution.chunk, "calls": solution.calls,
               "iterations": solution.iterations, "total_ms": 1e3 * total, "stages_ms": stages,
               "frames_per_second_solve": result.report["frames_per_second_solve"],
               "variants": _variants(solve_module, captured["args"], args.repeat), "load_1min": os.getloadavg()[0]}
        rows.append(row)
        print(f"{label}: {total * 1e3:.0f} ms, load {row['load_1min']:.1f}", flush=True)
    print()
    print_table(f"Stage profile of the contact-aware retarget, ms ({device_description()}; 1-min load "
                f"{os.getloadavg()[0]:.1f})",
                ["pair", "frames", "joints (needed)", "rot / mapped", "chunk x calls", "LM it", *STAGES, "total",
                 "frames/s solve"],
                [[r["pair"], r["frames"], f"{r['joints']} ({r['needed_joints']})", f"{r['rotations']} / {r['mapped']}",
                  f"{r['chunk']} x {r['calls']}", r["iterations"], *(f"{r['stages_ms'][k]:.1f}" for k in STAGES),
                  f"{r['total_ms']:.0f}", f"{r['frames_per_second_solve']:,.0f}"] for r in rows])
    print()
    print_table("Plain LM solve variants, timed in turns (min of runs; ratio: time of 'all joints' / this)",
                ["pair", "variant", "ms", "frames/s", "ratio", "LM it", "loss", "max position diff"],
                [[r["pair"], name, f"{v['ms']:.1f}", f"{v['fps']:,.0f}", f"{v['ratio']:.2f}", v["iterations"],
                  f"{v['loss']:.6g}", f"{v['max_position_diff']:.3g}"] for r in rows for name, v in r["variants"].items()])
    print()
    print_table("The default (frames split over every CPU device) against one device, same run",
                ["pair", "ms one device", "ms all devices", "speed-up", "LM it (one / all)", "chunk"],
                [[r["pair"], f"{one['ms']:.1f}", f"{every['ms']:.1f}", f"{one['ms'] / every['ms']:.2f}x",
                  f"{one['iterations']} / {every['iterations']}", r["chunk"]]
                 for r in rows
                 for one, every in [(r["variants"]["nielsen"], r["variants"]["nielsen, all CPU devices"])]])
    path = write_results("retarget_solve_speed", {"device": device_description(), "cpu_devices": cpu_devices,
                                                  "rows": rows})
    print(f"\nwrote {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

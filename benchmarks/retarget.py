"""Retargeting benchmark: the default solver against the paper's per-frame Adam, the
paper experiment (about half of the CMU joints removed) and cross-rig cases.

    PYTHONPATH=. python benchmarks/retarget.py [--file cmu86/86_01_from_amc_cgspeed_layout.bvh]
                                               [--adam-sample 48] [--repeats 3] [--quick]

Speed (one run, same machine, same loss, same frames): the default method (LM) solves
every frame of the take; the paper's method (Adam, lr 0.1, 500 iterations, one frame at a
time, as the paper ran it) is timed on ``--adam-sample`` frames spread over the take and
its frames/s extrapolated — the table says so. Adam vmapped over a block of frames
(mathematically the same per-frame optimiser) is timed too. Losses are compared on the
frames both solved. Compile time is reported apart. Prints tables, writes
``benchmarks/results/retarget.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = Path(os.environ.get("USDMOTION_SHARED_DATA", REPO.parent / "shared" / "data"))

#: The paper experiment (docs/retarget.md): list A removes 13 of the 31 CMU (cgspeed) joints
#: (31 -> 18, also the speed case); list B removes 14 (31 -> 17: the zero-length joints
#: except Spine1's parent chain, the hand detail and the toes).
PAPER_REMOVE = ["LHipJoint", "RHipJoint", "LowerBack", "Spine1", "Neck", "LeftShoulder", "RightShoulder",
                "LeftFingerBase", "RightFingerBase", "LeftHandIndex1", "RightHandIndex1", "LThumb", "RThumb"]
PAPER_REMOVE_B = ["LHipJoint", "RHipJoint", "LowerBack", "Neck", "LeftShoulder", "RightShoulder", "LeftFingerBase",
                  "RightFingerBase", "LeftHandIndex1", "RightHandIndex1", "LThumb", "RThumb", "LeftToeBase",
                  "RightToeBase"]
ALIASES = {"LeftHandIndex1": "LFingers", "RightHandIndex1": "RFingers"}


def read(relative: str, **kw):
    from usdmotion.io import read_motion

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_motion(SHARED / relative, **kw)


def removal_list(motion, names=PAPER_REMOVE) -> list[str]:
    return [n if n in motion.joint_names else ALIASES.get(n, n) for n in names]


def centred_problem(motion, remove):
    from usdmotion.ops.retarget.pipeline import _problem, prepare

    setup = prepare(motion, remove=remove)
    centre = setup.translations[:, 0].copy()
    t0 = setup.translations.copy()
    t0[:, 0] -= centre
    return setup, _problem(setup), t0, setup.targets[:, setup.mapped] - centre[:, None]


def losses(setup, q, t, frames):
    from usdmotion.ops.retarget.pipeline import frame_losses

    centre = setup.translations[frames, 0]
    targets = setup.targets[frames] - centre[:, None]
    return frame_losses(t, q, setup.rig.parents, setup.mapped, targets, setup.weights)


def speed(motion, adam_sample: int, adam_block: int, repeats: int) -> dict:
    from usdmotion.ops.retarget.solve import solve

    setup, problem, t0, targets = centred_problem(motion, removal_list(motion))
    n = motion.n_frames
    q_lm0, q_paper = setup.inits["compose"], setup.inits["copy"]
    first = solve(problem, q_lm0, t0, targets)  # compiles
    runs = [solve(problem, q_lm0, t0, targets) for _ in range(repeats)]
    lm = min(runs, key=lambda s: s.run_s)
    sample = np.unique(np.linspace(0, n - 1, adam_sample).round().astype(int))
    per_frame = []
    compile_adam = 0.0
    for f in sample:  # the paper's way: one frame after another
        s = solve(problem, q_paper[f:f + 1], t0[f:f + 1], targets[f:f + 1], method="adam", chunk=1)
        compile_adam += s.compile_s
        per_frame.append(s)
    adam_seconds = sum(s.run_s for s in per_frame)
    adam_q = np.concatenate([s.q for s in per_frame])
    adam_t = np.concatenate([s.t for s in per_frame])
    block = np.unique(np.linspace(0, n - 1, adam_block).round().astype(int))
    solve(problem, q_paper[block], t0[block], targets[block], method="adam")  # compiles
    batched = solve(problem, q_paper[block], t0[block], targets[block], method="adam")
    loss_lm_sample = float(losses(setup, lm.q[sample], lm.t[sample], sample).sum())
    loss_adam_sample = float(losses(setup, adam_q, adam_t, sample).sum())
    loss_lm_block = float(losses(setup, lm.q[block], lm.t[block], block).sum())
    loss_adam_block = float(losses(setup, batched.q, batched.t, block).sum())
    copied_sample = float(losses(setup, q_paper[sample], t0[sample], sample).sum())
    fps_lm = n / lm.run_s
    fps_adam = len(sample) / adam_seconds
    return {
        "file": None, "frames": n, "target_joints": int((~setup.rig.end_sites).sum()),
        "source_joints": int((~motion.end_sites).sum()), "mapped_points": int(len(setup.mapped)),
        "parameters_per_frame": problem.n_params,
        "lm": {"frames_per_second": fps_lm, "seconds_all_frames": lm.run_s, "compile_s": first.compile_s,
               "runs_s": [s.run_s for s in runs], "chunk": lm.chunk, "calls": lm.calls,
               "iterations": lm.iterations, "loss_on_adam_sample": loss_lm_sample, "loss_on_adam_block": loss_lm_block,
               "loss_all_frames": float(losses(setup, lm.q, lm.t, np.arange(n)).sum())},
        "adam_per_frame": {"frames_timed": int(len(sample)), "frames_per_second": fps_adam,
                           "seconds_all_frames_extrapolated": n / fps_adam, "compile_s": compile_adam,
                           "loss_on_sample": loss_adam_sample, "copied_loss_on_sample": copied_sample},
        "adam_vmapped": {"frames_timed": int(len(block)), "frames_per_second": len(block) / batched.run_s,
                         "compile_s": 0.0, "loss_on_block": loss_adam_block},
        "speedup_vs_adam_per_frame": fps_lm / fps_adam,
        "speedup_vs_adam_vmapped": fps_lm / (len(block) / batched.run_s),
        "lm_loss_over_adam_loss_on_sample": loss_lm_sample / loss_adam_sample if loss_adam_sample > 0 else None,
    }


def paper_experiment(files) -> list[dict]:
    from usdmotion.ops.retarget.pipeline import retarget

    rows = []
    for relative in files:
        motion = read(relative)
        for label, names in (("A", PAPER_REMOVE), ("B", PAPER_REMOVE_B)):
            for directions in ("mean", "rest"):
                r = retarget(motion, remove=removal_list(motion, names), directions=directions, source_path=relative)
                loss = r.report["loss"]
                joints = f"{int((~motion.end_sites).sum())} -> {r.report['target_joints_without_end_sites']}"
                rows.append({"file": relative, "frames": motion.n_frames, "list": label, "directions": directions,
                             "joints": joints, "removed": r.report["removed"], "copied_loss": loss["copied"]["total"],
                             "initial_loss": loss["initial"]["total"], "final_loss": loss["final"]["total"],
                             "final_over_copied": loss["final_over_copied"], "final_rms": loss["final"]["rms"],
                             "per_joint_rms": r.report["per_joint_rms"], "iterations": r.report["iterations_run"]})
    return rows


def cross_rig(source_file: str, targets) -> list[dict]:
    from usdmotion.ops.retarget.pipeline import retarget

    source = read(source_file, units="asf")
    rows = []
    for target_file in targets:
        target = read(target_file)
        for lengths in ("source", "target"):
            r = retarget(source, target, lengths=lengths, source_path=source_file, target_path=target_file)
            rep = r.report
            rows.append({"source": source_file, "target": target_file, "lengths": lengths, "map": rep["map"]["how"],
                         "mapped": rep["mapped_joints"], "initial_rms": rep["loss"]["initial"]["rms"],
                         "final_rms": rep["loss"]["final"]["rms"], "per_joint_rms": rep["per_joint_rms"],
                         "frames_per_second": rep["frames_per_second_solve"], "units": "cm"})
    return rows


def print_speed(console, s: dict) -> None:
    from rich.table import Table

    from usdmotion.ops.retarget.jax_runtime import device_description

    table = Table(title=f"{s['file']}: {s['source_joints']} -> {s['target_joints']} joints, {s['frames']} frames "
                        f"({s['parameters_per_frame']} parameters/frame, {device_description()}, float32)")
    for col in ("method", "frames timed", "frames/s", "time, all frames", "vs paper Adam", "loss (same frames)"):
        table.add_column(col, justify="right" if col != "method" else "left")
    lm, ad, av = s["lm"], s["adam_per_frame"], s["adam_vmapped"]
    table.add_row(f"default (LM, {lm['iterations']} it., all frames at once)", f"{s['frames']} (all)",
                  f"{lm['frames_per_second']:,.0f}", f"{lm['seconds_all_frames']:.3f} s",
                  f"{s['speedup_vs_adam_per_frame']:,.0f}x", f"{lm['loss_on_adam_sample']:.6g} (sample)")
    table.add_row("paper: Adam lr 0.1 x 500, per frame", f"{ad['frames_timed']} (sample)",
                  f"{ad['frames_per_second']:,.1f}", f"{ad['seconds_all_frames_extrapolated']:.1f} s (extrapolated)",
                  "1x", f"{ad['loss_on_sample']:.6g} (sample)")
    table.add_row("paper's Adam, vmapped over frames", f"{av['frames_timed']} (block)",
                  f"{av['frames_per_second']:,.1f}", f"{s['frames'] / av['frames_per_second']:.1f} s (extrapolated)",
                  f"{av['frames_per_second'] / ad['frames_per_second']:.1f}x",
                  f"{av['loss_on_block']:.6g} vs LM {lm['loss_on_adam_block']:.6g} (block)")
    console.print(table)
    runs = ", ".join(f"{x:.3f}" for x in lm["runs_s"])
    console.print(f"compile: LM {lm['compile_s']:.1f} s, Adam per frame {ad['compile_s']:.1f} s (not in the times "
                  f"above); LM runs {runs} s (best taken)")


def print_paper(console, rows: list[dict]) -> None:
    from rich.table import Table

    table = Table(title="paper experiment: about half of the 31 CMU joints removed (list A: 13, list B: 14); loss "
                        "before = rotations copied, offsets adapted; paper: 0.11 % / 0.23 %")
    for col in ("file", "frames", "list", "joints", "step 1 directions", "loss before", "final loss",
                "final / before", "worst joint (RMS, file units)"):
        table.add_column(col, justify="left" if col in ("file", "step 1 directions", "list") else "right")
    for r in rows:
        worst = max(r["per_joint_rms"].items(), key=lambda kv: kv[1])
        table.add_row(r["file"], str(r["frames"]), r["list"], r["joints"], r["directions"],
                      f"{r['copied_loss']:.6g}", f"{r['final_loss']:.6g}", f"{100 * r['final_over_copied']:.3f} %",
                      f"{worst[0]} {worst[1]:.3f}")
    console.print(table)


def print_cross(console, rows: list[dict]) -> None:
    from rich.table import Table

    table = Table(title="cross-rig: CMU walk (ASF units) -> target rig (cm); per-joint RMS error in cm")
    for col in ("target", "bone lengths", "mapped", "RMS before", "RMS after", "worst joints (RMS cm)"):
        table.add_column(col)
    for r in rows:
        worst = sorted(r["per_joint_rms"].items(), key=lambda kv: -kv[1])[:3]
        table.add_row(r["target"], r["lengths"], str(r["mapped"]), f"{r['initial_rms']:.2f}",
                      f"{r['final_rms']:.2f}", ", ".join(f"{k} {v:.1f}" for k, v in worst))
    console.print(table)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--file", default="cmu86/86_01_from_amc_cgspeed_layout.bvh")
    parser.add_argument("--adam-sample", type=int, default=48, help="frames for the per-frame Adam timing")
    parser.add_argument("--adam-block", type=int, default=256, help="frames for the vmapped Adam timing")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="speed table only")
    args = parser.parse_args(argv)
    from rich.console import Console

    from usdmotion.ops.retarget.jax_runtime import device_description

    console = Console(width=150)
    result = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "device": device_description(),
                          "dtype": "float32", "platform": platform.platform()}}
    s = speed(read(args.file), args.adam_sample, args.adam_block, args.repeats)
    s["file"] = args.file
    result["speed"] = s
    print_speed(console, s)
    if not args.quick:
        result["paper_experiment"] = paper_experiment(["cmu/cgspeed_12_01_walk.bvh",
                                                       "cmu86/86_01_from_amc_cgspeed_layout.bvh",
                                                       "cmu/cgspeed_01_01_playground_jumps.bvh"])
        print_paper(console, result["paper_experiment"])
        result["cross_rig"] = cross_rig("cmu/cgspeed_12_01_walk.bvh", ["cmu/daz_10_01_soccer_kick.bvh",
                                                                       "bandai1/dataset-1_walk_normal_001.bvh"])
        print_cross(console, result["cross_rig"])
    out = REPO / "benchmarks" / "results" / "retarget.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    console.print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Within-rig residuals of the paper experiment: how much of the final loss a better
solver could still remove (the *gap*) and how much the removed joints make unreachable
(the *floor*), per frame and per joint.

    PYTHONPATH=. python benchmarks/retarget_residual.py [--rounds 10] [--no-groups] [--plot docs/retarget_residual.png]

For each take (CMU 12_01 walk, 86_01, 01_01) with the paper's list B removed (31 -> 17
joints, ``benchmarks/retarget.py``):

* **shipped**: ``retarget(motion, remove=...)`` exactly as the command runs it (the same
  call as ``benchmarks/retarget.py``'s paper experiment), its ``final / copied`` figure
  and its per-frame loss (float64, from the returned motion);
* **best found**, per frame, the lowest float64 loss over much longer solves: LM restarted
  ``--rounds`` times in a row (each restart resets the damping and runs until converged,
  so ``rounds`` x the shipped iterations at least) from each of several initial guesses —
  the shipped result, the source's local rotations copied (``copy``), ``aim``, and the
  neighbouring frames' best solutions (previous and next frame), again restarted;
* **gap** = shipped − best found (what a better solver could recover), **floor** = best
  found (what no rotation of this rig reaches);
* **per joint**: the floor's share per target joint (sum over frames of its squared error
  at the best-found rotations);
* **per removed joint** (``--no-groups`` skips it): the same take with one group of the
  list kept (e.g. LowerBack back in the rig); floor(list) − floor(list without the group),
  per frame, is what removing that group costs. The costs do not add up: removals interact
  (keeping either LowerBack or the hip joints frees the same hip triangle).

Prints tables, writes ``benchmarks/results/retarget_residual.json`` and a PNG of loss per
frame (shipped vs best found, and each group's floor cost).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from retarget import PAPER_REMOVE_B, read, removal_list  # noqa: E402

FILES = ["cmu/cgspeed_12_01_walk.bvh", "cmu86/86_01_from_amc_cgspeed_layout.bvh",
         "cmu/cgspeed_01_01_playground_jumps.bvh"]
#: Groups of list B whose floor cost is measured by keeping them in the rig.
GROUPS = {"LowerBack": ["LowerBack"], "Neck": ["Neck"], "Left/RightShoulder": ["LeftShoulder", "RightShoulder"],
          "L/RHipJoint": ["LHipJoint", "RHipJoint"], "Left/RightToeBase": ["LeftToeBase", "RightToeBase"],
          "hand detail": ["LeftFingerBase", "RightFingerBase", "LeftHandIndex1", "RightHandIndex1", "LThumb",
                          "RThumb"]}
#: One compiled size for every take and rig (the XLA compile is the slow part here).
CHUNK = 1024


def _loss_args(setup):
    return setup.rig.parents, setup.mapped, setup.targets, setup.weights


def joint_errors(setup, q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``(F, J)`` weighted squared position error per target joint (target units², float64);
    zero for joints not compared. Sums over joints to ``frame_losses``."""
    from usdmotion.kinematics import fk_arrays

    _, world_p = fk_arrays(q, t, setup.rig.parents)
    d = world_p - setup.targets
    err = np.einsum("fjk,fjk->fj", d, d) * setup.weights[None, :]
    keep = np.zeros(setup.rig.n_joints, bool)
    keep[setup.mapped] = True
    return np.where(keep[None, :], err, 0.0)


class Residual:
    """Shipped solve and best-found rotations of one derived-rig problem.

    Attributes (float64; ``F`` frames, ``J`` target joints):
        setup: the :class:`usdmotion.ops.retarget.pipeline.Setup`.
        shipped_q, best_q: ``(F, J, 4)`` rotations; ``t``: ``(F, J, 3)`` translations (uncentred).
        shipped, best: ``(F,)`` per-frame loss (target units²).
        copied: total loss of the copied rotations (the paper's "before").
        winner: ``(F,)`` name of the start that found each frame's best.
    """

    def __init__(self, motion, remove, rounds: int = 10, neighbours: bool = True, chunk: int | None = CHUNK,
                 shipped=None):
        from usdmotion.ops.retarget.losses import frame_losses
        from usdmotion.ops.retarget.pipeline import _problem, prepare, retarget
        from usdmotion.ops.retarget.solve import solve

        # shipped: the retarget() call the command makes (or its result, passed in)
        shipped = shipped if shipped is not None else retarget(motion, remove=remove)
        setup = prepare(motion, remove=remove)
        self.setup = setup
        centre = setup.translations[:, setup.anchor].copy()
        t0 = setup.translations.copy()
        t0[:, setup.anchor] -= centre
        targets = setup.targets[:, setup.mapped] - centre[:, None]
        problem = _problem(setup)
        args = _loss_args(setup)
        self.compile_s, self.solve_s = 0.0, 0.0

        def run(q0):
            s = solve(problem, q0, t0, targets, chunk=chunk)
            self.compile_s += s.compile_s
            self.solve_s += s.run_s
            t = s.t.copy()
            t[:, setup.anchor] += centre
            return s.q, t

        q, self.t = shipped.motion.rotations.copy(), setup.translations  # derived rigs: root translation exact
        self.shipped_q = q
        self.shipped = frame_losses(self.t, q, *args)
        self.copied = float(frame_losses(setup.translations, setup.inits["copy"], *args).sum())
        best_q, best = q.copy(), self.shipped.copy()
        winner = np.full(motion.n_frames, "shipped", dtype=object)

        def longer(name, start):
            nonlocal best_q, best
            q = start
            for _ in range(rounds):
                q, _ = run(q)  # the solver's float32 offsets: evaluate with the rig's own (as retarget() writes them)
                loss = frame_losses(self.t, q, *args)
                better = loss < best
                best_q[better], best[better], winner[better] = q[better], loss[better], name

        longer("shipped, restarted", q)
        for name in ("copy", "aim"):
            longer(name, setup.inits[name])
        if neighbours:
            for name, shift in (("previous frame", 1), ("next frame", -1)):
                longer(name, np.roll(best_q, shift, axis=0))
        self.best_q, self.best, self.winner = best_q, best, winner

    @property
    def gap(self) -> np.ndarray:
        return self.shipped - self.best

    def per_joint_floor(self) -> dict:
        """Target joint -> its share of the total floor (sum over frames of its squared error)."""
        err = joint_errors(self.setup, self.best_q, self.t).sum(axis=0)
        names = self.setup.rig.joint_names
        return {names[j]: float(err[j]) for j in np.argsort(-err) if err[j] > 0}


def take(relative: str, rounds: int, groups: bool) -> tuple[dict, dict]:
    from usdmotion.ops.retarget.pipeline import retarget

    motion = read(relative)
    remove = removal_list(motion, PAPER_REMOVE_B)
    r = retarget(motion, remove=remove, source_path=relative)  # the shipped command, as benchmarks/retarget.py
    began = time.perf_counter()
    res = Residual(motion, remove, rounds, shipped=r)
    loss = r.report["loss"]
    row = {"file": relative, "frames": motion.n_frames, "removed": remove,
           "shipped_command": {"final_over_copied": loss["final_over_copied"],
                               "final": loss["final"]["total"], "copied": loss["copied"]["total"],
                               "iterations": r.report["iterations_run"],
                               "frames_per_second": r.report["frames_per_second_solve"]},
           "copied": res.copied, "shipped": float(res.shipped.sum()), "best_found": float(res.best.sum()),
           "gap": float(res.gap.sum()), "shipped_over_copied": float(res.shipped.sum()) / res.copied,
           "floor_over_copied": float(res.best.sum()) / res.copied,
           "gap_over_copied": float(res.gap.sum()) / res.copied,
           "frames_gap_over_1pct": int((res.gap > 0.01 * np.maximum(res.best, 1e-12)).sum()),
           "largest_frame_gap": float(res.gap.max()), "largest_frame_gap_at": int(res.gap.argmax()),
           "winners": {str(k): int(v) for k, v in zip(*np.unique(res.winner.astype(str), return_counts=True))},
           "per_joint_floor": res.per_joint_floor(), "seconds": time.perf_counter() - began,
           "compile_s": res.compile_s}
    curves = {"shipped": res.shipped, "best": res.best, "fps": motion.fps, "groups": {}}
    if groups:
        row["group_floor_cost"] = {}
        for label, names in GROUPS.items():
            kept = removal_list(motion, names)
            without = Residual(motion, [n for n in remove if n not in kept], rounds=max(2, rounds // 5),
                               neighbours=False)
            cost = res.best - without.best
            curves["groups"][label] = cost
            top = np.argsort(-cost)[:3]
            row["group_floor_cost"][label] = {"total": float(cost.sum()), "over_copied": float(cost.sum()) / res.copied,
                                              "share_of_floor": float(cost.sum() / res.best.sum()),
                                              "worst_frames": top.tolist()}
    return row, curves


def plot(curves: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(curves), 1, figsize=(11, 3.2 * len(curves)), squeeze=False)
    for ax, (name, c) in zip(axes[:, 0], curves.items()):
        seconds = np.arange(len(c["shipped"])) / c["fps"]
        ax.semilogy(seconds, np.maximum(c["shipped"], 1e-9), color="tab:red", lw=1.4, label="shipped solve")
        ax.semilogy(seconds, np.maximum(c["best"], 1e-9), color="black", lw=0.8, ls="--",
                    label="best found (floor)")
        merged: dict = {}  # groups with the same cost (keeping either frees the same joint) share a curve
        for label, cost in c["groups"].items():
            same = next((k for k, v in merged.items() if np.abs(v - cost).sum() < 0.01 * np.abs(cost).sum()), None)
            if same is None:
                merged[label] = cost
            else:
                merged[f"{same} or {label}"] = merged.pop(same)
        for (label, cost), colour in zip(merged.items(), ("tab:blue", "tab:green", "tab:orange",
                                                               "tab:purple", "tab:brown", "tab:pink")):
            if cost.sum() > 0.02 * c["best"].sum():
                ax.semilogy(seconds, np.maximum(cost, 1e-9), color=colour, lw=0.7, alpha=0.8,
                            label=f"floor cost of removing {label}")
        ax.set_title(name, fontsize=10)
        ax.set_ylabel("loss per frame (ASF units²)")
        ax.set_ylim(bottom=max(1e-5, 0.3 * float(np.percentile(c["best"], 1))))
        ax.legend(fontsize=7, loc="upper right", ncol=2)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=10, help="LM restarts per start for the best-found solve")
    parser.add_argument("--no-groups", action="store_true", help="skip the per-removed-joint floor costs")
    parser.add_argument("--files", nargs="*", default=FILES)
    parser.add_argument("--plot", type=Path, default=REPO / "docs" / "retarget_residual.png")
    args = parser.parse_args(argv)
    from rich.console import Console
    from rich.table import Table

    from usdmotion.ops.retarget.jax_runtime import device_description, enable_compilation_cache

    enable_compilation_cache()
    console = Console(width=160)
    load = os.getloadavg()[0]
    rows, curves = [], {}
    for relative in args.files:
        row, c = take(relative, args.rounds, not args.no_groups)
        rows.append(row)
        curves[f"{relative}: list B removed"] = c
    table = Table(title=f"within-rig residual, list B (31 -> 17 joints): shipped vs best found over {args.rounds} "
                        f"restarts x 5 starts; % of the copied-rotations loss (paper: 0.11 %); load {load:.1f}")
    for col in ("file", "frames", "benchmark cmd", "shipped", "best found = floor", "gap", "frames gap > 1 %",
                "LM it.", "frames/s", "floor by joint (share)"):
        table.add_column(col, justify="left" if col in ("file", "floor by joint (share)") else "right")
    for r in rows:
        floor = sum(r["per_joint_floor"].values())
        joints = ", ".join(f"{k} {v / floor:.0%}" for k, v in list(r["per_joint_floor"].items())[:3])
        table.add_row(r["file"], str(r["frames"]), f"{100 * r['shipped_command']['final_over_copied']:.3f} %",
                      f"{100 * r['shipped_over_copied']:.3f} %", f"{100 * r['floor_over_copied']:.3f} %",
                      f"{100 * r['gap_over_copied']:.2g} %", str(r["frames_gap_over_1pct"]),
                      str(r["shipped_command"]["iterations"]), f"{r['shipped_command']['frames_per_second']:,.0f}",
                      joints)
    console.print(table)
    if not args.no_groups:
        table = Table(title="what each removed group costs: floor(list B) - floor(list B with the group kept), "
                            "% of the copied loss (share of the floor)")
        table.add_column("group", justify="left")
        for r in rows:
            table.add_column(Path(r["file"]).stem, justify="right")
        for label in GROUPS:
            table.add_row(label, *(f"{100 * r['group_floor_cost'][label]['over_copied']:.3f} % "
                                   f"({r['group_floor_cost'][label]['share_of_floor']:.0%})" for r in rows))
        console.print(table)
    plot(curves, args.plot)
    result = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "device": device_description(),
                          "load_1min": load, "platform": platform.platform()}, "rounds": args.rounds, "takes": rows}
    out = REPO / "benchmarks" / "results" / "retarget_residual.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    console.print(f"wrote {out} and {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

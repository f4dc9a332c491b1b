"""Benchmark: full kinematic analysis of a 10,000-frame, 31-joint motion (issue 5, goal < 0.5 s).

The shared CMU walk (cgspeed 12_01, 31 joints + 7 end sites, 120 fps) without its T-pose
frame is tiled to 10,000 frames (the root carried forward each tile so the motion stays
continuous) and written as a BVH. Timed, each the median of ``--repeat`` runs (wall and
CPU time, the machine may be shared):

* ``read``: parse the BVH into a Motion;
* ``analyse``: the full analysis — forward kinematics, filtered velocities and
  accelerations, joint angles, bend angles, segment orientations, world and relative
  angular velocity and acceleration from quaternions, de Leva centre of mass and momentum;
* ``summary``: per-joint peaks and ranges of motion, COM figures;
* ``table``: the long per-frame table, and writing it as Parquet;
* peer ``pybvh`` 0.9.0 (read + node velocities + accelerations + local angular
  velocities, unfiltered finite differences — a subset of the above), in the same run.

Prints a table and writes ``benchmarks/results/analyze.json``.
Run: ``PYTHONPATH=. python benchmarks/analyze.py [--repeat 5] [--frames 10000]``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT.parent / "shared" / "data" / "cmu" / "cgspeed_12_01_walk.bvh"
GOAL_S = 0.5


def tiled_motion(frames: int):
    """The walk without frame 0, repeated to ``frames`` frames, root advanced per tile."""
    from usdmotion.io import read_motion
    from usdmotion.ops.analyse.measures import slice_frames

    walk = slice_frames(read_motion(SOURCE, units="asf"), 1)
    reps = -(-frames // walk.n_frames)
    step = walk.root_translation[-1] - walk.root_translation[0]
    step[1] = 0.0  # keep the height, carry the horizontal travel
    root = np.concatenate([walk.root_translation + k * step for k in range(reps)])[:frames]
    rotations = np.tile(walk.rotations, (reps, 1, 1))[:frames]
    return walk.with_frames(rotations, root)


def timed(fn, repeat: int) -> tuple[dict, object]:
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return {"median_s": statistics.median(walls), "min_s": min(walls), "cpu_median_s": statistics.median(cpus)}, result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--frames", type=int, default=10_000)
    args = parser.parse_args()
    if not SOURCE.is_file():
        print(f"missing {SOURCE}", file=sys.stderr)
        return 2
    from usdmotion.anthropometry import body_model
    from usdmotion.io import read_motion, write_motion
    from usdmotion.ops.analyse.measures import analyse
    from usdmotion.ops.analyse.report import summary, write_kinematics

    motion = tiled_motion(args.frames)
    rows: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        bvh = write_motion(motion, Path(tmp) / "walk10k.bvh")
        rows["read"], motion = timed(lambda: read_motion(bvh, units="asf"), args.repeat)
        analyse(motion, body=body_model(motion), mass=70.0)  # warm-up: imports, caches

        def full():
            return analyse(motion, body=body_model(motion), mass=70.0)

        rows["analyse"], kin = timed(full, args.repeat)
        rows["summary"], _ = timed(lambda: summary(kin), args.repeat)
        rows["table + parquet"], _ = timed(lambda: write_kinematics(kin, Path(tmp) / "k.parquet"), args.repeat)
        rows["end to end (read .. parquet)"] = {
            key: rows["read"][key] + rows["analyse"][key] + rows["summary"][key] + rows["table + parquet"][key]
            for key in ("median_s", "min_s", "cpu_median_s")}
        peer = None
        try:
            import pybvh
            from pybvh import analysis

            def pybvh_run():
                b = pybvh.read_bvh_file(str(bvh), world_up="+y")
                return (analysis.node_velocities(b), analysis.node_accelerations(b), analysis.angular_velocities(b))

            pybvh_run()
            rows["peer: pybvh read + derivatives"], _ = timed(pybvh_run, args.repeat)
            peer = pybvh.__version__
        except ImportError:
            pass
    n_joints = int((~motion.end_sites).sum())
    print(f"analysis of {motion.n_frames} frames x {n_joints} joints (+{int(motion.end_sites.sum())} end sites), "
          f"median of {args.repeat}")
    print(f"{'stage':34s} {'median s':>9s} {'min s':>8s} {'cpu s':>8s}")
    for name, row in rows.items():
        print(f"{name:34s} {row['median_s']:9.3f} {row['min_s']:8.3f} {row['cpu_median_s']:8.3f}")
    ratio = None
    if peer is not None:
        ours = rows["read"]["median_s"] + rows["analyse"]["median_s"]
        ratio = rows["peer: pybvh read + derivatives"]["median_s"] / ours
        print(f"pybvh {peer} read + velocities, accelerations, angular velocities (unfiltered): {ratio:.2f}x the time "
              f"of our read + full analysis ({ours:.3f} s)")
    met = rows["analyse"]["median_s"] < GOAL_S
    print(f"goal: analyse < {GOAL_S} s: {'met' if met else 'NOT met'} ({rows['analyse']['median_s']:.3f} s wall, "
          f"{rows['analyse']['cpu_median_s']:.3f} s CPU)")
    if rows["analyse"]["cpu_median_s"] < 0.8 * rows["analyse"]["median_s"]:
        print("note: CPU time well below wall time: the machine is busy; re-run on a quiet machine")
    out = ROOT / "benchmarks" / "results" / "analyze.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({
        "benchmark": "analyze", "frames": motion.n_frames, "joints": n_joints,
        "end_sites": int(motion.end_sites.sum()), "repeat": args.repeat, "goal_s": GOAL_S, "goal_met": met,
        "stages": rows,
        "peer": {"name": "pybvh", "version": peer, "ratio_peer_over_read_plus_analyse": ratio,
                 "work": "read + node velocities + accelerations + angular velocities"},
        "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine()},
    }, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

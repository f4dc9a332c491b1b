"""Benchmark: every editing operation on a 10,000-frame, 31-joint motion.

The motion is the CMU walk 12_01 (cgspeed, 31 joints + 7 end sites, 120 fps) tiled to
10,000 frames (each tile's root continues from where the previous one ended). Goal from
issue 7: each operation ≤ 100 ms on the project machine (2 cores). Prints a table and
writes ``benchmarks/results/edit.json``.

    PYTHONPATH=$PWD python benchmarks/edit.py [--repeat 7] [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from usdmotion.io import read_motion  # noqa: E402
from usdmotion.ops import edit as E  # noqa: E402

GOAL_MS = 100.0
FRAMES = 10_000


def tiled_walk(data: Path):
    m = read_motion(data / "cmu" / "cgspeed_12_01_walk.bvh")
    m = E.trim(m, 1)  # frame 0 is cgspeed's T-pose
    tiles = -(-FRAMES // m.n_frames)
    idx = np.arange(tiles * m.n_frames) % m.n_frames
    step = m.root_translation[-1] - m.root_translation[0]
    step[1] = 0.0
    root = m.root_translation[idx] + (np.arange(tiles * m.n_frames) // m.n_frames)[:, None] * step
    return m.with_frames(m.rotations[idx][:FRAMES], root[:FRAMES])


def cases(m, other):
    keys = [{"joint": "LeftArm", "frame": 2000, "rotate": [0, 0, 40]},
            {"joint": "LeftArm", "frame": 5000, "rotation": [10, 20, 30]},
            {"joint": "Hips", "frame": 7000, "translate": [0, -3, 0]}]
    return {
        "equalize preset denoise (3 bands)": lambda: E.equalize(m, preset="denoise"),
        "equalize 6 bands": lambda: E.equalize(m, gains=[0, 0.5, 1, 1.5, 1.5, 1.2]),
        "equalize subtree LeftUpLeg": lambda: E.equalize(m, preset="denoise", joint="LeftUpLeg", subtree=True),
        "reorient (heading + position)": lambda: E.reorient(m, heading_deg=225, position=(0, 0)),
        "displace (3 keys, falloff 60)": lambda: E.displace(m, keys, falloff=60),
        "layer (rx curve, 4 keys)": lambda: E.layer(m, "Head", "rx", [(0, 0), (3000, 20), (6000, -10), (9999, 0)]),
        "blend 0.5 s transition": lambda: E.blend(m, other, transition=60),
        "blend peaks alignment": lambda: E.blend(m, other, transition=60, align="peaks", align_joint="LeftUpLeg"),
        "blend constant 50 %": lambda: E.blend(m, other, keys=[(0, 0.5)]),
        "speed x1.5 cubic": lambda: E.speed(m, 1.5),
        "speed x1.5 linear (slerp)": lambda: E.speed(m, 1.5, interp="linear"),
        "speed keyed curve cubic": lambda: E.speed(m, keys=[(0, 1.0), (5000, 0.5), (9999, 2.0)]),
        "resample 120 -> 30 fps": lambda: E.resample(m, 30.0),
        "resample 120 -> 100 fps": lambda: E.resample(m, 100.0),
        "cycle 10,000 frames (loops)": lambda: E.cycle(m, 50, 231, transition=30, loops=67),
        "trim": lambda: E.trim(m, 100, 9900),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    args = parser.parse_args()
    m = tiled_walk(args.data)
    other = E.trim(m, 37)  # a second motion: the same walk, out of phase
    rows = []
    print(f"{m.n_frames} frames, {int((~m.end_sites).sum())} joints (+{int(m.end_sites.sum())} end sites), "
          f"{m.fps:g} fps; median of {args.repeat} runs after one warm-up; goal ≤ {GOAL_MS:g} ms")
    print(f"{'operation':36s} {'median ms':>10s} {'min ms':>8s} {'out frames':>10s}  goal")
    for name, fn in cases(m, other).items():
        out = fn()  # warm-up (imports, caches)
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fn()
            times.append((time.perf_counter() - t0) * 1000)
        median = statistics.median(times)
        rows.append({"operation": name, "median_ms": round(median, 2), "min_ms": round(min(times), 2),
                     "output_frames": out.n_frames, "goal_ms": GOAL_MS, "ratio_to_goal": round(median / GOAL_MS, 3),
                     "met": median <= GOAL_MS})
        verdict = "met" if median <= GOAL_MS else "NOT met"
        print(f"{name:36s} {median:10.1f} {min(times):8.1f} {out.n_frames:10d}  {verdict}")
    result = {"benchmark": "edit", "frames": m.n_frames, "joints": int((~m.end_sites).sum()),
              "end_sites": int(m.end_sites.sum()), "fps": m.fps, "repeat": args.repeat, "goal_ms": GOAL_MS,
              "machine": {"python": platform.python_version(), "numpy": np.__version__, "cpus": os.cpu_count(),
                          "platform": platform.platform()},
              "results": rows}
    out_path = REPO / "benchmarks" / "results" / "edit.json"
    out_path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out_path.relative_to(REPO)}; {sum(r['met'] for r in rows)}/{len(rows)} within {GOAL_MS:g} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

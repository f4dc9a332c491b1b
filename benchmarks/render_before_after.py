"""The issue-4 case (skinned CMU walk, 1280×720, no shadows, the default look) rendered by this
checkout and by an earlier commit, alternating, each render in a fresh process (so each pays what
a user's first render pays): frames/s end to end (after the body build) and the process's CPU time
a frame (all threads), per pair and as medians.

    PYTHONPATH=$PWD python benchmarks/render_before_after.py [--rev 50b2c2d] [--pairs 3] [--frames 120]

``--rev`` (default: the commit before issue 20's speed work) is unpacked with ``git archive`` into a
temporary folder and run with this checkout's Python environment. Prints a table; writes
``benchmarks/results/render_before_after.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
from _common import scratch_folder  # noqa: E402
WALK = Path(os.environ.get("USDMOTION_SHARED_DATA", ROOT.parent / "shared" / "data")) / "cmu/cgspeed_12_01_walk.bvh"

#: One render in a fresh process; prints a JSON line.
CHILD = r"""
import json, os, sys
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, render_motion
walk, frames, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
motion = read_motion(walk, units="asf")
cpu = []
def progress(current, total, message):
    if current == 1 or current == total:
        cpu.append(sum(os.times()[:2]))
load = os.getloadavg()[0]
options = RenderOptions(width=1280, height=720, start=1, end=1 + 2 * frames, fps=60.0, camera="side")
result = render_motion(motion, out, options, progress=progress)
print(json.dumps({"fps_end_to_end": result.frames / (result.seconds - result.timings["build"]),
                  "cpu_ms_per_frame": 1e3 * (cpu[-1] - cpu[0]) / (result.frames - 1),
                  "load_average": (load + os.getloadavg()[0]) / 2}))
"""


def run(tree: Path, frames: int, out: Path) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, str(WALK), str(frames), str(out)], cwd=tree,
                          env={**os.environ, "PYTHONPATH": str(tree)}, capture_output=True, text=True)
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode or not lines:
        raise SystemExit(f"{tree}: the render failed:\n{done.stderr[-2000:]}")
    return json.loads(lines[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rev", default="50b2c2d", help="the earlier commit (the peer)")
    parser.add_argument("--pairs", type=int, default=3, help="renders of each, alternating")
    parser.add_argument("--frames", type=int, default=120, help="output frames a render")
    args = parser.parse_args()
    tmp = scratch_folder("usdmotion-before-")
    before = tmp / "tree"
    before.mkdir()
    archive = subprocess.run(["git", "archive", args.rev], cwd=ROOT, capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(before)], input=archive, check=True)
    trees = {f"before ({args.rev})": before, "now": ROOT}
    runs = {name: [] for name in trees}
    for _ in range(args.pairs):
        for name, tree in trees.items():
            runs[name].append(run(tree, args.frames, tmp / "out.mp4"))
    names = list(trees)
    ratio = [now["fps_end_to_end"] / then["fps_end_to_end"] for then, now in zip(runs[names[0]], runs[names[1]])]
    median = {name: {key: float(np.median([r[key] for r in rows])) for key in rows[0]} for name, rows in runs.items()}
    print(f"issue-4 case (1280x720, no shadows, default look), {args.frames} frames, {args.pairs} pairs, "
          "fresh process each")
    print(f"{'code':>18} {'fps e2e':>8} {'CPU ms/frame':>12} {'load':>5}")
    for name, m in median.items():
        print(f"{name:>18} {m['fps_end_to_end']:>8.1f} {m['cpu_ms_per_frame']:>12.1f} {m['load_average']:>5.1f}")
    cpu_ratio = median[names[1]]["cpu_ms_per_frame"] / median[names[0]]["cpu_ms_per_frame"]
    print(f"now / before, frames/s per pair: {[round(r, 2) for r in ratio]}, median {np.median(ratio):.2f}; "
          f"CPU a frame: {cpu_ratio:.2f}")
    out = ROOT / "benchmarks" / "results" / "render_before_after.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"benchmark": "render_before_after", "rev": args.rev, "frames": args.frames,
                               "runs": runs, "medians": median, "fps_ratio_per_pair": ratio,
                               "cpu_count": os.cpu_count()}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""Reading a long USDC vs reading the same motion as BVH: time and peak memory (issue 16 item 9).

    .venv/bin/python benchmarks/usd_read.py [--frames 200000] [--repeat 3]

A 31-joint CMU file tiled to ``--frames`` frames is written as BVH and as USDC (our
writer). Each read runs in a fresh subprocess that imports the same modules (pxr and
usdmotion's readers, excluded from the time) and reports the wall time of
``read_motion`` and the process's peak RSS (``VmHWM``) next to the post-import
baseline. Goal: the USDC reads at least as fast as the BVH and with no more memory (ratios ≤ 1).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, SHARED_DATA, print_table, tiled_bvh, write_results  # noqa: E402

CHILD = r"""
import json, sys, time
from usdmotion.io import read_motion
import pxr.Usd, pxr.UsdSkel, pxr.UsdGeom  # imports out of the measurement
import usdmotion.io.bvh, usdmotion.io.usd, usdmotion.io.usd_read, usdmotion.io.usd_samples
def hwm_kib():  # this process's peak RSS (VmHWM; unlike ru_maxrss not inherited across fork+exec)
    line = next(l for l in open("/proc/self/status") if l.startswith("VmHWM:"))
    return int(line.split()[1])
base = hwm_kib()
t = time.perf_counter()
motion = read_motion(sys.argv[1])
seconds = time.perf_counter() - t
peak = hwm_kib()
print(json.dumps({"s": seconds, "peak_mib": peak / 1024, "base_mib": base / 1024, "frames": motion.n_frames,
                  "joints": motion.n_joints}))
"""


def measure(path: Path, repeat: int) -> dict:
    runs = []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True,
                             check=True, cwd=REPO)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return {"median_s": statistics.median(r["s"] for r in runs),
            "peak_mib": statistics.median(r["peak_mib"] for r in runs),
            "base_mib": statistics.median(r["base_mib"] for r in runs),
            "frames": runs[0]["frames"], "joints": runs[0]["joints"], "runs": repeat}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--source", type=Path, default=SHARED_DATA / "cmu" / "cgspeed_01_01_playground_jumps.bvh")
    args = parser.parse_args()
    if not args.source.is_file():
        sys.exit(f"benchmark input {args.source} not found (set USDMOTION_SHARED_DATA)")

    from usdmotion.io import read_motion
    from usdmotion.io.usd import write_usd

    load_before = os.getloadavg()[0]  # timings on a shared machine mean little without it
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bvh = tiled_bvh(args.source, args.frames, tmp / "long.bvh")
        usdc = write_usd(read_motion(bvh), tmp / "long.usdc")
        sizes = {"bvh_mib": bvh.stat().st_size / 2**20, "usdc_mib": usdc.stat().st_size / 2**20}
        results = {"bvh": measure(bvh, args.repeat), "usdc": measure(usdc, args.repeat)}
    ratios = {"time_usdc_over_bvh": results["usdc"]["median_s"] / results["bvh"]["median_s"],
              "memory_usdc_over_bvh": results["usdc"]["peak_mib"] / results["bvh"]["peak_mib"]}
    rows = [[k, f"{v['frames']}×{v['joints']}", f"{v['median_s']:.3f}", f"{v['peak_mib']:.0f}", f"{v['base_mib']:.0f}",
             f"{sizes[k + '_mib']:.0f}"] for k, v in results.items()]
    load = [load_before, os.getloadavg()[0]]
    print_table(f"read_motion, {args.frames} frames (median of {args.repeat} fresh processes; "
                f"1-min load average {load[0]:.1f} → {load[1]:.1f})",
                ["file", "frames×joints", "seconds", "peak MiB", "after imports MiB", "file MiB"], rows)
    print(f"USDC/BVH: time {ratios['time_usdc_over_bvh']:.2f}×, memory {ratios['memory_usdc_over_bvh']:.2f}× "
          "(goal: both ≤ 1)")
    out = write_results("usd_read", {"frames": args.frames, "source": args.source.name, "sizes": sizes,
                                     "results": results, "ratios": ratios, "load_average_1min": load})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

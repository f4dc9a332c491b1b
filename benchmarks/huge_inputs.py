"""Deep and huge inputs (issue 16, "Must show" 3): time and peak memory of the real CLI.

    python benchmarks/huge_inputs.py [--frames 1000000] [--depth 50000]

1. A ``--depth``-deep joint chain (BVH) converted to USDC: converted or refused, in how
   long and how much memory (goal ≤ 5 s and ≤ 1 GB).
2. The CMU walk (31 joints + 7 end sites, 96 channels) tiled to ``--frames`` frames,
   converted BVH → USDC: peak memory against the file's float data (frames × channels ×
   8 bytes; goal ≤ 3×), then read back (``usdmotion info``) against reading the BVH
   (goal: the USDC at least as fast).

Each step runs ``python -m usdmotion`` in its own process; peak memory is that process's
maximum resident set (``os.wait4``). Prints a table, writes
``benchmarks/results/huge_inputs.json``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import REPO, print_table, tiled_bvh, write_results  # noqa: E402

WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"


def run_cli(*args: str) -> dict:
    """``usdmotion ARGS`` in a child process: exit code, wall seconds, peak RSS (MB), last stderr line."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "usdmotion", *map(str, args)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - start
    lines = err.strip().splitlines()
    return {"exit": proc.returncode, "seconds": round(seconds, 2), "peak_mb": round(usage.ru_maxrss / 1024, 1),
            "stderr": lines[-1][:200] if lines else ""}


def chain_bvh(depth: int, path: Path) -> Path:
    with path.open("w") as fh:
        fh.write("HIERARCHY\nROOT j0\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
                 "Yrotation\n")
        for k in range(1, depth):
            fh.write(f"JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n")
        fh.write("}\n" * depth)
        fh.write("MOTION\nFrames: 2\nFrame Time: 0.04\n")
        row = " ".join(["0"] * (3 * depth + 3)) + "\n"
        fh.write(row * 2)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--depth", type=int, default=50_000)
    args = parser.parse_args()
    load_before = os.getloadavg()[0]  # timings on a shared machine mean little without it
    work = Path(tempfile.mkdtemp(prefix="usdmotion-huge-"))
    rows, payload = [], {"frames": args.frames, "depth": args.depth}
    try:
        chain = chain_bvh(args.depth, work / "chain.bvh")
        deep = run_cli("convert", chain, work / "chain.usdc")
        payload["deep_chain"] = deep
        rows.append([f"{args.depth:,}-deep chain → USDC", "converted" if deep["exit"] == 0 else f"exit {deep['exit']}",
                     deep["seconds"], deep["peak_mb"], f"{chain.stat().st_size / 1e6:.1f} MB file", ""])

        big = tiled_bvh(WALK, args.frames, work / "big.bvh")
        channels = 96  # the walk: root 6 + 30 joints × 3
        float_mb = args.frames * channels * 8 / 2**20
        payload["float_data_mb"] = round(float_mb, 1)
        payload["bvh_mb"] = round(big.stat().st_size / 2**20, 1)
        convert = run_cli("convert", big, work / "big.usdc", "--no-validate")
        payload["convert"] = convert
        rows.append([f"{args.frames:,}-frame BVH → USDC", f"exit {convert['exit']}", convert["seconds"],
                     convert["peak_mb"], f"{convert['peak_mb'] / float_mb:.2f}× float data", ""])
        read_bvh = run_cli("info", big)
        read_usd = run_cli("info", work / "big.usdc") if convert["exit"] == 0 else {"exit": None, "seconds": None,
                                                                                     "peak_mb": None}
        payload["read_bvh"], payload["read_usdc"] = read_bvh, read_usd
        rows.append(["read BVH (info)", f"exit {read_bvh['exit']}", read_bvh["seconds"], read_bvh["peak_mb"],
                     f"{read_bvh['peak_mb'] / float_mb:.2f}× float data", "peer"])
        if read_usd["seconds"]:
            rows.append(["read USDC (info)", f"exit {read_usd['exit']}", read_usd["seconds"], read_usd["peak_mb"],
                         f"{read_usd['peak_mb'] / float_mb:.2f}× float data",
                         f"{read_usd['seconds'] / read_bvh['seconds']:.2f}× BVH time"])
    finally:
        for path in sorted(work.rglob("*"), reverse=True):
            path.unlink() if path.is_file() else path.rmdir()
        work.rmdir()
    payload["load_average_1min"] = [load_before, os.getloadavg()[0]]
    print_table(f"huge inputs ({args.frames:,} frames × 96 channels = {payload['float_data_mb']} MB float64; "
                f"BVH {payload['bvh_mb']} MB; 1-min load average {load_before:.1f} → {os.getloadavg()[0]:.1f})",
                ["case", "outcome", "seconds", "peak MB", "memory", "vs"], rows)
    print(f"wrote {write_results('huge_inputs', payload)}")


if __name__ == "__main__":
    main()

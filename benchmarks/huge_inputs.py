"""Deep and huge inputs (issue 16, "Must show" 3): time and peak memory of the real CLI.

    python benchmarks/huge_inputs.py [--frames 1000000] [--depth 50000] [--repeat 1] [--unrepeated]

1. A ``--depth``-deep joint chain (BVH) converted to USDC: converted or refused, in how
   long and how much memory (goal ≤ 5 s and ≤ 1 GB).
2. The CMU walk (31 joints + 7 end sites, 96 channels) tiled to ``--frames`` frames,
   converted BVH → USDC: peak memory against the file's float data (frames × channels ×
   8 bytes; goal ≤ 3×), then read back (``usdmotion info``) against reading the BVH
   (goal: the USDC at least as fast). ``--unrepeated`` adds per-frame noise so that no frame
   repeats: usdc deduplicates a tiled take's equal samples into a small file, a real
   capture's is ~1.1 GB per million frames (results in ``huge_inputs_unrepeated.json``).

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


def unrepeated_bvh(source: Path, frames: int, out: Path, noise_deg: float = 0.05) -> Path:
    """``source`` tiled to ``frames`` rows plus Gaussian noise (``noise_deg`` degrees or file
    units, seeded) on every value, written with 4 decimals: no two frames alike, so the USDC
    cannot deduplicate samples as it does a tiled take's (a real capture's file size)."""
    import numpy as np

    from usdmotion.io.bvh import parse_bvh

    data = parse_bvh(source.read_bytes(), source)
    text = source.read_text()
    values = np.tile(data.values, (frames // len(data.values) + 1, 1))[:frames]
    values = values + np.random.default_rng(0).normal(0.0, noise_deg, values.shape)
    with out.open("w") as fh:
        fh.write(f"{text[:text.index('MOTION')]}MOTION\nFrames: {frames}\nFrame Time: {data.frame_time}\n")
        np.savetxt(fh, values, fmt="%.4f")
    return out


def alternating_reads(bvh: Path, usdc: Path | None, repeat: int) -> tuple[dict, dict]:
    """``usdmotion info`` of the BVH and the USDC, alternating ``repeat`` times: the run with
    the median seconds of each (the machine's load drifts; alternation pairs the two)."""
    runs = {"bvh": [], "usdc": []}
    for _ in range(repeat):
        runs["bvh"].append(run_cli("info", bvh))
        if usdc is not None:
            runs["usdc"].append(run_cli("info", usdc))

    def median(found: list[dict]) -> dict:
        if not found:
            return {"exit": None, "seconds": None, "peak_mb": None}
        ordered = sorted(found, key=lambda r: r["seconds"])
        return {**ordered[len(ordered) // 2], "all_seconds": [r["seconds"] for r in found]}

    return median(runs["bvh"]), median(runs["usdc"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--depth", type=int, default=50_000)
    parser.add_argument("--repeat", type=int, default=1,
                        help="read the BVH and the USDC this many times, alternating (median; 3 under load)")
    parser.add_argument("--unrepeated", action="store_true",
                        help="add per-frame noise to the tiled walk (no repeated frame: a real take's USDC size)")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]  # timings on a shared machine mean little without it
    work = Path(tempfile.mkdtemp(prefix="usdmotion-huge-"))
    rows, payload = [], {"frames": args.frames, "depth": args.depth, "repeat": args.repeat}
    try:
        chain = chain_bvh(args.depth, work / "chain.bvh")
        deep = run_cli("convert", chain, work / "chain.usdc")
        payload["deep_chain"] = deep
        rows.append([f"{args.depth:,}-deep chain → USDC", "converted" if deep["exit"] == 0 else f"exit {deep['exit']}",
                     deep["seconds"], deep["peak_mb"], f"{chain.stat().st_size / 1e6:.1f} MB file", ""])

        big = (unrepeated_bvh if args.unrepeated else tiled_bvh)(WALK, args.frames, work / "big.bvh")
        channels = 96  # the walk: root 6 + 30 joints × 3
        float_mb = args.frames * channels * 8 / 2**20
        payload["float_data_mb"] = round(float_mb, 1)
        payload["bvh_mb"] = round(big.stat().st_size / 2**20, 1)
        payload["unrepeated"] = args.unrepeated
        convert = run_cli("convert", big, work / "big.usdc", "--no-validate")
        payload["convert"] = convert
        payload["usdc_mb"] = round((work / "big.usdc").stat().st_size / 2**20, 1) if convert["exit"] == 0 else None
        rows.append([f"{args.frames:,}-frame BVH → USDC", f"exit {convert['exit']}", convert["seconds"],
                     convert["peak_mb"], f"{convert['peak_mb'] / float_mb:.2f}× float data", ""])
        read_bvh, read_usd = alternating_reads(big, work / "big.usdc" if convert["exit"] == 0 else None, args.repeat)
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
                f"BVH {payload['bvh_mb']} MB, USDC {payload['usdc_mb']} MB{', unrepeated frames' if args.unrepeated else ''}; 1-min load average {load_before:.1f} → {os.getloadavg()[0]:.1f})",
                ["case", "outcome", "seconds", "peak MB", "memory", "vs"], rows)
    print(f"wrote {write_results('huge_inputs_unrepeated' if args.unrepeated else 'huge_inputs', payload)}")


if __name__ == "__main__":
    main()

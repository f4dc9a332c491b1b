"""Parse and BVH → USDC convert time for a 5,000-frame, 31-joint CMU file, vs pybvh and bvhio.

    benchmarks/setup_peers.sh            # once: .venv-bench with pybvh and bvhio
    .venv/bin/python benchmarks/parse_convert.py [--frames 5000] [--repeat 7]

Ours: ``parse_bvh`` (text → channel arrays), ``read_bvh`` (file → Motion with quaternions),
``convert`` (read_bvh + write_usd .usdc). Peers run in their own venv, in a subprocess,
timing only their parse call (import excluded), on the same file, in the same run.
Goals (issue 2): read at least 2× faster than pybvh; convert under 3× our own read.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, SHARED_DATA, print_table, tiled_bvh, timed, write_results  # noqa: E402

PEER_SCRIPT = r"""
import json, statistics, sys, time
path, repeat = sys.argv[1], int(sys.argv[2])
import pybvh, bvhio
def run(fn):
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter(); fn(); times.append(time.perf_counter() - t)
    return {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times), "runs": repeat}
out = {"pybvh": run(lambda: pybvh.read_bvh_file(path)),
       "bvhio": run(lambda: bvhio.readAsBvh(path)),
       "versions": {"pybvh": getattr(pybvh, "__version__", "?"), "bvhio": "1.5.4"}}
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--source", type=Path, default=SHARED_DATA / "cmu" / "cgspeed_01_01_playground_jumps.bvh")
    args = parser.parse_args()
    if not args.source.is_file():
        sys.exit(f"benchmark input {args.source} not found (set USDMOTION_SHARED_DATA)")

    from usdmotion.io.bvh import parse_bvh, read_bvh
    from usdmotion.io.usd import write_usd

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bvh = tiled_bvh(args.source, args.frames, tmp / "cmu_tiled.bvh")
        raw = bvh.read_bytes()
        motion = read_bvh(bvh)
        results = {
            "parse_bvh": timed(lambda: parse_bvh(raw), args.repeat),
            "read_bvh": timed(lambda: read_bvh(bvh), args.repeat),
            "write_usdc": timed(lambda: write_usd(motion, tmp / "out.usdc"), args.repeat),
            "convert_usdc": timed(lambda: write_usd(read_bvh(bvh), tmp / "out.usdc"), args.repeat),
        }
        peer_python = REPO / ".venv-bench" / "bin" / "python"
        peers = {}
        if peer_python.exists():
            done = subprocess.run([str(peer_python), "-c", PEER_SCRIPT, str(bvh), str(args.repeat)],
                                  capture_output=True, text=True, check=True)
            peers = json.loads(done.stdout)
        else:
            print("peers not installed: run benchmarks/setup_peers.sh", file=sys.stderr)

    ours = results["read_bvh"]["median_s"]
    rows = [[name, f"{r['median_s'] * 1e3:.1f}", f"{r['min_s'] * 1e3:.1f}", ""] for name, r in results.items()]
    for name in ("pybvh", "bvhio"):
        if name in peers:
            r = peers[name]
            rows.append([f"{name}.parse", f"{r['median_s'] * 1e3:.1f}", f"{r['min_s'] * 1e3:.1f}",
                         f"ours (read_bvh) {r['median_s'] / ours:.1f}x faster"])
    convert_ratio = results["convert_usdc"]["median_s"] / ours
    print_table(f"BVH parse / convert, {args.frames} frames x {motion.n_joints} joints "
                f"({int((~motion.end_sites).sum())} + end sites), {args.source.name} tiled",
                ["step", "median ms", "min ms", "ratio"], rows)
    print(f"\nconvert (read + write .usdc) = {convert_ratio:.2f}x our read time (goal < 3x)")
    if "pybvh" in peers:
        speedup = peers["pybvh"]["median_s"] / ours
        print(f"read_bvh vs pybvh: {speedup:.1f}x faster (goal >= 2x); "
              f"parse_bvh alone vs pybvh: {peers['pybvh']['median_s'] / results['parse_bvh']['median_s']:.1f}x")
    path = write_results("parse_convert", {"frames": args.frames, "joints": motion.n_joints, "ours": results,
                                            "peers": peers, "convert_over_read": convert_ratio})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

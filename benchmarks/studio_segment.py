"""Studio segmentation editor: time to show the signal and the detector's cuts on long takes.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/studio_segment.py [--repeat 3]

What the page waits for when the editor opens (or *Run detector* is pressed) on a take already
read: ``GET /api/segment/signal`` (``Q`` and its low-passed copy, JSON) and ``POST
/api/segment/detect`` (the default kcpd run, answered at once below 30,000 frames, as a job
above), through a real server. Peer, measured in the same run: the library's
``segment()`` on the same motion (what ``usdmotion segment`` spends after reading), so
``ratio`` = studio detect / library. Each detect asks for a slightly different shortest segment
(1 s + k µs) so the server's cache of detector runs never answers. Takes: CMU 86_01 (4,579
frames, 120 Hz) and the same tiled to 20,000 and 40,000 frames. Prints a table; writes
``benchmarks/results/studio_segment.json``. Report the load average with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import SHARED_DATA, print_table, tiled_bvh, write_results  # noqa: E402

TAKE = "cmu86/86_01_from_amc_cgspeed_layout.bvh"
FRAMES = (None, 20_000, 40_000)


def call(base: str, path: str, body: dict | None = None, wait_job: bool = True) -> tuple[dict, float]:
    """The answer and the wall time (s); a ``{job}`` answer is followed to its result."""
    start = time.perf_counter()
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(base + path, data=data, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=600) as r:
        answer = json.loads(r.read())
    while wait_job and "job" in answer and "doc" not in answer:
        with urllib.request.urlopen(f"{base}/api/jobs/{answer['job']}", timeout=60) as r:
            job = json.loads(r.read())
        if job["state"] in ("done", "failed", "cancelled"):
            answer = job["result"] or {"error": job["error"]}
            break
        time.sleep(0.05)
    return answer, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from studio_support import running_studio

    from usdmotion.io import read_motion
    from usdmotion.ops.segment.detect import segment

    source = SHARED_DATA / TAKE
    if not source.is_file():
        sys.exit(f"{source} not found (set USDMOTION_SHARED_DATA)")
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        lib = Path(tmp) / "lib"
        lib.mkdir()
        for frames in FRAMES:
            name = "86_01.bvh" if frames is None else f"86_01_x{frames}.bvh"
            tiled_bvh(source, frames, lib / name) if frames else (lib / name).write_bytes(source.read_bytes())
        with running_studio([lib], out=Path(tmp) / "out") as base:
            for frames in FRAMES:
                name = "86_01.bvh" if frames is None else f"86_01_x{frames}.bvh"
                motion = read_motion(lib / name, units="asf")
                library = []
                for k in range(args.repeat):
                    start = time.perf_counter()
                    segment(motion, min_length_s=1.0 + k * 1e-6)
                    library.append(time.perf_counter() - start)
                take = f"0/{name}"
                call(base, f"/api/skeleton?take={take}")  # the take read, as when it is opened
                signal, signal_s = call(base, f"/api/segment/signal?take={take}")
                studio, cuts = [], None
                for k in range(args.repeat):
                    answer, seconds = call(base, "/api/segment/detect",
                                           {"take": take, "detector": {"min_length": 1.0 + (k + 1) * 1e-6}})
                    studio.append(seconds)
                    cuts = answer["doc"]["cuts"]
                lib_s, studio_s = statistics.median(library), statistics.median(studio)
                row = {"frames": motion.n_frames, "signal_s": signal_s, "detect_s": studio_s, "library_s": lib_s,
                       "ratio": studio_s / lib_s, "cuts": len(cuts), "as_job": motion.n_frames > 30_000}
                results.append(row)
                rows.append([motion.n_frames, f"{signal_s * 1000:.0f}", f"{studio_s * 1000:.0f}",
                             f"{lib_s * 1000:.0f}", f"{row['ratio']:.2f}", len(cuts), "job" if row["as_job"] else ""])
    load = os.getloadavg()[0]
    print_table(f"Segmentation editor on CMU 86_01 (tiled), median of {args.repeat}; load average {load:.1f}",
                ["frames", "signal ms (first)", "detect ms (studio)", "segment() ms (library)", "ratio", "cuts", ""],
                rows)
    print(f"wrote {write_results('studio_segment', {'load_average_1min': load, 'takes': results})}")


if __name__ == "__main__":
    main()

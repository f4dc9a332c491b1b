"""Studio edits panel: live-preview time of each edit on a 10,000-frame, 31-joint take in the library.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/studio_edits.py [--frames 10000] [--repeat 5]

Goal (issue 14): every edit previewed in ≤ 100 ms. A preview is what the page does on each
slider change: ``POST /api/edit/preview`` (the server runs ``usdmotion edit``'s pipeline on
the cached take) then ``GET /api/edit/positions`` (the edited joint positions, float32, like
a take's; computing them is the library's FK of every frame). Peer, measured in the same run: the library's :func:`run_pipeline` alone on the
same motion (what the CLI does: *edit ms*) and with the FK of every joint of the result
(*edit+FK ms*, what a preview would cost done the plain way), so ``ratio`` = preview /
(edit+FK). The studio's preview recomputes only the joints below a changed one
(:func:`usdmotion.studio.takes.edited_view_positions`), so an edit of one limb can come in
under 1.
The take is the bundled CMU walk cycled by the library to ``--frames`` frames (as in
``benchmarks/studio.py``). Prints a table; writes ``benchmarks/results/studio_edits.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
from _common import scratch_folder  # noqa: E402

GOAL_MS = 100.0

#: The panel's edits, as the page sends them (band 4 ≈ 2.7 Hz at 120 fps on the left leg).
OPERATIONS = {
    "equaliser (left leg)": [{"op": "equalize", "gains": [1, 1, 1, 1, 3, 1, 1], "joint": "LeftUpLeg",
                              "subtree": True}],
    "equaliser (whole body)": [{"op": "equalize", "gains": [0, 0.5, 1, 1, 1.5, 1, 1]}],
    "trim": [{"op": "trim", "start": 1000, "stop": 9000}],
    "speed curve": [{"op": "speed", "keys": [["0s", 1], ["30s", 0.5], ["60s", 1.5]]}],
    "cycle (best loop)": [{"op": "trim", "start": 0, "stop": 600}, {"op": "cycle", "stop": "auto", "loops": 16}],
    "displace": [{"op": "displace", "keys": [{"joint": "LeftArm", "frame": "20s", "rotate": [0, 0, 30]}],
                  "falloff": "1s"}],
    "blend with a second take": [{"op": "blend", "with": "0/lib/second.bvh", "at": "40s", "transition": "1s"}],
}


def post(base: str, path: str, body: dict) -> tuple[dict, float]:
    request = urllib.request.Request(base + path, data=json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=300) as r:
        answer = json.loads(r.read())
        server = float(r.headers.get("server-timing", "app;dur=nan").split("dur=")[1])
    return answer, server


def get(base: str, path: str) -> int:
    with urllib.request.urlopen(base + path, timeout=300) as r:
        return len(r.read())


def preview_ms(base: str, take: str, ops: list) -> dict:
    t = time.perf_counter()
    answer, server = post(base, "/api/edit/preview", {"take": take, "ops": ops})
    size = get(base, f"/api/edit/positions?key={answer['key']}")
    return {"ms": 1e3 * (time.perf_counter() - t), "server_ms": server, "bytes": size, "frames": answer["frames"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    from studio import make_take
    from studio_support import serving
    from usdmotion.io import read_motion, write_motion
    from usdmotion.ops.edit.pipeline import run_pipeline, validate_pipeline
    from usdmotion.studio.app import create_app
    from usdmotion.studio.takes import view_positions

    folder = scratch_folder("studio_edits_")
    path = make_take(folder, args.frames)
    motion = read_motion(path, units="asf")
    second = path.parent / "second.bvh"
    write_motion(motion.sliced(3000, 6000), second)
    other = read_motion(second, units="asf")
    take = f"0/lib/{path.name}"
    rows, results = [], {}
    with serving(create_app([folder], {"units": "asf"}, folder / "out")) as base:
        get(base, f"/api/skeleton?take={take}")  # the take read once, as when the user opened it
        get(base, "/api/skeleton?take=0/lib/second.bvh")
        for name, ops in OPERATIONS.items():
            ops = [{**op, "with": str(second)} if op["op"] == "blend" else op for op in ops]
            page_ops = [{**op, "with": "0/lib/second.bvh"} if op["op"] == "blend" else op for op in ops]
            library, with_fk = [], []
            for _ in range(args.repeat):
                t = time.perf_counter()
                edited = run_pipeline(motion, validate_pipeline(ops), folder, read=lambda p: other)
                library.append(1e3 * (time.perf_counter() - t))
                view_positions(edited)
                with_fk.append(1e3 * (time.perf_counter() - t))
            previews = [preview_ms(base, take, page_ops) for _ in range(args.repeat)]  # recomputed every time
            ms = statistics.median(p["ms"] for p in previews)
            lib_ms, fk_ms = statistics.median(library), statistics.median(with_fk)
            results[name] = {"preview_ms": ms, "server_ms": statistics.median(p["server_ms"] for p in previews),
                             "library_ms": lib_ms, "library_fk_ms": fk_ms, "ratio": ms / fk_ms,
                             "frames_out": previews[0]["frames"], "positions_bytes": previews[0]["bytes"],
                             "goal_met": ms <= GOAL_MS}
            rows.append([name, f"{ms:.0f}", f"{results[name]['server_ms']:.0f}", f"{lib_ms:.0f}", f"{fk_ms:.0f}",
                         f"{ms / fk_ms:.2f}", previews[0]["frames"], "yes" if ms <= GOAL_MS else "no"])
    load = os.getloadavg()[0]
    header = ["edit", "preview ms", "server ms", "edit ms", "edit+FK ms", "ratio", "frames out",
              f"≤ {GOAL_MS:.0f} ms"]
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    print(f"Studio edit previews on a {args.frames}-frame, {motion.n_joints}-joint take "
          f"(median of {args.repeat}; load average {load:.1f})")
    for row in [header, ["-" * w for w in widths], *rows]:
        print("  ".join(str(x).ljust(w) for x, w in zip(row, widths)))
    out = ROOT / "benchmarks" / "results" / "studio_edits.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"frames": args.frames, "joints": motion.n_joints, "repeat": args.repeat,
                               "load_average_1min": load, "goal_ms": GOAL_MS, "results": results}, indent=2) + "\n")
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()

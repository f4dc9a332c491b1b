"""GLB vs USDC of the bundled walk (issue 12, must-show 4): file size and write time, same run.

    .venv/bin/python benchmarks/glb.py [--repeat 5] [--source FILE --units asf]

Rows (GLB and USDC timed alternately ``--repeat`` times after a warm-up, median seconds;
bytes of the file):

* ``write``: the motion already read and the body already built, only the writer runs —
  ``write_gltf(.glb, body=...)`` vs ``write_usd(.usdc, decorate=body_decorator(body))``;
* ``convert``: what ``usdmotion convert walk.bvh out.{glb,usdc} --mesh --no-validate``
  does in-process: read the BVH, build the body, write;
* ``no mesh``: skeleton and animation only; ``read``: ``read_motion`` of those files
  (after the "write, no mesh" row wrote them); ``--fps 30``: GLB resampled to 30 fps.

Goal (issue 12): the GLB with ``--mesh`` no larger and no slower to write than the USDC;
the table shows the GLB/USDC ratios.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, print_table, timed, write_results  # noqa: E402

WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"


def interleaved(ours, peer, repeat: int) -> tuple[dict, dict]:
    """Time ``ours`` and ``peer`` alternately (one warm-up each), so that load from other
    processes on a shared machine falls on both alike."""
    import statistics
    import time

    ours(), peer()
    runs = ([], [])
    for _ in range(repeat):
        for fn, times in zip((ours, peer), runs):
            start = time.perf_counter()
            fn()
            times.append(time.perf_counter() - start)
    return tuple({"median_s": statistics.median(t), "min_s": min(t), "max_s": max(t), "runs": repeat} for t in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--source", type=Path, default=WALK)
    parser.add_argument("--units", default="asf")
    args = parser.parse_args()

    from usdmotion.io import read_motion
    from usdmotion.io.gltf import write_gltf
    from usdmotion.io.usd import write_usd
    from usdmotion.io.usd_mesh import body_decorator
    from usdmotion.ops.edit.timewarp import resample
    from usdmotion.skin import build_body

    motion = read_motion(args.source, units=args.units)
    body = build_body(motion)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        glb, usdc = tmp / "walk.glb", tmp / "walk.usdc"

        def convert(path):
            read = read_motion(args.source, units=args.units)
            built = build_body(read)
            if path.suffix == ".glb":
                write_gltf(read, path, body=built)
            else:
                write_usd(read, path, decorate=body_decorator(built))

        cases = {
            "write --mesh": (lambda: write_gltf(motion, glb, body=body),
                             lambda: write_usd(motion, usdc, decorate=body_decorator(body))),
            "convert --mesh": (lambda: convert(glb), lambda: convert(usdc)),
            "write, no mesh": (lambda: write_gltf(motion, glb), lambda: write_usd(motion, usdc)),
            "read (no mesh)": (lambda: read_motion(glb), lambda: read_motion(usdc)),
        }
        results, rows = {}, []
        for name, (ours, peer) in cases.items():
            t_glb, t_usdc = interleaved(ours, peer, args.repeat)
            size_glb, size_usdc = glb.stat().st_size, usdc.stat().st_size
            results[name] = {"glb": {**t_glb, "bytes": size_glb}, "usdc": {**t_usdc, "bytes": size_usdc},
                             "size_ratio": size_glb / size_usdc, "time_ratio": t_glb["median_s"] / t_usdc["median_s"]}
            rows.append([name, f"{size_glb:,}", f"{size_usdc:,}", f"{size_glb / size_usdc:.3f}",
                         f"{t_glb['median_s'] * 1e3:.1f}", f"{t_usdc['median_s'] * 1e3:.1f}",
                         f"{t_glb['median_s'] / t_usdc['median_s']:.3f}"])
        at30 = resample(motion, 30.0)
        t30 = timed(lambda: write_gltf(at30, glb, body=body), args.repeat)
        results["write --mesh --fps 30 (glb only)"] = {"glb": {**t30, "bytes": glb.stat().st_size}}
        rows.append(["write --mesh --fps 30", f"{glb.stat().st_size:,}", "", "", f"{t30['median_s'] * 1e3:.1f}", "",
                     ""])
    title = (f"GLB vs USDC: {args.source.name}, {motion.n_frames} frames at {motion.fps:g} fps, {motion.n_joints} "
             f"joints, body {len(body.vertices):,} vertices / {len(body.faces):,} triangles; median of {args.repeat}")
    print_table(title, ["case", "GLB bytes", "USDC bytes", "size GLB/USDC", "GLB ms", "USDC ms", "time GLB/USDC"],
                rows)
    path = write_results("glb", {"source": str(args.source), "frames": motion.n_frames, "joints": motion.n_joints,
                                 "vertices": len(body.vertices), "triangles": len(body.faces), "results": results})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

"""Rendering throughput: frames/s end to end (skin → render → encode to H.264), with the
skinning, rendering and encoding times separated, for a skinned CMU walk at 1280×720 and
640×480, with and without shadows; through EGL on whatever renderer it finds (Mesa llvmpipe on
the CPU, or a GPU's driver; the table names it).

    PYTHONPATH=$PWD python benchmarks/render.py [--frames 120] [--long 10000]

Goal (issue 4): ≥ 25 frames/s end to end at 1280×720, skinned body, no shadows, 2 cores.
Issue 20 adds, at 1280×720 in the same run: angles + plot panel + compare ghost ≥ 20 frames/s,
a 2×2 layout ≥ 10 frames/s, and anti-aliasing on/off (ratios to the plain case, the peer):
the default FXAA pass drawn on the tiles near drawn pixels ("plain"), the same pass over the whole
picture (the default before, same output: "FXAA full-screen"), none ("no AA", ``--no-fxaa``) and
MSAA 4 (``--msaa 4``; Mesa's llvmpipe offers 4 samples only, so ``--msaa 2`` is the same); and the
body with all its triangles ("full-detail body", ``RenderOptions(lod=False)``: the peer of the level of
detail, usdmotion.render.lod).
``--long N`` also renders N frames at 320×240 to check that memory stays flat (RSS
sampled every 500 frames). ``--ab N`` renders only the anti-aliasing rows (FXAA tiles,
FXAA full-screen, no AA), alternating, N times each, and prints each one's median (for a
machine loaded by other jobs); JSON to ``benchmarks/results/render_ab.json``.
Prints a table; writes ``benchmarks/results/render.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from _common import scratch_folder  # noqa: E402
WALK = Path(os.environ.get("USDMOTION_SHARED_DATA", ROOT.parent / "shared" / "data")) / "cmu/cgspeed_12_01_walk.bvh"


def rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def gl_renderer() -> str:
    from usdmotion.render.gl import offscreen_renderer

    r = offscreen_renderer(16, 16)
    r._platform.make_current()
    from OpenGL import GL

    name = GL.glGetString(GL.GL_RENDERER).decode()
    r.delete()
    return name


#: Feedback-video cases at 1280x720 (issue 20): RenderOptions extras and whether to compare
#: ("fxaa_tiles": usdmotion.render.gl.FXAA_TILES for that case).
FEATURES = {
    "plain": ({}, False),  # the default look: FXAA pass on the tiles near drawn pixels, widened grid lines
    "FXAA full-screen": ({"fxaa_tiles": False}, False),
    "no AA": ({"fxaa": False}, False),
    "full-detail body": ({"lod": False}, False),  # all the body's triangles (usdmotion.render.lod off)
    "msaa4": ({"msaa": 4}, False),
    "angles+panel+ghost": ({"angles": ("knee_left", "elbow_right"), "panel": "angle:knee_left,speed:RightHand"},
                           True),
    "2x2": ({"layout": "2x2", "camera": "side,front,top,follow"}, False),
    "2x2+msaa4": ({"layout": "2x2", "camera": "side,front,top,follow", "msaa": 4}, False),
}


def run_case(motion, width, height, shadows, frames, tmp: Path, case: str = "", extra: dict | None = None,
             other=None) -> dict:
    from usdmotion.render import RenderOptions, gl, render_motion

    settings = dict(width=width, height=height, start=1, end=1 + frames * 2, fps=60.0, shadows=shadows,
                    camera="side")
    settings.update(extra or {})
    gl.FXAA_TILES = settings.pop("fxaa_tiles", True)
    options = RenderOptions(**settings)
    cpu = []  # process CPU seconds (all threads: llvmpipe's, the encoder's) after the first and the last frame
    first = []  # when the first frame was done

    def progress(current, total, message):  # a usdmotion.progress.Progress
        if current == 1:
            first.append(time.perf_counter())
        if current == 1 or current == total:
            cpu.append(sum(os.times()[:2]))

    started = time.perf_counter()
    try:
        result = render_motion(motion, tmp / f"bench_{width}x{height}_{int(shadows)}_{case}.mp4", options, other,
                               progress=progress)
    finally:
        gl.FXAA_TILES = True
    t = result.timings
    n = result.frames
    loop = result.seconds - t["build"]
    return {"case": case or "plain", "size": f"{width}x{height}", "shadows": shadows, "frames": n,
            "fps_end_to_end": n / loop, "fps_incl_body_build": result.fps,
            "body_build_s": t["build"], "skin_ms": 1e3 * t["skin"] / n, "render_ms": 1e3 * t["render"] / n,
            "encode_ms": 1e3 * t["encode"] / n, "overlay_ms": 1e3 * t.get("overlay", 0.0) / n, "loop_s": loop,
            "first_frame_s": first[0] - started - t["build"],
            "cpu_ms_per_frame": 1e3 * (cpu[-1] - cpu[0]) / max(n - 1, 1), "load_average": os.getloadavg()[0]}


def run_long(motion, count: int, tmp: Path) -> dict:
    from usdmotion.render import RenderOptions, render_motion

    long = motion.with_frames(np.resize(motion.rotations[1:], (count,) + motion.rotations.shape[1:]),
                              np.resize(motion.root_translation[1:], (count, 3)), fps=60.0)
    samples = []

    def progress(current, total, message):  # a usdmotion.progress.Progress
        if current % 500 == 0:
            samples.append((current, round(rss_mib(), 1)))

    started = time.perf_counter()
    render_motion(long, tmp / "long.mp4", RenderOptions(width=320, height=240, fps=60.0, camera="follow"),
                  progress=progress)
    return {"frames": count, "seconds": time.perf_counter() - started, "rss_mib_every_500_frames": samples,
            "rss_growth_mib_after_first_1000": samples[-1][1] - samples[1][1] if len(samples) > 2 else None}


AA_ROWS = ("plain", "FXAA full-screen", "no AA")


def run_ab(motion, repeats: int, frames: int, tmp: Path) -> None:
    """The anti-aliasing rows at 1280x720, alternating, ``repeats`` times each; medians."""
    runs = {name: [] for name in AA_ROWS}
    for _ in range(repeats):
        for name in AA_ROWS:
            case = run_case(motion, 1280, 720, False, frames, tmp, name, FEATURES[name][0])
            runs[name].append({"fps_end_to_end": case["fps_end_to_end"], "cpu_ms_per_frame": case["cpu_ms_per_frame"],
                               "load_average": os.getloadavg()[0]})
    median = {name: {key: float(np.median([r[key] for r in rows])) for key in rows[0]} for name, rows in runs.items()}
    print(f"anti-aliasing rows at 1280x720, {frames} frames, alternating, {repeats} times each (medians)")
    print(f"{'case':>18} {'fps e2e':>8} {'/ no AA':>8} {'CPU ms/frame':>12} {'/ no AA':>8} {'load':>5}")
    base = median["no AA"]
    for name, m in median.items():
        print(f"{name:>18} {m['fps_end_to_end']:>8.1f} {m['fps_end_to_end'] / base['fps_end_to_end']:>8.2f} "
              f"{m['cpu_ms_per_frame']:>12.1f} {m['cpu_ms_per_frame'] / base['cpu_ms_per_frame']:>8.2f} "
              f"{m['load_average']:>5.1f}")
    out = ROOT / "benchmarks" / "results" / "render_ab.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"benchmark": "render --ab", "input": WALK.name, "frames": frames, "runs": runs,
                               "medians": median, "cpu_count": os.cpu_count()}, indent=2))
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=120, help="output frames per case")
    parser.add_argument("--long", type=int, default=0, help="also render this many frames to check memory")
    parser.add_argument("--ab", type=int, default=0, help="only the anti-aliasing rows, alternating, N times each")
    args = parser.parse_args()
    from usdmotion.io import read_motion

    motion = read_motion(WALK, units="asf")
    tmp = scratch_folder("usdmotion-bench-")
    if args.ab:
        return run_ab(motion, args.ab, args.frames, tmp)
    load_at_start = os.getloadavg()[0]
    renderer = gl_renderer()
    cases = [run_case(motion, w, h, s, args.frames, tmp) for (w, h) in ((1280, 720), (640, 480)) for s in (False, True)]
    # a second take for the ghost: the same walk, 0.3 m aside
    other = motion.with_frames(motion.rotations, motion.root_translation + np.array([0.3 / motion.meters_per_unit,
                                                                                      0.0, 0.0]))
    features = [run_case(motion, 1280, 720, False, args.frames, tmp, name, extra, other if compare else None)
                for name, (extra, compare) in FEATURES.items()]
    by_case = {c["case"]: c["fps_end_to_end"] for c in features}
    on_cpu = any(word in renderer.lower() for word in ("llvmpipe", "softpipe", "swrast"))
    result = {
        "benchmark": "render", "input": WALK.name, "device": f"EGL {renderer} ({'CPU' if on_cpu else 'GPU'})",
        "on_gpu": not on_cpu, "cpu_count": os.cpu_count(),
        "python": platform.python_version(), "cases": cases,
        "goal": "≥ 25 frames/s end to end at 1280x720, skinned body, no shadows",
        "goal_met": bool(cases[0]["fps_end_to_end"] >= 25.0),
        "features_1280x720": features,
        "feature_goals": {"plain (anti-aliased) ≥ 25 fps": features[0]["fps_end_to_end"] >= 25.0,
                          "angles+panel+ghost ≥ 20 fps": by_case["angles+panel+ghost"] >= 20.0,
                          "2x2 ≥ 10 fps": by_case["2x2"] >= 10.0},
        "load_average_at_start": load_at_start, "load_average_at_end": os.getloadavg(),
    }
    if args.long:
        result["long"] = run_long(motion, args.long, tmp)
    result["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"device: {result['device']}; cores: {os.cpu_count()}, "
          f"1-minute load average {load_at_start:.2f} at the start, {os.getloadavg()[0]:.2f} at the end")
    print(f"{'size':>9} {'shadows':>7} {'frames':>6} {'fps e2e':>8} {'skin ms':>8} {'render ms':>9} "
          f"{'encode ms':>9} {'body s':>6} {'1st frame s':>11} {'CPU ms/frame':>12} {'load':>5}")
    for c in cases:
        print(f"{c['size']:>9} {str(c['shadows']):>7} {c['frames']:>6} {c['fps_end_to_end']:>8.1f} "
              f"{c['skin_ms']:>8.2f} {c['render_ms']:>9.1f} {c['encode_ms']:>9.1f} {c['body_build_s']:>6.2f} "
              f"{c['first_frame_s']:>11.2f} {c['cpu_ms_per_frame']:>12.1f} {c['load_average']:>5.1f}")
    print("(skinning, overlays and encoding run on helper threads in parallel with rendering; fps e2e = frames / "
          "the time after the body build, which is listed separately; the first row is the process's first render: "
          "its first frame also compiles the shaders and loads what the later rows find loaded)")
    print(f"goal ≥ 25 fps at 1280x720 no shadows: {'met' if result['goal_met'] else 'NOT met'} "
          f"({cases[0]['fps_end_to_end']:.1f} fps)")
    plain = features[0]["fps_end_to_end"]
    print(f"\nfeedback-video cases at 1280x720, same run (ratio to 'plain' = the peer):")
    print(f"{'case':>20} {'fps e2e':>8} {'ratio':>6} {'render ms':>9} {'encode ms':>9} {'1st frame s':>11} "
          f"{'CPU ms/frame':>12} {'load':>5}")
    for c in features:
        print(f"{c['case']:>20} {c['fps_end_to_end']:>8.1f} {c['fps_end_to_end'] / plain:>6.2f} "
              f"{c['render_ms']:>9.1f} {c['encode_ms']:>9.1f} {c['first_frame_s']:>11.2f} "
              f"{c['cpu_ms_per_frame']:>12.1f} {c['load_average']:>5.1f}")
    print("(CPU ms/frame: the process's CPU time, all threads, per frame after the first: what the frame costs "
          "the machine, much less sensitive than frames/s to other jobs' load)")
    for goal, met in result["feature_goals"].items():
        print(f"goal {goal}: {'met' if met else 'NOT met'}")
    if args.long:
        print(f"long render: {result['long']['frames']} frames in {result['long']['seconds']:.0f} s, RSS every 500 "
              f"frames: {[s[1] for s in result['long']['rss_mib_every_500_frames']]} MiB")
    out = ROOT / "benchmarks" / "results" / "render.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""Where a 1280×720 frame of ``benchmarks/render.py``'s first row goes: the stages of one frame,
run one after the other (each waits for the renderer: ``glFinish``), for each anti-aliasing
mode, in one run. Stages: skinning (per frame, done 32 at a time), vertex upload and camera,
drawing the scene, anti-aliasing + read-back (FXAA pass or plain copy, ``glReadPixels``,
row flip), the frame/time overlay and composition, and H.264 encoding (here on the same
thread; ``render`` runs it on a writer thread beside the rendering).

    PYTHONPATH=$PWD python benchmarks/render_stages.py [--frames 120]

For each stage: wall ms and the process's CPU ms (all threads, llvmpipe's included) per frame
after the first (which compiles the shaders);
the CPU figure moves much less than the wall one when other jobs load the machine. Modes:
"FXAA tiles" (the default), "FXAA full-screen" (the same pass over the whole picture, the
default before), "no AA" (``--no-fxaa``), "MSAA 4". Prints a table; writes
``benchmarks/results/render_stages.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from _common import scratch_folder  # noqa: E402
WALK = Path(os.environ.get("USDMOTION_SHARED_DATA", ROOT.parent / "shared" / "data")) / "cmu/cgspeed_12_01_walk.bvh"
STAGES = ("skin", "upload", "draw", "AA + read-back", "overlay", "encode")
MODES = {"FXAA tiles": {}, "FXAA full-screen": {"fxaa_tiles": False}, "no AA": {"fxaa": False},
         "MSAA 4": {"msaa": 4}}


def clocks() -> tuple[float, float]:
    return time.perf_counter(), sum(os.times()[:2])


def profile(motion, frames: int, extra: dict, out: Path) -> dict:
    """Per-stage ``{stage: (wall ms, CPU ms)}`` per frame, rendering ``frames`` frames."""
    import pyrender
    from OpenGL import GL

    from usdmotion.render import RenderOptions, gl, plan_render
    from usdmotion.render.output import VideoWriter
    from usdmotion.render.views import Views

    extra = dict(extra)
    gl.FXAA_TILES = extra.pop("fxaa_tiles", True)
    options = RenderOptions(start=1, end=1 + 2 * frames, fps=60.0, camera="side", **extra)
    plan = plan_render(motion, options)
    views = Views(motion, None, plan, options)
    writer = VideoWriter(out, options.width, options.height, plan.fps, options.quality)
    spent = {stage: np.zeros(2) for stage in STAGES}
    inner, scene, actor = views.renderer._renderer, views.scenes[0], views.actors[0]
    read = inner._read_main_framebuffer
    flags = pyrender.RenderFlags.OFFSCREEN
    try:
        for i in range(len(plan.frames)):
            marks = [clocks()]
            if i % 32 == 0:
                chunk = actor.skin(np.arange(i, min(i + 32, len(plan.frames))))
            marks.append(clocks())
            views.renderer._platform.make_current()
            actor.update(i % 32, chunk)
            views.shadow.update(chunk.joints[i % 32])
            scene.set_pose(scene.camera_node, plan.camera.poses[i])
            inner._update_context(scene, flags)
            marks.append(clocks())
            inner._read_main_framebuffer = lambda *args: None  # draw only
            inner._forward_pass(scene, flags)
            inner._read_main_framebuffer = read
            GL.glFinish()
            marks.append(clocks())
            image = np.ascontiguousarray(read(scene, flags)[0])
            marks.append(clocks())
            views._overlay([image], i)
            image = views._compose([image], i)
            marks.append(clocks())
            writer.write(image, i)
            marks.append(clocks())
            for stage, a, b in zip(STAGES, marks, marks[1:]):
                spent[stage] += np.subtract(b, a) if i else 0.0  # the first frame compiles the shaders
        writer.commit()
    finally:
        views.close()
        gl.FXAA_TILES = True
    n = len(plan.frames) - 1
    return {stage: [1e3 * t / n for t in spent[stage]] for stage in STAGES}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=120, help="frames per mode")
    args = parser.parse_args()
    from usdmotion.io import read_motion

    motion = read_motion(WALK, units="asf")
    tmp = scratch_folder("usdmotion-stages-")
    load = [os.getloadavg()[0]]
    result = {}
    for mode, extra in MODES.items():
        result[mode] = profile(motion, args.frames, extra, tmp / f"{len(result)}.mp4")
        load.append(os.getloadavg()[0])
    print(f"1280x720, {args.frames} frames a mode, one stage after the other; 1-minute load average "
          f"{min(load):.1f}-{max(load):.1f}; ms per frame, wall / CPU (all threads)")
    print(f"{'stage':>16} " + " ".join(f"{mode:>17}" for mode in MODES))
    for stage in STAGES + ("total",):
        cells = [np.sum([result[m][s] for s in STAGES], axis=0) if stage == "total" else result[m][stage]
                 for m in MODES]
        print(f"{stage:>16} " + " ".join(f"{w:>8.1f} /{c:>7.1f}" for w, c in cells))
    out = ROOT / "benchmarks" / "results" / "render_stages.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"benchmark": "render_stages", "input": WALK.name, "size": "1280x720",
                               "frames": args.frames, "load_average": load, "cpu_count": os.cpu_count(),
                               "ms_per_frame_wall_cpu": result}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

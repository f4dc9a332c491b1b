"""Regenerate the stills and the short video of docs/render.md (run from the repository root):

    .venv/bin/python docs/render/make_media.py

CMU playground jump (angles, plot panel, stroboscope) and a Bandai Namco run compared with
the same run time-warped (sampled at a known smooth warp, moved 1 m aside and turned 30°),
aligned back with --align time.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
DATA = Path(os.environ.get("USDMOTION_SHARED_DATA", ROOT.parent / "shared" / "data"))
OUT = ROOT / "docs" / "render"


def warped(motion, amount: float = 0.12):
    """``motion`` played through the known warp τ(u) = u + amount·sin(2πu), moved and turned."""
    from usdmotion.ops.edit.timewarp import sample_motion
    from usdmotion.rotations import quat_mul

    n = motion.n_frames
    u = np.linspace(0.0, 1.0, n)
    rotations, root, joint_t = sample_motion(motion, (n - 1) * (u + amount * np.sin(2 * np.pi * u)))
    angle = np.radians(30.0)
    turn = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    rotations = rotations.copy()
    rotations[:, 0] = quat_mul(np.array([np.cos(angle / 2), 0, np.sin(angle / 2), 0]), rotations[:, 0])
    root = root @ turn.T + np.array([1.0 / motion.meters_per_unit, 0, 0])
    return motion.with_frames(rotations, root, joint_t)


def main() -> None:
    import dataclasses
    import shutil
    import tempfile

    from usdmotion.io import read_motion
    from usdmotion.render import RenderOptions, render_motion
    from usdmotion.render.strobe import render_strobe

    jump = read_motion(DATA / "cmu/cgspeed_01_01_playground_jumps.bvh", units="asf")
    base = RenderOptions(width=960, height=540, body_resolution=96, labels=("CMU 01_01 playground jumps", ""))
    tmp = Path(tempfile.mkdtemp())
    still = dataclasses.replace(base, start=430, end=431, angles=("knee_left", "hip_left", "trunk"),
                                panel="angle:knee_left,speed:Hips", msaa=4)
    # the panel spans the whole jump; the still shows its take-off frame
    render_motion(jump, tmp / "jump/####.png", dataclasses.replace(still, start=380, end=560, fps=10.0))
    frames = sorted((tmp / "jump").glob("*.png"))
    shutil.copy(frames[5], OUT / "jump_angles_panel.png")
    render_strobe(jump, OUT / "jump_strobe.png", dataclasses.replace(base, start=380, end=560, msaa=4), count=7)
    layout = dataclasses.replace(base, start=470, end=471, layout="2x2", camera="side,front,top,follow", msaa=4)
    render_motion(jump, tmp / "layout/####.png", layout)
    shutil.copy(tmp / "layout/0000.png", OUT / "jump_2x2.png")

    run = read_motion(DATA / "bandai1/dataset-1_run_normal_001.bvh")
    other = warped(run)
    compare = dataclasses.replace(base, width=640, height=360, speed=0.25, align="time", angles=("knee_left",),
                                  labels=("Bandai run", "same run, time-warped"), msaa=4)
    render_motion(run, OUT / "bandai_run_vs_warped.mp4", compare, other)
    render_motion(run, tmp / "cmp/####.png", dataclasses.replace(compare, start=6, end=7), other)
    shutil.copy(tmp / "cmp/0000.png", OUT / "bandai_run_vs_warped.png")
    render_motion(run, tmp / "start/####.png", dataclasses.replace(compare, start=6, end=7, align="start"), other)
    shutil.copy(tmp / "start/0000.png", OUT / "bandai_run_vs_warped_unaligned.png")
    shutil.rmtree(tmp)
    print("wrote", ", ".join(sorted(p.name for p in OUT.iterdir())))


if __name__ == "__main__":
    main()

"""``render --compare OTHER --align …``: a take against its own time-warped, moved copy
(the warp is known here) coincides after ``--align time`` — joints within 2 px at every
frame, projected here — and the ghost, drawn just inside its own surface, disappears
behind the main body; with ``--align start`` it does not."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, plan_render, render_motion
from tests.test_render import is_ghost, project, read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"
OPTIONS = RenderOptions(width=320, height=240, start=100, end=400, fps=4.0, overlay=False, body_resolution=40,
                        align="time")


@pytest.fixture(scope="module")
def takes():
    from tests.conftest import shared_path

    walk = read_motion(shared_path(WALK), units="asf")
    n = walk.n_frames
    u = np.linspace(0.0, 1.0, n)
    source = np.rint((n - 1) * (u + 0.08 * np.sin(2 * np.pi * u))).astype(int)  # known monotone warp
    assert np.all(np.diff(source) >= 0)
    # the copy: frame k shows the walk's frame source[k], 1.5 units along x and 0.4 along z,
    # turned 40° about the vertical (Y-up file)
    angle = np.radians(40.0)
    turn = np.array([[np.cos(angle), 0.0, np.sin(angle)], [0.0, 1.0, 0.0], [-np.sin(angle), 0.0, np.cos(angle)]])
    half = np.array([np.cos(angle / 2), 0.0, np.sin(angle / 2), 0.0])  # wxyz about +Y
    from usdmotion.rotations import quat_mul

    rotations = walk.rotations[source].copy()
    rotations[:, 0] = quat_mul(half, rotations[:, 0])
    root = walk.root_translation[source] @ turn.T + np.array([150.0, 0.0, 40.0])
    return walk, walk.with_frames(rotations, root), source


def world(motion, frames):
    from usdmotion.kinematics import fk_arrays, local_translations

    return fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)[1] \
        * motion.meters_per_unit


def test_align_time_maps_the_warped_copy_back_within_2_px(takes):
    walk, copy, source = takes
    plan = plan_render(walk, OPTIONS, copy)
    assert len(plan.frames) == 10
    # the clocks: the copy's frame shows the same walk frame (±1 where the warp skipped it)
    assert np.abs(source[plan.other_frames] - plan.frames).max() <= 1
    exact = np.isin(plan.frames, source)
    assert (source[plan.other_frames][exact] == plan.frames[exact]).all()
    # the bodies: main joints vs the copy's joints moved by the alignment, both projected here
    main = world(walk, plan.frames)
    other = world(copy, plan.other_frames) @ plan.alignment.turn.T + plan.alignment.shift
    for i in range(len(plan.frames)):
        a = project(main[i], plan.camera.poses[i], plan.camera.yfov, 320, 240)
        b = project(other[i], plan.camera.poses[i], plan.camera.yfov, 320, 240)
        assert np.linalg.norm(a - b, axis=1).max() <= 2.0, f"frame {plan.frames[i]}"
    # without alignment the copy is elsewhere
    start = plan_render(walk, dataclasses.replace(OPTIONS, align="start"), copy)
    assert np.abs(world(copy, start.other_frames) - main).max() > 0.5


def test_ghost_hides_behind_the_aligned_body_only(takes, tmp_path):
    walk, copy, _ = takes
    options = dataclasses.replace(OPTIONS, end=160)
    counts = {}
    for mode in ("time", "start", "frame:100,0"):
        out = tmp_path / mode.replace(":", "_") / "####.png"
        render_motion(walk, out, dataclasses.replace(options, align=mode), copy)
        counts[mode] = [int(is_ghost(read_image(p)).sum()) for p in sorted(out.parent.iterdir())]
    assert max(counts["time"]) < 40, counts  # a few edge pixels where a frame is one off
    assert min(counts["start"]) > 400, counts
    # frame:100,0 pairs the right poses' places (same spot) but the wrong times: the ghost shows
    assert max(counts["frame:100,0"]) > 100, counts


@pytest.mark.parametrize("extra, message", [
    (["--align", "time"], "--align needs --compare"),
    (["--compare", "SELF", "--align", "frame:1"], "--align 'frame:1': use start, time"),
    (["--compare", "SELF", "--align", "frame:9999,0"], "frame 9999 is outside the main take"),
])
def test_bad_align_fails_in_one_line_without_output(shared_file, tmp_path, capsys, extra, message):
    path = str(shared_file(WALK))
    extra = [path if e == "SELF" else e for e in extra]
    code = main(["render", path, str(tmp_path / "out.mp4"), "--units", "asf", "--size", "160x120", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_rigs_without_hips_compare_in_place_and_refuse_dtw(shared_file, tmp_path, capsys):
    simple = str(shared_file("edge_cases/bvhanim_test_simple.bvh"))
    base = ["render", simple, str(tmp_path / "out.mp4"), "--compare", simple, "--size", "160x120", "--style", "stick"]
    assert main(base) == 0
    assert (tmp_path / "out.mp4").is_file()
    (tmp_path / "out.mp4").unlink()
    assert main(base + ["--align", "time"]) == 2
    err = capsys.readouterr().err
    assert "--align time compares the limbs' bone angles: cannot find the joints" in err
    assert len(err.strip().splitlines()) == 1 and not any(tmp_path.iterdir())

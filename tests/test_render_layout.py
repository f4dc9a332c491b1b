"""``render --layout 2x2 --camera side,front,top,follow``: in every tile the body covers the
joints of the same source frame projected (here) through that tile's camera, and not
those of a frame half a second away; bad layouts fail in one line."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, plan_render, render_motion
from tests.test_render import inner_joints, is_body, joints_render_space, project, read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"
CAMERAS = ("side", "front", "top", "follow")


def test_four_views_show_the_same_frame(shared_file, tmp_path):
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=480, height=360, start=100, end=401, fps=2.0, overlay=False, body_resolution=40,
                            layout="2x2", camera=",".join(CAMERAS), grid=False)
    render_motion(walk, tmp_path / "f/####.png", options)
    plan = plan_render(walk, options)
    assert plan.panel == (240, 180) and len(plan.cameras) == 4
    joints = joints_render_space(walk, plan.frames)[:, inner_joints(walk)]
    files = sorted((tmp_path / "f").iterdir())
    assert len(files) == len(plan.frames) == 6
    for i, path in enumerate(files):
        image = read_image(path)
        for v, camera in enumerate(plan.cameras):
            tile = is_body(image[180 * (v // 2):180 * (v // 2 + 1), 240 * (v % 2):240 * (v % 2 + 1)])

            def covered(k):
                px = project(joints[k], camera.poses[i], camera.yfov, 240, 180)
                inside = (px[:, 0] >= 0) & (px[:, 0] < 240) & (px[:, 1] >= 0) & (px[:, 1] < 180)
                return tile[px[inside, 1].astype(int), px[inside, 0].astype(int)].sum() / len(px)

            assert covered(i) > 0.85, (CAMERAS[v], i)
            if CAMERAS[v] in ("side", "top"):  # views across the walk: another frame is elsewhere
                assert covered((i + 1) % len(files)) < 0.5, (CAMERAS[v], i)


@pytest.mark.parametrize("extra, message", [
    (["--layout", "2x2", "--camera", "side,front"], "--layout 2x2 needs 4 cameras"),
    (["--layout", "9x9", "--camera", "side"], "--layout '9x9': use ROWSxCOLUMNS"),
    (["--camera", "side,front"], "several cameras need --layout"),
    (["--layout", "1x2", "--camera", "side,sideways"], "unknown camera preset 'sideways'"),
])
def test_bad_layouts_fail_in_one_line_without_output(shared_file, tmp_path, capsys, extra, message):
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "out.mp4"), "--units", "asf", "--size", "160x120",
                 "--frames", "100:110", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())

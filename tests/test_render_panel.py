"""``render --panel``: the plot strip's cursor, read from the pixels, moves linearly with
time from the left end of the plot to the right end; bad series fail in one line."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, plan_render, render_motion
from usdmotion.render.panel import CURSOR
from tests.test_render import read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"


def test_cursor_moves_linearly_with_time(shared_file, tmp_path):
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=320, height=240, start=100, end=221, fps=6.0, overlay=False, body_resolution=40,
                            panel="angle:knee_left,speed:RightHand")
    render_motion(walk, tmp_path / "f/####.png", options)
    plan = plan_render(walk, options)
    assert plan.panel == (320, 240 - 68)  # the 3-D view above a 68-row strip
    columns = []
    for path in sorted((tmp_path / "f").iterdir()):
        image = read_image(path).astype(int)
        assert image.shape == (240, 320, 3)
        strip = image[plan.panel[1]:]
        cursor = (np.abs(strip - np.array(CURSOR)).max(axis=-1) < 30)
        cols = np.flatnonzero(cursor.sum(axis=0) > 0.5 * strip.shape[0])  # a full-height vertical line
        assert 1 <= len(cols) <= 3, cols
        columns.append(cols.mean())
    columns = np.array(columns)
    assert len(columns) == len(plan.times) == 7
    fit = np.polyfit(plan.times, columns, 1)
    assert np.abs(np.polyval(fit, plan.times) - columns).max() < 0.75  # linear in time
    assert columns[0] < 0.25 * 320 and columns[-1] > 0.9 * 320  # from the plot's left end to its right end


@pytest.mark.parametrize("extra, message", [
    (["--panel", "force:RightHand"], "use angle:NAME or speed:JOINT"),
    (["--panel", "speed:RightPaw"], "no joint named 'RightPaw'"),
    (["--panel", "angle:knee_middle"], "unknown angle"),
])
def test_bad_panel_fails_in_one_line_without_output(shared_file, tmp_path, capsys, extra, message):
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "out.mp4"), "--units", "asf", "--size", "160x120",
                 "--frames", "100:110", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())

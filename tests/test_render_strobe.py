"""Stroboscope stills, read from the pixels: N separated bodies, each around its own
projected root (projection written in tests/test_render.py), fading from light to full
colour; bad values fail in one line before anything is written."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions
from usdmotion.render.strobe import fixed_camera, render_strobe
from usdmotion.skin import body_size
from tests.test_render import project, read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"


def test_strobe_still_shows_n_separated_bodies_where_their_roots_project(shared_file, tmp_path):
    from scipy import ndimage

    from usdmotion.render import render_joints

    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=480, height=240, start=20, end=521, overlay=False, body_resolution=40, grid=False)
    frames = render_strobe(walk, tmp_path / "strobe.png", options, count=5)
    assert list(frames) == [20, 145, 270, 395, 520]
    image = read_image(tmp_path / "strobe.png").astype(int)
    background = image[2, 2]
    figure = np.abs(image - background).max(axis=-1) > 10
    labels, count = ndimage.label(figure)
    sizes = ndimage.sum(figure, labels, np.arange(1, count + 1))
    bodies = np.flatnonzero(sizes > 150) + 1
    assert len(bodies) == 5, sorted(sizes)[-8:]
    camera = fixed_camera(walk, frames, options, 0.08 * body_size(walk) * walk.meters_per_unit)
    roots = project(render_joints(walk, frames)[:, 0], camera.poses[-1], camera.yfov, 480, 240)
    hit = [labels[int(y), int(x)] for x, y in roots]
    assert sorted(hit) == sorted(bodies.tolist())  # one body around each root, each root in its own body
    # fading: the first pose is the lightest, the last the most saturated
    saturation = [np.mean(image[labels == k][:, 0] - image[labels == k][:, 2]) for k in hit]
    assert all(np.diff(saturation) > 0), saturation


@pytest.mark.parametrize("extra, message", [
    (["--strobe", "1"], "--strobe must be 2..200 poses"),
    (["--strobe-every", "0s"], "must be positive"),
    (["--strobe-every", "soon"], "--strobe-every 'soon': use seconds"),
    (["--strobe", "4", "--strobe-every", "0.1s"], "give one of --strobe N or --strobe-every"),
    (["--strobe-every", "0.0001s"], "poses over frames"),
])
def test_bad_strobe_values_fail_in_one_line_without_output(shared_file, tmp_path, capsys, extra, message):
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "still.png"), "--units", "asf", "--size",
                 "160x120", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_strobe_to_a_video_name_is_refused(shared_file, tmp_path, capsys):
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "still.mp4"), "--units", "asf", "--strobe", "3"])
    assert code == 2 and "a stroboscope still is one image" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("extra, named", [
    (["--trace", "LeftFoot"], "--trace"),
    (["--style", "stick", "--angle", "knee_left"], "--angle, --style"),
])
def test_strobe_refuses_options_it_does_not_draw(shared_file, tmp_path, capsys, extra, named):
    """A stroboscope still draws bodies only: options it would drop are refused, never ignored."""
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "still.png"), "--units", "asf", "--size",
                 "160x120", "--strobe", "3", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and len(err.strip().splitlines()) == 1
    assert f"leave out {named}" in err
    assert not any(tmp_path.iterdir())

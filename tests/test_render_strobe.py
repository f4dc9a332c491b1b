"""Stroboscope stills, read from the pixels: N separated bodies, each around its own
projected root (projection written in tests/test_render.py), fading from light to full
colour; bad values fail in one line before anything is written."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, framing_pad
from usdmotion.render.strobe import fixed_camera, render_strobe
from usdmotion.skin import body_size
from tests.test_render import is_body, joints_render_space, project, read_image

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
    (["--panel", "speed:Hips"], "--panel"),
    (["--style", "stick", "--angle", "knee_left"], "--angle"),
    (["--layout", "1x2", "--camera", "side,front"], "--layout"),
])
def test_strobe_refuses_options_it_does_not_draw(shared_file, tmp_path, capsys, extra, named):
    """A stroboscope still draws poses and traces only: options it would drop are refused, never ignored."""
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "still.png"), "--units", "asf", "--size",
                 "160x120", "--strobe", "3", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and len(err.strip().splitlines()) == 1
    assert f"leave out {named}" in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("extra, message", [
    (["--trace", "LeftPinky"], "--trace: no joint named 'LeftPinky'"),
    (["--focus", "LeftFoot,LeftToe"], "--focus: no joint named 'LeftToe'"),
    (["--focus", "LeftFoot", "--camera", "CAM"], "--focus aims a preset"),
])
def test_strobe_bad_trace_or_focus_fails_in_one_line(shared_file, tmp_path, capsys, extra, message):
    (tmp_path / "cam.usda").write_text("#usda 1.0\n")
    extra = [str(tmp_path / "cam.usda") if e == "CAM" else e for e in extra]
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "still.png"), "--units", "asf", "--size",
                 "160x120", "--strobe", "3", *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and len(err.strip().splitlines()) == 1, err
    assert message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.usda"]


def _distances(mask: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(P, M)`` pixel distances from points ``(P, 2)`` (column, row) to the ``M`` pixel centres of ``mask``."""
    rows, cols = np.nonzero(mask)
    return np.hypot(points[:, None, 0] - (cols + 0.5), points[:, None, 1] - (rows + 0.5))


def _near(mask: np.ndarray, points: np.ndarray, radius: float) -> np.ndarray:
    """For each point ``(P, 2)``: is a ``mask`` pixel within ``radius`` px?"""
    return (_distances(mask, points) <= radius).any(axis=1)


def _off_path(mask: np.ndarray, path: np.ndarray, radius: float) -> int:
    """How many ``mask`` pixels lie farther than ``radius`` px from the polyline through ``path (P, 2)``."""
    dense = np.concatenate([np.linspace(a, b, 8, endpoint=False) for a, b in zip(path[:-1], path[1:])] + [path[-1:]])
    return int((_distances(mask, dense).min(axis=0) > radius).sum())


def test_strobe_traces_are_drawn_over_the_poses_on_the_projected_paths(shared_file, tmp_path):
    """--trace LeftFoot (green) and com (magenta) in the still: their pixels lie on the paths projected
    by the test's own pinhole model through every source frame from the first pose to the last, and
    the foot's path shows at the poses' own frames too, where the body surrounds the joint (drawn over)."""
    from usdmotion.skin import build_body, centre_of_mass

    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=480, height=240, start=20, end=521, overlay=False, body_resolution=40, grid=False,
                            traces=("LeftFoot", "com"))
    frames = render_strobe(walk, tmp_path / "strobe.png", options, count=5)
    image = read_image(tmp_path / "strobe.png").astype(int)
    green = (image[..., 1] - image[..., 0] > 50) & (image[..., 1] - image[..., 2] > 30)
    magenta = (image[..., 0] - image[..., 1] > 50) & (image[..., 2] - image[..., 1] > 50)
    camera = fixed_camera(walk, frames, options, framing_pad(walk, options))
    span = np.arange(frames[0], frames[-1] + 1)
    foot = project(joints_render_space(walk, span)[:, walk.joint_index("LeftFoot")], camera.poses[-1],
                   camera.yfov, 480, 240)
    com = project(centre_of_mass(walk, build_body(walk, resolution=40), span) * walk.meters_per_unit,
                  camera.poses[-1], camera.yfov, 480, 240)
    assert green.sum() > 200 and magenta.sum() > 200
    assert _off_path(green, foot, 3.0) == 0 and _off_path(magenta, com, 3.0) == 0
    assert _near(green, foot, 2.5).mean() > 0.97 and _near(magenta, com, 2.5).mean() > 0.97
    assert _near(green, foot[frames - frames[0]], 2.5).all()  # at the poses: over the body, not hidden in it
    body = is_body(image) & ~green & ~magenta
    assert body[np.rint(foot[frames - frames[0]][:, 1]).astype(int) - 4,
                np.rint(foot[frames - frames[0]][:, 0]).astype(int)].any()  # ... which is there


def test_strobe_stick_style_draws_the_joints_of_every_pose_without_a_body(shared_file, tmp_path):
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=480, height=240, start=20, end=521, overlay=False, grid=False, style="stick")
    frames = render_strobe(walk, tmp_path / "stick.png", options, count=4)
    image = read_image(tmp_path / "stick.png").astype(int)
    joint_red = (image[..., 0] - image[..., 1] > 60) & (image[..., 0] - image[..., 2] > 60)
    camera = fixed_camera(walk, frames, options, framing_pad(walk, options))
    limbs = [walk.joint_index(side + part) for side in ("Left", "Right")
             for part in ("UpLeg", "Leg", "Foot", "Arm", "ForeArm", "Hand")] + [walk.joint_index("Head")]
    last = project(joints_render_space(walk, frames[-1:])[0, limbs], camera.poses[-1], camera.yfov, 480, 240)
    assert _near(joint_red, last, 2.0).all()  # the latest pose, in full colour
    orange = is_body(image) & (image[..., 1] - image[..., 2] > 20)  # a body's green is above its blue, a joint's not
    assert not orange.any()


def test_focus_frames_the_named_joints_close_up(shared_file):
    """--focus LeftFoot,LeftToeBase: the still's fixed camera and the video's follow camera frame those
    joints' paths (projected by the test), several times larger than the whole body's view; the head is out."""
    import dataclasses

    from usdmotion.render import plan_render

    walk = read_motion(shared_file(WALK), units="asf")
    feet = [walk.joint_index("LeftFoot"), walk.joint_index("LeftToeBase")]
    frames = np.arange(105, 192, 12)
    options = RenderOptions(width=640, height=320, start=105, end=192, focus=("LeftFoot", "LeftToeBase"))
    still = fixed_camera(walk, frames, options, framing_pad(walk, options))
    joints = joints_render_space(walk, frames)
    points = project(joints[:, feet], still.poses[-1], still.yfov, 640, 320).reshape(-1, 2)
    whole = dataclasses.replace(options, focus=())
    wide = fixed_camera(walk, frames, whole, framing_pad(walk, whole))
    wide_points = project(joints[:, feet], wide.poses[-1], wide.yfov, 640, 320).reshape(-1, 2)
    assert (points > 0).all() and (points < (640, 320)).all()
    zoom = np.ptp(points, axis=0) / np.ptp(wide_points, axis=0)
    assert (zoom > 4).all(), zoom  # the feet drawn several times larger than in the whole body's view
    body = project(joints.reshape(-1, 3), still.poses[-1], still.yfov, 640, 320)
    assert body[:, 1].min() < 0  # the head is out of the picture
    plan = plan_render(walk, options)
    video = np.stack([project(joints_render_space(walk, plan.frames[i:i + 1])[0, feet], plan.camera.poses[i],
                              plan.camera.yfov, 640, 320) for i in range(len(plan.frames))])
    assert (video > 0).all() and (video < (640, 320)).all()
    assert plan.camera.poses[0][1, 3] < joints[..., 1].max()  # a camera near the floor, below the head


def test_strobe_cli_draws_traces_styles_and_focus(shared_file, tmp_path, capsys):
    """The options the still used to refuse now run from the command line: one PNG, the traced pixels in it."""
    out = tmp_path / "still.png"
    code = main(["render", str(shared_file(WALK)), str(out), "--units", "asf", "--size", "200x120", "--strobe", "3",
                 "--trace", "LeftFoot", "--trace", "com", "--style", "both", "--focus", "LeftFoot,LeftToeBase"])
    assert code == 0 and "3 poses" in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir()] == ["still.png"]
    image = read_image(out).astype(int)
    assert ((image[..., 1] - image[..., 0] > 50) & (image[..., 1] - image[..., 2] > 30)).sum() > 20  # the foot's path

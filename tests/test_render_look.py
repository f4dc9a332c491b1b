"""The look, read from the pixels: a soft contact shadow darkens the floor under the body
(projected here) and fades out away from it; the grid lines stay unbroken."""

from __future__ import annotations

import dataclasses

import numpy as np

from usdmotion.io import read_motion
from usdmotion.render import RenderOptions, plan_render, render_motion
from tests.test_render import joints_render_space, project, read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"


def test_contact_shadow_darkens_the_floor_under_the_body_only(shared_file, tmp_path):
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=320, height=240, start=150, end=151, overlay=False, body_resolution=40, grid=False)
    images = {}
    for on in (True, False):
        render_motion(walk, tmp_path / f"{on}/####.png", dataclasses.replace(options, contact_shadow=on))
        images[on] = read_image(tmp_path / f"{on}/0000.png").astype(int)
    plan = plan_render(walk, options)
    joints = joints_render_space(walk, plan.frames)[0]
    centre = joints.mean(axis=0)
    size = float(np.ptp(joints, axis=0).max())
    floor = lambda dx, dz: np.array([centre[0] + dx, plan.ground, centre[2] + dz])  # noqa: E731
    darker = images[False].sum(-1) - images[True].sum(-1)
    # just in front of and behind the feet (the body does not cover those floor points)
    for dz in (0.15 * size, -0.15 * size):
        x, y = project(floor(0.0, dz), plan.camera.poses[0], plan.camera.yfov, 320, 240).astype(int)
        assert darker[y, x] > 30, (dz, darker[y, x])
    x, y = project(floor(0.0, 0.8 * size), plan.camera.poses[0], plan.camera.yfov, 320, 240).astype(int)
    assert abs(darker[y, x]) <= 3  # far from the body: untouched
    assert (darker >= -3).all()  # the shadow only darkens

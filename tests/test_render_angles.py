"""``render --angle``, read from the pixels: the value equals ``usdmotion analyze``'s bend
to 0.5°, the label shows exactly the sidecar's text, the arc is drawn around the joint
projected here (tests/test_render.py's projection, not the renderer's)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from usdmotion.io import read_motion
from usdmotion.ops.analyse import analyse
from usdmotion.render import RenderOptions, plan_render, render_motion
from tests.test_render import joints_render_space, project, read_image

WALK = "cmu/cgspeed_12_01_walk.bvh"
OPTIONS = RenderOptions(width=320, height=240, start=100, end=161, fps=4.0, overlay=False, body_resolution=40,
                        angles=("knee_left", "elbow_right", "LeftArm,LeftForeArm,LeftHand"))


@pytest.fixture(scope="module")
def walk():
    from tests.conftest import shared_path

    return read_motion(shared_path(WALK), units="asf")


@pytest.fixture(scope="module")
def rendered(walk, tmp_path_factory):
    folder = tmp_path_factory.mktemp("angles")
    render_motion(walk, folder / "with/####.png", OPTIONS)
    render_motion(walk, folder / "without/####.png", dataclasses.replace(OPTIONS, angles=()))
    sidecar = json.loads((folder / "with/angles.json").read_text())
    return folder, sidecar


def test_sidecar_values_equal_analyze_bend(walk, rendered):
    _, sidecar = rendered
    kin = analyse(walk)
    knee, elbow, left_elbow = (walk.joint_index(n) for n in ("LeftLeg", "RightForeArm", "LeftForeArm"))
    frames = [f["source_frame"] for f in sidecar["frames"]]
    assert len(frames) == len(plan_render(walk, OPTIONS).frames) == 3
    for f in sidecar["frames"]:
        a = f["angles"]
        assert abs(a["knee_left"]["value"] - kin.bend[f["source_frame"], knee]) < 0.5
        assert abs(a["elbow_right"]["value"] - kin.bend[f["source_frame"], elbow]) < 0.5
        # three joints by name (the left elbow): analyze's bend there
        assert abs(a["LeftArm,LeftForeArm,LeftHand"]["value"] - kin.bend[f["source_frame"], left_elbow]) < 0.5
    assert np.ptp([f["angles"]["knee_left"]["value"] for f in sidecar["frames"]]) > 5  # it changes over time


def test_label_pixels_show_exactly_the_sidecar_text(rendered):
    from PIL import Image, ImageDraw

    from usdmotion.render.angles import COLORS
    from usdmotion.render.overlay import _font

    folder, sidecar = rendered
    for i, frame in enumerate(sidecar["frames"]):
        shown = read_image(folder / f"with/{i:04d}.png").astype(int)
        plain = read_image(folder / f"without/{i:04d}.png")
        for k, name in enumerate(sidecar["angles"]):
            entry = frame["angles"][name]
            x0, y0, x1, y1 = entry["label_box"]

            def redraw(text):
                canvas = Image.fromarray(plain.copy())
                pen = ImageDraw.Draw(canvas)
                pen.rectangle([x0 - 3, y0 - 2, x1 + 3, y1 + 2], fill=(20, 20, 20))
                pen.text(tuple(entry["label_at"]), text, fill=COLORS[k], font=_font(max(14, 240 // 30)))
                return np.asarray(canvas).astype(int)[y0:y1, x0:x1]

            assert np.abs(redraw(entry["text"]) - shown[y0:y1, x0:x1]).max() <= 2, name
            wrong = entry["text"].replace(f"{entry['value']:.1f}", f"{entry['value'] + 1.0:.1f}")
            assert np.abs(redraw(wrong) - shown[y0:y1, x0:x1]).max() > 100  # another value would show


def test_arc_is_drawn_around_the_projected_joint(walk, rendered):
    folder, sidecar = rendered
    plan = plan_render(walk, OPTIONS)
    joints = joints_render_space(walk, plan.frames)
    knee = walk.joint_index("LeftLeg")
    ys, xs = np.mgrid[0:240, 0:320]
    for i, frame in enumerate(sidecar["frames"]):
        x, y = project(joints[i, knee], plan.camera.poses[i], plan.camera.yfov, 320, 240)
        entry = frame["angles"]["knee_left"]
        assert np.hypot(entry["vertex_px"][0] - x, entry["vertex_px"][1] - y) < 1.0
        shown = read_image(folder / f"with/{i:04d}.png").astype(int)
        yellow = (shown[..., 0] > 200) & (shown[..., 1] > 170) & (shown[..., 2] < 90)  # COLORS[0]
        r = np.hypot(xs - x, ys - y)
        ring = yellow & (np.abs(r - entry["arc_radius_px"]) < 2.5)
        assert ring.sum() >= 4, f"frame {i}: no arc around the knee"
        label = np.zeros_like(yellow)
        x0, y0, x1, y1 = entry["label_box"]
        label[y0 - 3:y1 + 3, x0 - 4:x1 + 4] = True
        assert not (yellow & ~label & (r > 1.6 * entry["arc_radius_px"])).any()  # nothing yellow far away

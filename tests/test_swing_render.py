"""The synthesised giant swing (ALGORITHMS.md §2) renders: the body covers the projected
bar-to-feet line at every frame, and the feet go round the bar as the angle table says."""

from __future__ import annotations

import numpy as np
from test_render import is_body, project, read_image

from usdmotion.kinematics import joint_positions
from usdmotion.render import RenderOptions, plan_render, render_motion
from usdmotion.synthesis import example_path, load_synthesis


def test_giant_swing_renders_the_swing(tmp_path):
    swing = load_synthesis(example_path("giant_swing"))
    options = RenderOptions(width=320, height=320, camera="front", fps=30.0, overlay=False, grid=False,
                            body_resolution=48)
    out = tmp_path / "swing" / "####.png"
    result = render_motion(swing, out, options)
    plan = plan_render(swing, options)
    assert result.frames == len(plan.frames) == 23
    positions = joint_positions(swing)[plan.frames]
    render_space = positions * swing.meters_per_unit  # Y-up file: render space = metres
    bar, feet = swing.joint_index(swing.joint_names[0]), swing.joint_index("Legs_End")
    angles = []
    for k, path in enumerate(sorted((tmp_path / "swing").iterdir())):
        image = read_image(path)
        body = is_body(image)
        # sample the bar→feet polyline (through the hips and shoulders) and project it
        chain = render_space[k]
        samples = np.concatenate([chain[j] + np.linspace(0.15, 0.85, 5)[:, None] * (chain[j + 1] - chain[j])
                                  for j in range(len(chain) - 1)])
        uv = project(samples, plan.camera.poses[k], plan.camera.yfov, 320, 320).round().astype(int)
        assert body[uv[:, 1], uv[:, 0]].mean() >= 0.9, f"frame {k}: body not where the swing projects"
        rows, cols = np.nonzero(body)
        centre = project(render_space[k, bar], plan.camera.poses[k], plan.camera.yfov, 320, 320)
        angles.append(np.arctan2(-(rows.mean() - centre[1]), cols.mean() - centre[0]))  # image angle of the body
    turn = np.degrees(np.unwrap(angles))
    # the body's centroid turns about the bar like the feet (table: arms from 16.6° to 363.3°)
    feet_turn = np.degrees(np.unwrap(np.arctan2(positions[:, feet, 1] - positions[:, bar, 1],
                                                positions[:, feet, 0] - positions[:, bar, 0])))
    assert abs(abs(turn[-1] - turn[0]) - abs(feet_turn[-1] - feet_turn[0])) < 25
    assert abs(turn[-1] - turn[0]) > 300

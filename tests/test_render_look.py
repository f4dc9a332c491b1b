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
    options = RenderOptions(width=320, height=240, start=150, end=151, overlay=False, body_resolution=40, grid=False,
                            fxaa=False)  # the shadow alone (FXAA also re-blends the body's outline over it)
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


def _grey(image: np.ndarray) -> np.ndarray:
    return image.astype(float) @ [0.299, 0.587, 0.114]


def _grid_line_columns(walk, options, grey):
    """For each grid line parallel to the picture within the grid (from 1.9 m before to 1.9 m
    behind the body), the pixel columns along it: ``[(line, [column greys around its projection])]``."""
    plan = plan_render(walk, options)
    pose, root = plan.camera.poses[0], joints_render_space(walk, plan.frames)[0][0]
    view = -pose[:3, 2]  # the camera looks along -z of its pose
    axis, along = (2, 0) if abs(view[2]) > abs(view[0]) else (0, 2)  # lines of constant z run across a side view
    lines = []
    for k in np.arange(np.ceil(root[axis] - 1.9), np.floor(root[axis] + 1.9) + 1):
        points = np.zeros((400, 3))
        points[:, axis], points[:, 1] = k, plan.ground
        points[:, along] = root[along] + np.linspace(-1.9, 1.9, 400)
        keep = np.abs(points[:, along] - root[along]) > 0.6  # not where the stick figure stands
        pixels = np.rint(project(points[keep], pose, plan.camera.yfov, options.width, options.height)).astype(int)
        inside = ((pixels >= 10) & (pixels < [options.width - 10, options.height - 10])).all(axis=1)
        columns = {x: grey[y - 5:y + 6, x] for x, y in pixels[inside]}
        if columns:  # (a line in front of the body may lie below the picture)
            lines.append((k, list(columns.values())))
    return lines


def test_grid_lines_are_anti_aliased_and_unbroken_near_and_far(shared_file, tmp_path):
    """Every pixel column along every grid line parallel to the picture, near the body and
    behind it, shows the line (no gaps where a thin far line used to vanish); with the default
    FXAA pass the stair steps of each tilted line are blended (greys between the floor's and a
    fully covered line pixel's), and without it they are hard (those two greys only)."""
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=640, height=360, start=150, end=151, overlay=False, body_resolution=40,
                            contact_shadow=False, style="stick")
    blended = {}
    for fxaa in (True, False):
        render_motion(walk, tmp_path / f"{fxaa}/####.png", dataclasses.replace(options, fxaa=fxaa))
        lines = _grid_line_columns(walk, options, _grey(read_image(tmp_path / f"{fxaa}/0000.png")))
        assert len(lines) >= 2 and all(len(columns) > 50 for _, columns in lines), [len(c) for _, c in lines]
        full = min(column.min() for _, columns in lines for column in columns)  # a wholly covered line pixel
        blended[fxaa] = []
        for k, columns in lines:
            for column in columns:
                assert column.max() - column.min() > 30, (fxaa, k, column.round())  # the line is there
            between = [((column > full + 3) & (column < column.max() - 3)).any() for column in columns]
            blended[fxaa].append(np.mean(between))
    assert min(blended[True]) > 0.05 and max(blended[False]) < 0.01, blended  # (measured: 0.10-0.12 and 0)


def test_fxaa_blends_edges_and_leaves_the_rest(shared_file, tmp_path):
    """The FXAA pass changes pixels only on strong edges of the picture (the body's outline),
    and it changes many of them, towards the colours on either side."""
    walk = read_motion(shared_file(WALK), units="asf")
    options = RenderOptions(width=320, height=240, start=150, end=151, overlay=False, body_resolution=40,
                            grid=False, contact_shadow=False)
    images = {}
    for on in (True, False):
        render_motion(walk, tmp_path / f"{on}/####.png", dataclasses.replace(options, fxaa=on))
        images[on] = read_image(tmp_path / f"{on}/0000.png").astype(int)
    grey = _grey(images[False])
    edge = np.zeros(grey.shape, bool)
    for dy, dx in ((0, 1), (1, 0)):
        step = np.abs(grey[dy:, dx:] - grey[:grey.shape[0] - dy, :grey.shape[1] - dx]) > 8
        edge[dy:, dx:] |= step
        edge[:grey.shape[0] - dy, :grey.shape[1] - dx] |= step
    near_edge = edge | np.roll(edge, 1, 0) | np.roll(edge, -1, 0) | np.roll(edge, 1, 1) | np.roll(edge, -1, 1)
    changed = np.abs(images[True] - images[False]).max(axis=-1) > 2
    assert changed.sum() > 150, changed.sum()
    assert not (changed & ~near_edge).any(), np.argwhere(changed & ~near_edge)[:5]
    # a changed pixel lies between its neighbours' extremes (a blend, not a new colour)
    lo = np.minimum.reduce([np.roll(grey, s, a) for s in (-1, 0, 1) for a in (0, 1)])
    hi = np.maximum.reduce([np.roll(grey, s, a) for s in (-1, 0, 1) for a in (0, 1)])
    after = _grey(images[True])[changed]
    assert ((after >= lo[changed] - 2) & (after <= hi[changed] + 2)).mean() > 0.97


def test_fxaa_on_tiles_equals_the_full_screen_pass(shared_file, tmp_path, monkeypatch):
    """The default FXAA pass runs only on the tiles near drawn pixels; over a walk with its
    ghost, grid, traces and contact shadow every frame is the full-screen pass's, bit for bit,
    and both differ from the picture without anti-aliasing; so is a two-view frame with shadows."""
    from usdmotion.render import gl

    walk = read_motion(shared_file(WALK), units="asf")
    other = walk.with_frames(walk.rotations, walk.root_translation + np.array([0.4 / walk.meters_per_unit, 0, 0]))
    options = RenderOptions(width=320, height=240, start=100, end=160, fps=10.0, body_resolution=40,
                            traces=("LeftHand",), camera="follow")
    frames = {}
    for name, tiles, fxaa in (("tiles", True, True), ("full", False, True), ("none", True, False)):
        monkeypatch.setattr(gl, "FXAA_TILES", tiles)
        render_motion(walk, tmp_path / f"{name}/####.png", dataclasses.replace(options, fxaa=fxaa), other)
        frames[name] = np.stack([read_image(path) for path in sorted((tmp_path / name).glob("*.png"))])
    assert len(frames["tiles"]) == 5  # 59 frames at 120 fps, shown at 10 fps
    np.testing.assert_array_equal(frames["tiles"], frames["full"])
    smoothed = (frames["tiles"] != frames["none"]).any(axis=-1).sum(axis=(1, 2))
    assert (smoothed > 100).all(), smoothed
    # two views with shadows on a solid floor (every tile kept): still the full-screen pass
    views = dataclasses.replace(options, shadows=True, layout="1x2", camera="side,front", end=110)
    for name, tiles in (("tiles2", True), ("full2", False)):
        monkeypatch.setattr(gl, "FXAA_TILES", tiles)
        render_motion(walk, tmp_path / f"{name}/####.png", views)
        frames[name] = read_image(tmp_path / name / "0000.png")
    np.testing.assert_array_equal(frames["tiles2"], frames["full2"])


def test_tile_runs_cover_exactly_the_kept_tiles():
    """The quads the FXAA pass is drawn over, painted back, are the kept tiles (runs per row)."""
    from usdmotion.render.gl import tile_runs

    rng = np.random.default_rng(3)
    keep = rng.random((9, 13)) < 0.4
    keep[4] = True  # a row that is one run
    keep[5] = False  # and an empty one
    quads = tile_runs(keep, tile=4)
    assert quads.shape[1:] == (6, 2) and quads.dtype == np.float32
    painted = np.zeros((9 * 4, 13 * 4), int)
    for quad in quads.astype(int):
        (x0, y0), (x1, y1) = quad.min(axis=0), quad.max(axis=0)
        painted[y0:y1, x0:x1] += 1
    assert painted.max() == 1  # no pixel drawn twice
    np.testing.assert_array_equal(painted[::4, ::4].astype(bool), keep)
    np.testing.assert_array_equal(painted, np.kron(keep, np.ones((4, 4), int)))
    assert len(tile_runs(np.zeros((3, 5), bool))) == 0

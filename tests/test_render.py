"""Offscreen rendering, checked numerically: body pixels lie where the joints project
(projection computed here from the camera matrices), the ghost differs from the main
body where the motions differ, EXR holds linear floats, MP4 decodes to the frames."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from usdmotion import rotations as R
from usdmotion.io import read_motion
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.render import RenderOptions, plan_render, render_motion

WALK = "cmu/cgspeed_12_01_walk.bvh"
SMALL = dict(width=320, height=240, start=100, end=220, fps=10.0, overlay=False, body_resolution=48)


@pytest.fixture(scope="module")
def walk():
    from tests.conftest import shared_path

    return read_motion(shared_path(WALK), units="asf")


def project(points: np.ndarray, pose: np.ndarray, yfov: float, width: int, height: int) -> np.ndarray:
    """Pinhole projection written out here (not the renderer's): pixel (column, row)."""
    rotation, eye = pose[:3, :3], pose[:3, 3]
    cam = (points - eye) @ rotation  # world → camera axes (columns of the pose)
    focal = (height / 2) / math.tan(yfov / 2)
    return np.stack([width / 2 + focal * cam[..., 0] / -cam[..., 2],
                     height / 2 - focal * cam[..., 1] / -cam[..., 2]], axis=-1)


def joints_render_space(motion, frames):
    p = fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)[1]
    return p * motion.meters_per_unit  # Y-up file: render space = metres


def is_body(pixels: np.ndarray) -> np.ndarray:
    """Body material (warm orange): red well above blue; background and grid are grey."""
    pixels = pixels.astype(int)
    return pixels[..., 0] - pixels[..., 2] > 45


def is_ghost(pixels: np.ndarray) -> np.ndarray:
    pixels = pixels.astype(int)
    return pixels[..., 2] - pixels[..., 0] > 25


def read_image(path):
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    pixels = image.read_image("uint8" if path.suffix == ".png" else "float")
    image.close()
    return pixels


def inner_joints(motion):
    """Joints inside the flesh: drive a bone and are not end sites or fingers."""
    names = motion.joint_names
    return np.array([j for j in range(motion.n_joints) if not motion.end_sites[j]
                     and not any(s in names[j] for s in ("Thumb", "Index", "FingerBase"))])


def write_camera(path, target: np.ndarray, offset: np.ndarray, z_up_cm: bool = False) -> str:
    """A USD camera at ``target + offset`` (metres, Y up) looking at ``target``; 35 mm lens."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    convert = (lambda p: Gf.Vec3d(p[0], -p[2], p[1]) * 100) if z_up_cm else (lambda p: Gf.Vec3d(*map(float, p)))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if z_up_cm else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01 if z_up_cm else 1.0)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    up = Gf.Vec3d(0, 0, 1) if z_up_cm else Gf.Vec3d(0, 1, 0)
    view = Gf.Matrix4d().SetLookAt(convert(target + offset), convert(target), up)
    cam.AddTransformOp().Set(view.GetInverse())
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateVerticalApertureAttr(20.25)
    stage.GetRootLayer().Save()
    return f"{path}:/World/Cam"


def test_png_body_pixels_are_where_the_joints_project(walk, tmp_path):
    options = RenderOptions(**SMALL, camera="side", grid=True)
    out = tmp_path / "frames" / "####.png"
    result = render_motion(walk, out, options)
    plan = plan_render(walk, options)
    files = sorted((tmp_path / "frames").iterdir())
    assert result.frames == len(plan.frames) == len(files) == 10  # floor(119 / 120 s × 10 fps) + 1
    joints = joints_render_space(walk, plan.frames)
    inner = inner_joints(walk)
    ys, xs = np.mgrid[0:240, 0:320]
    for k, path in enumerate(files):
        image = read_image(path)
        assert image.shape == (240, 320, 3) and image.dtype == np.uint8
        uv = project(joints[k], plan.camera.poses[k], plan.camera.yfov, 320, 240)
        cols, rows = np.floor(uv[inner]).astype(int).T
        assert np.all((cols >= 0) & (cols < 320) & (rows >= 0) & (rows < 240))
        assert is_body(image[rows, cols]).mean() >= 0.9, f"frame {k}: joints not on body pixels"
        # and body pixels are only near the projected skeleton
        body = is_body(image)
        assert body.sum() > 400
        dist = np.min(np.hypot(xs[..., None] - uv[:, 0], ys[..., None] - uv[:, 1]), axis=-1)
        scale = np.ptp(uv[:, 1])  # the skeleton's height in pixels
        assert (body & (dist > 0.2 * scale)).sum() <= 0.01 * body.sum()


def test_exr_holds_linear_floats_of_the_displayed_image(walk, tmp_path):
    options = RenderOptions(**{**SMALL, "end": 125}, camera="front")
    render_motion(walk, tmp_path / "png" / "f_%03d.png", options)
    render_motion(walk, tmp_path / "exr" / "f_%03d.exr", options)
    png = read_image(tmp_path / "png" / "f_000.png")
    exr = read_image(tmp_path / "exr" / "f_000.exr")
    assert exr.dtype == np.float32 and exr.shape == png.shape
    import OpenImageIO as oiio

    assert oiio.ImageInput.open(str(tmp_path / "exr" / "f_000.exr")).spec().format == oiio.HALF
    srgb = png.astype(np.float64) / 255.0
    np.testing.assert_allclose(exr, srgb ** 2.2, atol=2e-3, rtol=2e-3)  # half precision
    body = is_body(png)
    assert body.any()
    # linear, not display values: mid-tones are darker than their 8-bit code / 255
    mid = (srgb > 0.3) & (srgb < 0.8)
    assert np.all(exr[mid] < srgb[mid] - 0.05)


def test_mp4_decodes_to_the_rendered_frames(walk, tmp_path):
    import av

    options = RenderOptions(**SMALL, camera="follow", style="both", traces=("LeftHand", "com"))
    render_motion(walk, tmp_path / "walk.mp4", options)
    render_motion(walk, tmp_path / "ref" / "####.png", options)
    with av.open(str(tmp_path / "walk.mp4")) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        assert abs(float(stream.average_rate) - 10.0) < 1e-6
        decoded = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
    assert len(decoded) == 10 and decoded[0].shape == (240, 320, 3)
    for k in (0, 9):
        ref = read_image(tmp_path / "ref" / f"{k:04d}.png").astype(int)
        assert np.abs(decoded[k].astype(int) - ref).mean() < 4.0  # lossy, but the same picture


def _raise_left_arm(motion, degrees=80.0):
    """The same motion with the left shoulder turned about the body's forward axis."""
    j = motion.joint_index("LeftArm")
    turn = R.axis_angle_quat("Z", np.radians(degrees))
    rotations = np.array(motion.rotations)
    rotations[:, j] = R.quat_mul(rotations[:, j], turn)
    return dataclasses.replace(motion, rotations=rotations)


def test_ghost_differs_from_the_body_where_the_motions_differ(walk, tmp_path):
    other = _raise_left_arm(walk)
    root = joints_render_space(walk, np.array([120]))[0, 0]
    camera = write_camera(tmp_path / "front.usda", root, np.array([0.0, 0.3, 5.0]))  # same view for both
    options = RenderOptions(**{**SMALL, "end": 140}, camera=camera, grid=False)
    render_motion(walk, tmp_path / "alone" / "####.png", options)
    render_motion(walk, tmp_path / "ghost" / "####.png", options, other=other)
    plan = plan_render(walk, options, other)
    hand = walk.joint_index("LeftHand")
    arm = [walk.joint_index(n) for n in ("LeftForeArm", "LeftHand")]
    for k in range(len(plan.frames)):
        alone = read_image(tmp_path / "alone" / f"{k:04d}.png")
        ghost = read_image(tmp_path / "ghost" / f"{k:04d}.png")
        cam = plan.camera
        main_uv = project(joints_render_space(walk, plan.frames[k:k + 1])[0], cam.poses[k], cam.yfov, 320, 240)
        other_uv = project(joints_render_space(other, plan.other_frames[k:k + 1])[0], cam.poses[k], cam.yfov, 320, 240)
        oc, orow = np.floor(other_uv[hand]).astype(int)
        mc, mrow = np.floor(main_uv[hand]).astype(int)
        assert is_ghost(ghost[orow, oc]), "the ghost's raised hand is drawn in the ghost colour"
        assert not is_body(alone[orow, oc]), "…where the main body alone has nothing"
        assert is_body(ghost[mrow, mc]), "the main body's hand stays body-coloured"
        # pixels change only near the ghost's differing arm
        changed = np.abs(ghost.astype(int) - alone.astype(int)).max(axis=-1) > 40
        ys, xs = np.nonzero(changed)
        seg = np.concatenate([np.linspace(other_uv[walk.joint_index("LeftArm")], other_uv[a], 20) for a in arm])
        near = np.min(np.hypot(xs[:, None] - seg[:, 0], ys[:, None] - seg[:, 1]), axis=1) < 0.12 * 240
        assert changed.sum() > 50 and near.mean() > 0.9


def test_side_by_side_panels_show_each_motion(walk, tmp_path):
    other = _raise_left_arm(walk)
    options = RenderOptions(**{**SMALL, "end": 105}, camera="front", grid=False, compare_mode="side")
    render_motion(walk, tmp_path / "side" / "####.png", options, other=other)
    plan = plan_render(walk, options, other)
    image = read_image(tmp_path / "side" / "0000.png")
    assert image.shape == (240, 320, 3) and plan.panel == (160, 240)
    hand = walk.joint_index("LeftHand")
    for panel, motion, frames in ((0, walk, plan.frames), (1, other, plan.other_frames)):
        uv = project(joints_render_space(motion, frames[:1])[0], plan.camera.poses[0], plan.camera.yfov, 160, 240)
        c, r = np.floor(uv[hand]).astype(int)
        assert is_body(image[r, panel * 160 + c])
    left_hand_other = np.floor(project(joints_render_space(other, plan.other_frames[:1])[0], plan.camera.poses[0],
                                       plan.camera.yfov, 160, 240)[hand]).astype(int)
    assert not is_body(image[left_hand_other[1], left_hand_other[0]])  # not raised on the left panel


def test_usd_camera_is_used_as_authored(walk, tmp_path):
    root = joints_render_space(walk, np.array([100]))[0, 0]  # metres, Y up
    camera = write_camera(tmp_path / "cam.usda", root, np.array([4.0, 0.0, 0.0]), z_up_cm=True)  # 4 m to +X
    options = RenderOptions(**{**SMALL, "end": 101}, camera=camera)
    render_motion(walk, tmp_path / "usd" / "####.png", options)
    image = read_image(tmp_path / "usd" / "0000.png")
    # expected pose, computed here: eye 4 m along +X from the root, looking at it, Y up
    eye = root + np.array([4.0, 0.0, 0.0])
    back = (eye - root) / 4.0
    right = np.cross([0.0, 1.0, 0.0], back)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, np.cross(back, right), back], axis=1)
    pose[:3, 3] = eye
    yfov = 2 * math.atan(20.25 / 2 / 35.0)
    plan = plan_render(walk, options)
    np.testing.assert_allclose(plan.camera.poses[0], pose, atol=1e-6)
    uv = project(joints_render_space(walk, np.array([100]))[0], pose, yfov, 320, 240)
    cols, rows = np.floor(uv[inner_joints(walk)]).astype(int).T
    assert is_body(image[rows, cols]).mean() >= 0.9


@pytest.mark.parametrize("setting, expected", [(None, "True"), ("false", "False")])
def test_pyrender_import_keeps_pyglet_off_x11_unless_told(setting, expected):
    """GPU servers often have no X11 libraries: importing pyrender through usdmotion runs
    pyglet headless (EGL) unless PYGLET_HEADLESS says otherwise."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYGLET_HEADLESS"}
    if setting is not None:
        env["PYGLET_HEADLESS"] = setting
    code = ("from usdmotion.render.gl import import_pyrender; import_pyrender(); "
            "import pyglet; print(pyglet.options.headless)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == expected

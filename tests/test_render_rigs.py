"""A body for every rig: the contact sheet of every rig family in the shared corpus, read
from the pixels. Each rig is rendered in its rest (bind) pose from the front and at one
moving frame; the checks locate legs, shoulders and bones from the skeleton with a
projection written here (tests/test_render.py's), not the renderer's.

Set ``USDMOTION_CONTACT_SHEET=path.png`` to keep the sheet (docs/render/contact_sheet.png).
"""

from __future__ import annotations

import dataclasses
import os
import warnings

import numpy as np
import pytest

from usdmotion import rotations as R
from usdmotion.io import read_motion
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.render import RenderOptions, plan_render, render_motion
from usdmotion.skeleton_names import ELBOW_WORDS, KNEE_WORDS, parse_side
from tests.test_render import is_body, project, read_image

#: ``--units auto --up-axis auto``: the files stored Z up in inches (the body's own guess, stated as a warning).
AUTO = {"units": "auto", "up_axis": "auto"}
#: One file per rig family: (label, shared-data path, read options).
FAMILIES = (
    ("Bandai Namco", "bandai1/dataset-1_run_normal_001.bvh", {}),
    ("CMU cgspeed", "cmu/cgspeed_01_01_playground_jumps.bvh", {}),
    ("CMU DAZ", "cmu/daz_10_01_soccer_kick.bvh", {}),
    ("CMU 3ds Max", "cmu/max_131_01_start_walk_stop.bvh", {}),
    ("Mixamo", "other_rigs/ad_mixamo_Boxing.bvh", {}),
    ("Mixamo (mixamorig:)", "other_rigs/20tab_test_freebvh_mixamorig.bvh", {}),
    ("ASF, no head", "other_rigs/ad_cartwheel_clean.bvh", AUTO),
    ("ASF thorax/head", "other_rigs/ad_karate_mawashigeri.bvh", {**AUTO, "ignore_joint_positions": True}),
    ("FAIR", "other_rigs/ad_fair1_zombie.bvh", AUTO),
    ("Rokoko", "other_rigs/ad_rokoko_jesse_dance.bvh", {}),
    ("OptiTrack", "other_rigs/wspr_louise_optitrack_arena.bvh", {}),
    ("bvh-toolbox", "edge_cases/bvhtoolbox_walk01.bvh", {}),
    ("MocapBank", "edge_cases/20tab_test_mocapbank_crlf.bvh", {}),
    ("60 joints", "edge_cases/pybvh_bvh_test3_60joints_mixed_orders.bvh", AUTO),
    ("6 channels/joint", "edge_cases/wspr_milad_blank_line_6ch_125fps.bvh", {}),
    ("bvhio", "edge_cases/bvhio_example.bvh", {}),
)
SIZE = 240
OPTIONS = RenderOptions(width=SIZE, height=SIZE, overlay=False, body_resolution=40, camera="front", fps=1.0)


def render_space(motion: Motion, positions: np.ndarray) -> np.ndarray:
    """File units → metres, Y up, written out here."""
    p = positions * motion.meters_per_unit
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1) if motion.up_axis == "Z" else p


def world_frames(motion: Motion, frames=None) -> np.ndarray:
    """Joint positions ``(F, J, 3)`` of ``frames`` (all by default), metres, Y up."""
    frames = np.arange(motion.n_frames) if frames is None else np.asarray(frames)
    return render_space(motion, fk_arrays(motion.rotations[frames], local_translations(motion)[frames],
                                          motion.parents)[1])


def standing_frames(motion: Motion) -> tuple[int | None, int | None]:
    """``(reference, apart)`` frames of ``motion`` (None = the rest pose).

    ``reference`` is the standing pose the sheet checks: the rest pose if it is upright
    (``upright``), else the frame the renderer binds the body in (``usdmotion.skin.bind_frame``,
    the library's own choice) if that is upright, else the most upright frame with the feet
    apart — among the frames with the torso within 30° of up, the shins within
    ``APART_SHIN_DEG`` of down (from FK) and the ankles at one height (within
    ``APART_LEVEL`` body heights), the one with the largest ankle distance. ``apart`` is
    that last frame in any case (None where there is none): the legs-apart check uses it
    when the legs touch in the reference pose (e.g. Mixamo's T-pose)."""
    from usdmotion.skin import bind_frame

    mid = motion.n_frames // 2
    rest_world = render_space(motion, fk_arrays(np.tile([1.0, 0, 0, 0], (motion.n_joints, 1)),
                                                local_translations(motion)[mid], motion.parents)[1])
    world = world_frames(motion)
    wide = upright_frames(motion, world, shin_deg=APART_SHIN_DEG)
    leg = legs(motion)
    apart = None
    if wide.any() and set(leg) == {"left", "right"}:
        step = world[:, leg["left"][1]] - world[:, leg["right"][1]]
        level = np.abs(step[:, 1]) < APART_LEVEL * np.ptp(world[:, :, 1], axis=1)  # both feet down
        ankles = np.linalg.norm(step, axis=1)
        if (wide & level).any():
            apart = int(np.argmax(np.where(wide & level, ankles, -np.inf)))
    if upright(motion, rest_world):
        return None, apart
    bind = bind_frame(motion)
    if bind is not None and upright(motion, world[bind]):
        return bind, apart
    return (apart if apart is not None else bind), apart


#: Shins within this of straight down in the feet-apart frame (a boxing or fighting stance
#: spreads them wider than the 30° of a standing pose).
APART_SHIN_DEG = 55.0
#: Both feet down in the feet-apart frame: ankle heights within this many body heights.
APART_LEVEL = 0.05
#: The feet-apart frame stands in for a reference pose with touching legs only with the
#: ankles at least this far apart (metres).
APART_ANKLES_M = 0.25


def rest_and_moving(motion: Motion) -> Motion:
    """Three frames: the standing reference (``standing_frames``: the rest pose, the bind
    frame or the most upright frame with the feet apart), the middle frame, and the most
    upright frame with the feet apart (the reference again where there is none)."""
    mid = motion.n_frames // 2
    reference, apart = standing_frames(motion)
    apart = reference if apart is None else apart
    identity = np.zeros((motion.n_joints, 4))
    identity[:, 0] = 1.0
    pose = lambda f: identity if f is None else motion.rotations[f]
    rotations = np.stack([pose(reference), motion.rotations[mid], pose(apart)])
    root = motion.root_translation[[mid if f is None else f for f in (reference, mid, apart)]]
    joint_t = None if motion.joint_translations is None else motion.joint_translations[
        [mid if f is None else f for f in (reference, mid, apart)]]
    return motion.with_frames(rotations, root, joint_t, fps=1.0)


def legs(motion: Motion) -> dict[str, tuple[int, int]]:
    """``{side: (knee, ankle)}`` from the joint names (the knee's first child is the ankle)."""
    out = {}
    for j, name in enumerate(motion.joint_names):
        side, base = parse_side(name)
        if side and base in KNEE_WORDS and not motion.end_sites[j] and side not in out:
            children = motion.children(j)
            if len(children):
                out[side] = (j, int(children[0]))
    return out


def shoulders(motion: Motion) -> list[int]:
    """The joints above each elbow (upper-arm roots)."""
    return [int(motion.parents[j]) for j, name in enumerate(motion.joint_names)
            if parse_side(name)[0] and parse_side(name)[1] in ELBOW_WORDS and not motion.end_sites[j]]


def upright_frames(motion: Motion, world: np.ndarray, legs_too: bool = True, shin_deg: float = 30.0) -> np.ndarray:
    """Standing, per frame ``(F,)``: the shoulders' midpoint above the root within 30° of
    straight up and (``legs_too``) the shin axes (knee → ankle) within ``shin_deg`` of
    straight down (render space ``world (F, J, 3)``). False throughout without two
    shoulders (and knees)."""
    arms, leg = shoulders(motion), legs(motion)
    if len(arms) != 2 or (legs_too and set(leg) != {"left", "right"}):
        return np.zeros(len(world), bool)
    up = np.mean(world[:, arms], axis=1) - world[:, 0]
    ok = up[:, 1] / np.linalg.norm(up, axis=1) > np.cos(np.radians(30))
    for k, a in (leg.values() if legs_too else ()):
        down = world[:, a] - world[:, k]
        ok &= -down[:, 1] / np.linalg.norm(down, axis=1) > np.cos(np.radians(shin_deg))
    return ok


def upright(motion: Motion, world: np.ndarray, legs_too: bool = True, shin_deg: float = 30.0) -> bool:
    """``upright_frames`` of one pose ``world (J, 3)``."""
    return bool(upright_frames(motion, world[None], legs_too, shin_deg)[0])


@pytest.fixture(scope="module")
def sheet(tmp_path_factory):
    """``{label: (motion, two-frame motion, images (2, H, W, 3), camera poses, yfov)}``."""
    from tests.conftest import SHARED_DATA

    out = {}
    folder = tmp_path_factory.mktemp("sheet")
    for k, (label, relative, kwargs) in enumerate(FAMILIES):
        if not (SHARED_DATA / relative).is_file():
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            motion = read_motion(SHARED_DATA / relative, **kwargs)
        two = rest_and_moving(motion)
        options = dataclasses.replace(OPTIONS, camera=across_the_legs(two, folder / f"{k}.usda"))
        render_motion(two, folder / f"{k}/####.png", options)
        images = np.stack([read_image(folder / f"{k}/{i:04d}.png") for i in range(two.n_frames)])
        plan = plan_render(two, options)
        out[label] = (motion, two, images, plan.camera.poses, plan.camera.yfov)
    if not out:
        pytest.skip(f"no shared rig files under {SHARED_DATA}")
    picture = contact_sheet(out)
    target = os.environ.get("USDMOTION_CONTACT_SHEET")
    if target:
        import OpenImageIO as oiio

        image = oiio.ImageOutput.create(target)
        image.open(target, oiio.ImageSpec(picture.shape[1], picture.shape[0], 3, "uint8"))
        image.write_image(picture)
        image.close()
    return out


def across_the_legs(two: Motion, path) -> str:
    """A USD camera (Y up, metres, 24 time codes/s) that looks at each frame of ``two``
    (at 0 s, 1 s, ...) across the line between the knees, so the legs stand apart in the
    picture; from the front (+Z) when the rig has no knees by name."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateVerticalApertureAttr(20.25)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 1000.0))
    op = cam.AddTransformOp()
    leg = legs(two)
    world = render_space(two, fk_arrays(two.rotations, local_translations(two), two.parents)[1])
    for frame in range(two.n_frames):
        joints = world[frame]
        across = np.array([1.0, 0.0, 0.0])
        if set(leg) == {"left", "right"}:
            across = joints[leg["left"][0]] - joints[leg["right"][0]]
            across[1] = 0.0
        view = np.cross(across, [0.0, 1.0, 0.0])
        view = view / np.linalg.norm(view) if np.linalg.norm(view) > 1e-9 else np.array([0.0, 0.0, 1.0])
        target = 0.5 * (joints.min(axis=0) + joints.max(axis=0))
        height = float(np.ptp(joints, axis=0).max())
        eye = target + 2.8 * height * view + [0.0, 0.25 * height, 0.0]
        look = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*map(float, eye)), Gf.Vec3d(*map(float, target)), Gf.Vec3d(0, 1, 0))
        op.Set(look.GetInverse(), Usd.TimeCode(24.0 * frame))
    stage.GetRootLayer().Save()
    return f"{path}:/World/Cam"


def contact_sheet(renders: dict, columns: int = 4) -> np.ndarray:
    """Rest | moving pairs, ``columns`` rigs a row, each labelled."""
    from usdmotion.render.overlay import draw_text

    tiles = []
    for label, (_, _, images, _, _) in renders.items():
        pair = np.ascontiguousarray(np.hstack(images[:2]))  # reference | moving
        draw_text(pair, [label])
        tiles.append(pair)
    while len(tiles) % columns:
        tiles.append(np.full_like(tiles[0], 255))
    return np.vstack([np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)])


def joints_px(two: Motion, frame: int, poses, yfov) -> np.ndarray:
    world = fk_arrays(two.rotations[[frame]], local_translations(two)[[frame]], two.parents)[1][0]
    return project(render_space(two, world), poses[frame], yfov, SIZE, SIZE)


@pytest.mark.parametrize("label", [f[0] for f in FAMILIES])
def test_rest_pose_has_no_webbing_between_the_legs_below_the_knees(sheet, label):
    """In the standing reference pose (``standing_frames``: the rest pose, else the bind
    frame, else the most upright frame with the feet apart), or, where the legs touch in it
    (shins less than 0.1 body sizes apart all the way down), in the most upright frame with
    the feet apart (``APART_ANKLES_M`` at least): body pixels on both shins, none on the
    line midway between them."""
    if label not in sheet:
        pytest.skip(f"{label}: file not in the shared corpus")
    motion, two, images, poses, yfov = sheet[label]
    leg = legs(motion)
    if set(leg) != {"left", "right"}:
        pytest.skip(f"{label}: no left and right knee by name")
    for frame, shin_deg in ((0, 30.0), (2, APART_SHIN_DEG)):
        world = world_frames(two, [frame])[0]
        if not upright(two, world, shin_deg=shin_deg):
            continue
        size = float(np.ptp(world, axis=0).max())
        t = np.linspace(0.25, 0.9, 8)[:, None]
        axis = {s: world[k] + t * (world[a] - world[k]) for s, (k, a) in leg.items()}
        apart = np.linalg.norm(axis["left"] - axis["right"], axis=1) > 0.1 * size  # legs clearly apart
        ankles = np.linalg.norm(world[leg["left"][1]] - world[leg["right"][1]])
        if apart.any() and (frame == 0 or ankles >= APART_ANKLES_M):
            break
    else:
        pytest.skip(f"{label}: in no frame (rest, bind, or of the take) both standing and with the legs apart")
    between = project(0.5 * (axis["left"] + axis["right"])[apart], poses[frame], yfov, SIZE, SIZE)
    on_legs = project(np.concatenate([axis["left"][apart], axis["right"][apart]]), poses[frame], yfov, SIZE, SIZE)
    body = is_body(images[frame])
    pick = lambda px: body[np.clip(px[:, 1].astype(int), 0, SIZE - 1), np.clip(px[:, 0].astype(int), 0, SIZE - 1)]
    assert pick(on_legs).mean() > 0.9, f"{label} (frame {frame}): the legs themselves are not drawn"
    assert not pick(between).any(), f"{label} (frame {frame}): body pixels between the legs below the knees"


@pytest.mark.parametrize("label", [f[0] for f in FAMILIES])
def test_rest_pose_has_one_head_above_the_shoulders(sheet, label):
    from scipy import ndimage

    if label not in sheet:
        pytest.skip(f"{label}: file not in the shared corpus")
    motion, two, images, poses, yfov = sheet[label]
    arms = shoulders(motion)
    if len(arms) != 2:
        pytest.skip(f"{label}: no two upper arms by name")
    px = joints_px(two, 0, poses, yfov)
    world = render_space(two, fk_arrays(two.rotations[[0]], local_translations(two)[[0]], two.parents)[1][0])
    metre = np.linalg.norm(np.diff(project(world[[0, 0]] + [[0, 0, 0], [0, 1, 0]], poses[0], yfov, SIZE, SIZE),
                                   axis=0))
    height = float(np.ptp(world[:, 1]))
    if not upright(two, world, legs_too=False):
        pytest.skip(f"{label}: neither the rest pose nor the bind frame is upright")
    (x0, y0), (x1, y1) = px[arms[0]], px[arms[1]]
    half = 0.15 * height * metre
    left, right = max(int(0.5 * (x0 + x1) - half), 0), int(0.5 * (x0 + x1) + half)
    shoulder_row = min(y0, y1)
    body = is_body(images[0])
    band = body[:int(shoulder_row - 0.04 * height * metre), left:right + 1]
    labels, count = ndimage.label(band)
    assert count == 1, f"{label}: {count} body parts above the shoulders, not one head"
    rows = np.flatnonzero(band.any(axis=1))
    crown = (shoulder_row - rows[0]) / (height * metre)  # crown above the shoulders, body heights
    head = band[rows[0]:rows[0] + int(0.07 * height * metre)]  # the top 0.07 body heights
    width = head.sum(axis=1).max() / (height * metre)
    assert 0.12 < crown < 0.3, f"{label}: crown {crown:.2f} body heights above the shoulders"
    assert 0.05 < width < 0.15, f"{label}: head {width:.2f} body heights wide (profile with the nose)"


def floor_rooted(motion: Motion, offset: np.ndarray) -> Motion:
    """``motion`` under a new static root joint on the floor at ``offset`` (file units):
    a Character Creator-like rig whose root bone sits at the floor, the hips translating
    below it."""
    n, f = motion.n_joints, motion.n_frames
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (f, 1, 1))
    joint_t = np.concatenate([np.zeros((f, 1, 3)), local_translations(motion)], axis=1)
    joint_t[:, 1] -= offset
    return Motion(joint_names=("FloorRoot",) + motion.joint_names, parents=np.r_[-1, np.asarray(motion.parents) + 1],
                  offsets=np.r_[[offset], motion.offsets], rotations=np.concatenate(
                      [identity, motion.rotations], axis=1), root_translation=np.tile(offset, (f, 1)), fps=motion.fps,
                  joint_translations=joint_t, end_sites=np.r_[False, motion.end_sites],
                  meters_per_unit=motion.meters_per_unit, up_axis=motion.up_axis)


@pytest.mark.parametrize("style", ["body", "both"])
def test_a_root_bone_at_the_floor_gets_no_body_and_no_stick(sheet, tmp_path, style):
    """The bone from a static floor root to the hips is no body segment: no body (or stick)
    pixels along it, though it passes well clear of the body."""
    label = "CMU cgspeed"
    if label not in sheet:
        pytest.skip(f"{label}: file not in the shared corpus")
    motion, two, _, _, _ = sheet[label]
    one = two.sliced(1, 2)
    hips = local_translations(one)[0, 0]
    size = float(np.ptp(fk_arrays(one.rotations, local_translations(one), one.parents)[1][0], axis=0).max())
    side = np.array([0.5 * size, 0.0, 0.0])  # beside the body, on the floor (Y up file)
    rooted = floor_rooted(one, np.array([hips[0], 0.0, hips[2]]) + side)
    options = dataclasses.replace(OPTIONS, style=style, grid=False)
    render_motion(rooted, tmp_path / "f/####.png", options)
    image = read_image(tmp_path / "f/0000.png")
    plan = plan_render(rooted, options)
    world = render_space(rooted, fk_arrays(rooted.rotations, local_translations(rooted), rooted.parents)[1][0])
    t = np.linspace(0.1, 0.6, 12)[:, None]
    along = world[0] + t * (world[1] - world[0])
    clear = np.linalg.norm(along[:, None] - world[None, 1:], axis=-1).min(axis=1) > 0.1 * size * one.meters_per_unit
    assert clear.sum() >= 4
    px = project(along[clear], plan.camera.poses[0], plan.camera.yfov, SIZE, SIZE).astype(int)
    pixels = image[px[:, 1], px[:, 0]].astype(int)
    background = np.abs(pixels - image[2, 2].astype(int)).max(axis=1) < 40  # not body, not a dark stick
    assert background.all(), f"drawn along the floor root bone: {pixels[~background]}"
    assert is_body(image).sum() > 200  # the body itself is there


def test_default_side_camera_follows_the_body_at_about_60_percent_of_the_height(tmp_path):
    """A 4 m walk: at its first and last frames the body is ~60 % of the picture height and
    near the middle (the fixed ``path`` preset, for comparison, shows it much smaller)."""
    from tests.conftest import shared_path

    walk = read_motion(shared_path("cmu/cgspeed_12_01_walk.bvh"), units="asf")
    shares = {}
    for camera in ("side", "path"):
        options = RenderOptions(width=320, height=240, overlay=False, body_resolution=40, camera=camera, fps=0.5,
                                grid=False)
        render_motion(walk, tmp_path / camera / "####.png", options)
        shares[camera] = []
        for path in sorted((tmp_path / camera).iterdir()):
            body = is_body(read_image(path))
            rows, cols = np.flatnonzero(body.any(axis=1)), np.flatnonzero(body.any(axis=0))
            shares[camera].append((np.ptp(rows) + 1) / 240)
            if camera == "side":
                assert abs(0.5 * (cols[0] + cols[-1]) - 160) < 0.2 * 320, path.name  # near the middle
    assert len(shares["side"]) == 3
    assert all(0.45 < s < 0.75 for s in shares["side"]), shares
    assert max(shares["path"]) < 0.8 * min(shares["side"]), shares


def with_helpers(motion: Motion, size: float) -> Motion:
    """``motion`` with a twist bone under the left upper arm (half-way down it) and an IK
    helper under the root, ``0.4 size`` to the side: leaves without End Sites."""
    arm, forearm = motion.joint_index("LeftArm"), motion.joint_index("LeftForeArm")
    f = motion.n_frames
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (f, 2, 1))
    return Motion(joint_names=motion.joint_names + ("LeftArmTwist", "ik_hand_root"),
                  parents=np.r_[motion.parents, arm, 0],
                  offsets=np.r_[motion.offsets, [0.5 * motion.offsets[forearm]], [[0.4 * size, 0.0, 0.0]]],
                  rotations=np.concatenate([motion.rotations, identity], axis=1),
                  root_translation=motion.root_translation, fps=motion.fps,
                  end_sites=np.r_[motion.end_sites, False, False], meters_per_unit=motion.meters_per_unit,
                  up_axis=motion.up_axis)


def test_twist_and_ik_helper_joints_get_no_body(tmp_path):
    from tests.conftest import shared_path
    from usdmotion.skin import bone_capsules, body_size

    walk = read_motion(shared_path("cmu/cgspeed_12_01_walk.bvh"), units="asf").sliced(100, 101)
    size = body_size(walk)
    rig = with_helpers(walk, size)
    caps = bone_capsules(rig)
    helpers = [rig.joint_index("LeftArmTwist"), rig.joint_index("ik_hand_root")]
    assert not np.isin(caps.joint, helpers).any()
    rest = fk_arrays(rig.rotations[:1] * 0 + [1.0, 0, 0, 0], local_translations(rig)[:1], rig.parents)[1][0]
    ends = np.linalg.norm(caps.end[:, None] - rest[helpers][None], axis=-1)
    assert (ends > 1e-6 * size).all()  # no capsule ends at a helper either
    options = dataclasses.replace(OPTIONS, camera="front", grid=False, style="both", contact_shadow=False)
    render_motion(rig, tmp_path / "f/####.png", options)
    image = read_image(tmp_path / "f/0000.png")
    plan = plan_render(rig, options)
    world = render_space(rig, fk_arrays(rig.rotations, local_translations(rig), rig.parents)[1][0])
    x, y = project(world[rig.joint_index("ik_hand_root")], plan.camera.poses[0], plan.camera.yfov, SIZE, SIZE)
    patch = image[int(y) - 2:int(y) + 3, int(x) - 2:int(x) + 3].astype(int)
    assert np.abs(patch - image[2, 2].astype(int)).max() < 40, "a body or stick at the IK helper"


@pytest.mark.parametrize("label", ["CMU cgspeed", "CMU DAZ", "Mixamo", "Bandai Namco", "OptiTrack"])
def test_the_nose_points_where_the_toes_point(label):
    """The head's nose (the facing cue) sits in front of the head, front taken here from the
    feet of the bind pose (ankle → toe, horizontal), not from the left/right limbs the body
    builder uses."""
    from tests.conftest import SHARED_DATA
    from usdmotion.body_parts import head_joint
    from usdmotion.skin import bind_pose, bone_capsules

    relative, kwargs = next((r, k) for name, r, k in FAMILIES if name == label)
    if not (SHARED_DATA / relative).is_file():
        pytest.skip(f"{relative} not in the shared corpus")
    motion = read_motion(SHARED_DATA / relative, **kwargs)
    rest = bind_pose(motion)[1]
    caps = bone_capsules(motion, positions=rest)
    on_head = np.flatnonzero(caps.joint == head_joint(motion))
    assert len(on_head) == 2  # one head, one nose
    nose, head = on_head[np.argsort(caps.r0[on_head])]
    assert caps.r0[nose] < 0.5 * caps.r0[head] and np.all(caps.start[nose] == caps.end[nose])
    up = np.zeros(3)
    up[1 if motion.up_axis == "Y" else 2] = 1.0
    ankles = [a for _, a in legs(motion).values()]
    forward = np.mean([rest[motion.children(a)[0]] - rest[a] for a in ankles], axis=0)  # ankle → toe
    forward -= (forward @ up) * up
    centre = 0.5 * (caps.start[head] + caps.end[head])
    assert (caps.start[nose] - centre) @ forward > 0

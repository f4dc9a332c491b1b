"""Stroboscope stills (``render --strobe N`` / ``--strobe-every 0.1s``): many poses of the
rendered range in one picture, fading from the background colour (oldest) to the full
body colour (latest), like Dartfish StroMotion.

The body is built once and skinned at every chosen frame at once (one :func:`lbs` call);
each pose is an opaque mesh of its own colour, so overlapping poses are depth-sorted by
the renderer, not blended in an arbitrary order (``--style both``: translucent bodies,
each at its own centre so they are drawn back to front, with a stick figure inside;
``--style stick``: stick figures only). ``--trace`` paths are the video's
(:mod:`usdmotion.render.traces`) over every source frame from the first pose to the last.
The camera is the chosen preset held fixed over the whole range (framing ``--focus``
joints only, if given). The still is written atomically (PNG or JPEG).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError, UsdMotionError
from usdmotion.io.atomic import atomic_output
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.render import focus_joints, framing_pad, output_frames, plan_render
from usdmotion.render.camera import load_presets, preset_track, project
from usdmotion.render.gl import import_pyrender, offscreen_renderer, render_rgb
from usdmotion.render.overlay import draw_text
from usdmotion.render.scene import COLORS, add_lights, grid_mesh, material, to_render_space
from usdmotion.render.space import render_joints
from usdmotion.render.traces import is_com, trace_meshes
from usdmotion.render.views import stick_figure
from usdmotion.skin import build_body, lbs, skinning_matrices

STILL_EXTENSIONS = (".png", ".jpg", ".jpeg")
_EVERY = re.compile(r"^\s*(?P<value>[0-9]*\.?[0-9]+)\s*(?P<unit>s|ms|f|frames?)?\s*$", re.IGNORECASE)


def strobe_frames(motion: Motion, start: int, end: int, count: int | None, every: str | None) -> np.ndarray:
    """Source frames ``(N,)`` of the poses: ``count`` evenly spaced over ``start:end`` (end
    exclusive, both ends shown), or one every ``every`` (``0.1s``, ``100ms``, ``12f``)."""
    if (count is None) == (every is None):
        raise UsdMotionError("give one of --strobe N or --strobe-every TIME")
    last = end - 1
    if count is not None:
        if not 2 <= count <= 200:
            raise UsdMotionError(f"--strobe must be 2..200 poses, got {count}")
        return np.unique(np.rint(np.linspace(start, last, count)).astype(np.int64))
    match = _EVERY.match(every)
    if not match:
        raise UsdMotionError(f"--strobe-every {every!r}: use seconds (0.1s), milliseconds (100ms) or frames (12f)")
    value, unit = float(match["value"]), (match["unit"] or "s").lower()
    step = value * motion.fps if unit == "s" else value * motion.fps / 1000.0 if unit == "ms" else value
    if not step > 0:
        raise UsdMotionError(f"--strobe-every {every!r} must be positive")
    frames = np.unique(np.rint(np.arange(start, last + 1e-9, step)).astype(np.int64))
    if not 2 <= len(frames) <= 200:
        raise UsdMotionError(f"--strobe-every {every!r} gives {len(frames)} poses over frames {start}:{end} "
                             "(need 2..200)")
    return frames


def check_still(path: Path) -> None:
    """Fail early on a still that cannot be written."""
    if path.suffix.lower() not in STILL_EXTENSIONS:
        raise OutputError(f"{path}: a stroboscope still is one image: use .png or .jpg")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {folder} does not exist")


#: Colour weight of the oldest pose (1: the full colour; the latest pose has 1).
FADE_OLDEST = 0.3


def render_strobe(motion: Motion, output: str | Path, options, count: int | None = None,
                  every: str | None = None) -> np.ndarray:
    """Render the stroboscope still of ``motion`` to ``output``; returns its source frames ``(N,)``."""
    import dataclasses

    output = Path(output)
    check_still(output)
    rendered, _, _ = output_frames(motion, options)
    frames = strobe_frames(motion, int(rendered[0]), int(rendered[-1]) + 1, count, every)
    plan = plan_render(motion, dataclasses.replace(options, start=int(frames[0]), end=int(frames[-1]) + 1))
    image = _draw(motion, frames, plan, options)
    import OpenImageIO as oiio

    with atomic_output(output) as tmp:
        spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, "uint8")
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec) or not out.write_image(image):
            raise OutputError(f"{output}: cannot write: {oiio.geterror()}")
        out.close()
    return frames


def fixed_camera(motion: Motion, frames: np.ndarray, options, pad: float):
    """The preset camera of ``options.camera`` held fixed, framing the joints at ``frames``."""
    presets = load_presets()
    if options.camera not in presets:
        return None
    held = {options.camera: dict(presets[options.camera], track="fixed", orbit=0.0)}
    joints = render_joints(motion, frames)
    times = frames / motion.fps
    return preset_track(options.camera, joints, times, options.width / options.height, pad, presets=held,
                        frame=focus_joints(motion, options.focus))


def _draw(motion: Motion, frames: np.ndarray, plan, options) -> np.ndarray:
    pyrender = import_pyrender()

    world_q, world_p = fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)
    joints = to_render_space(world_p, motion.meters_per_unit, motion.up_axis)
    camera = fixed_camera(motion, frames, options, framing_pad(motion, options)) or plan.camera
    travel = joints[-1, 0] - joints[0, 0]
    travel[1] = 0.0
    forward = travel / np.linalg.norm(travel) if np.linalg.norm(travel) > 1e-6 else np.array([0.0, 0.0, 1.0])
    scene, traced = (_scene(pyrender, camera, options, forward) for _ in range(2))  # poses; traces over them
    body = None
    if options.style != "stick" or any(map(is_com, options.traces)):
        body = build_body(motion, resolution=options.body_resolution)
    weights = np.linspace(FADE_OLDEST, 1.0, len(frames))
    if options.style in ("body", "both"):
        positions = lbs(body.vertices, body.weight_matrix(), skinning_matrices(world_q, world_p, body.bind_transforms))
        _add_bodies(scene, to_render_space(positions, motion.meters_per_unit, motion.up_axis), body.faces,
                    weights, translucent=options.style == "both")
    if options.style in ("stick", "both"):
        _add_sticks(scene, stick_figure(motion), joints, weights)
    distance = float(np.linalg.norm(camera.poses[-1][:3, 3] - joints[:, 0].mean(axis=0)))
    if options.grid:
        margin = max(2.0, 2 * options.grid_scale)
        lo, hi = joints.reshape(-1, 3).min(axis=0) - margin, joints.reshape(-1, 3).max(axis=0) + margin
        for mesh in grid_mesh(lo, hi, plan.ground, options.grid_scale, max(0.0025 * distance, 0.004),
                              eye=camera.poses[-1][:3, 3], pixel_angle=2 * np.tan(camera.yfov / 2) / options.height):
            scene.add(mesh)
    if options.traces:  # the paths over every source frame from the first pose to the last
        span = np.arange(frames[0], frames[-1] + 1)
        for mesh in trace_meshes(motion, options.traces, span, render_joints(motion, span), distance, body):
            traced.add(mesh)
    renderer = offscreen_renderer(options.width, options.height, msaa=options.msaa, fxaa=options.fxaa)
    try:
        image = render_rgb(renderer, scene, options.shadows)
        if options.traces:
            image = _over(image, *_on_black_and_white(renderer, traced))
    finally:
        renderer.delete()
    if options.overlay:
        step = (frames[-1] - frames[0]) / motion.fps / max(len(frames) - 1, 1)
        text = f"frames {frames[0]}-{frames[-1]}: {len(frames)} poses every {step:.3f} s"
        draw_text(image, [options.labels[0], text] if options.labels[0] else [text])
    return image


def _scene(pyrender, camera, options, forward: np.ndarray):
    """An empty scene seen by ``camera`` (its last pose), lit from the front left of ``forward``."""
    scene = pyrender.Scene(bg_color=np.array(COLORS["background"]), ambient_light=np.full(3, 0.45))
    scene.add(pyrender.PerspectiveCamera(yfov=camera.yfov, aspectRatio=options.width / options.height,
                                         znear=camera.znear, zfar=camera.zfar), pose=camera.poses[-1])
    add_lights(scene, forward)
    return scene


def _add_bodies(scene, positions: np.ndarray, faces: np.ndarray, weights: np.ndarray, translucent: bool) -> None:
    """One mesh per pose (``positions (N, V, 3)`` m), coloured by ``weights (N,)`` (:func:`_faded`).
    Translucent bodies (``--style both``) sit at their own centre, so the renderer draws them back to front."""
    pyrender = import_pyrender()
    import trimesh

    colors = _faded(np.asarray(COLORS["body"]), weights)
    colors[:, 3] = 0.45 if translucent else 1.0
    for pose, color in zip(positions, colors):
        centre = pose.mean(axis=0) if translucent else np.zeros(3)
        mesh = trimesh.Trimesh(pose - centre, faces, process=False)
        scene.add(pyrender.Mesh.from_trimesh(mesh, material=material(tuple(color)), smooth=True),
                  pose=np.r_[np.c_[np.eye(3), centre], [[0.0, 0.0, 0.0, 1.0]]])


def _add_sticks(scene, figure, joints: np.ndarray, weights: np.ndarray) -> None:
    """One stick figure per pose (``joints (N, J, 3)`` m), its colours faded by ``weights (N,)``."""
    pyrender = import_pyrender()

    for pose, w in zip(joints, weights):
        positions, normals = figure.geometry(pose)
        colors = _faded(figure.colors, w).astype(np.float32)
        primitive = pyrender.Primitive(positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                                       indices=np.asarray(figure.faces, np.uint32), color_0=colors,
                                       material=material((1.0, 1.0, 1.0, 1.0)))
        scene.add(pyrender.Mesh([primitive]))


def _on_black_and_white(renderer, scene) -> tuple[np.ndarray, np.ndarray]:
    """``scene`` rendered on a black and on a white background: two ``(H, W, 3)`` uint8 images."""
    out = []
    for background in (0.0, 1.0):
        scene.bg_color = np.array([background] * 3 + [1.0])
        out.append(render_rgb(renderer, scene))
    return out[0], out[1]


def _over(image: np.ndarray, on_black: np.ndarray, on_white: np.ndarray) -> np.ndarray:
    """``image (H, W, 3)`` uint8 with a layer drawn over it, the layer given as rendered on black
    and on white: its coverage ``a = 1 - (white - black) / 255`` (anti-aliased edges partly covered),
    its colour times coverage the black one; the result ``black + (1 - a) · image``."""
    black, white = on_black.astype(np.float64), on_white.astype(np.float64)
    cover = np.clip(1.0 - (white - black).mean(axis=-1, keepdims=True) / 255.0, 0.0, 1.0)
    return np.clip(np.rint(black + (1.0 - cover) * image), 0, 255).astype(np.uint8)


def _faded(colors: np.ndarray, weights) -> np.ndarray:
    """RGBA ``colors (..., 4)`` moved towards the background: ``weights`` 1 keeps them, 0 is the background."""
    w = np.asarray(weights, dtype=np.float64)[..., None]
    rgb = (1 - w) * np.asarray(COLORS["background"][:3]) + w * np.asarray(colors)[..., :3]
    return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], axis=-1)


def projected_roots(motion: Motion, frames: np.ndarray, options) -> np.ndarray:
    """Pixel positions ``(N, 2)`` of the root at ``frames`` in the still (for tests, checks)."""
    camera = fixed_camera(motion, frames, options, framing_pad(motion, options))
    return project(render_joints(motion, frames)[:, 0], camera.poses[-1], camera.yfov, options.width, options.height)


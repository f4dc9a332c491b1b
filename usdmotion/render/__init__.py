"""Offscreen rendering of motions to feedback videos and image sequences (pyrender, EGL).

``render_motion(motion, output, options, other=None)`` renders a skinned body, a stick
figure or both, with a ground grid, trajectory traces, a frame/time overlay, and an
optional second motion beside it or overlaid as a translucent ghost. Frames stream
through a bounded queue into a writer thread (encoding overlaps rendering); skinning
runs in chunks of :data:`usdmotion.render.views.CHUNK` frames, so memory stays flat however long the motion.
See ``docs/render.md``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.progress import Progress
from usdmotion.render.angles import parse_angle, sidecar_path, write_sidecar
from usdmotion.render.camera import check_camera, is_usd_camera, preset_track, usd_camera_track
from usdmotion.render.compare import align_takes
from usdmotion.render.output import WriterThread, check_output, open_writer
from usdmotion.render.overlay import warm_up_text
from usdmotion.render.panel import parse_panel, strip_height
from usdmotion.render.scene import to_render_space
from usdmotion.render.traces import check_traces
from usdmotion.skin import body_size

STYLES = ("body", "stick", "both")
COMPARE_MODES = ("ghost", "side")


@dataclass(frozen=True)
class RenderOptions:
    """What to render. Frame numbers are the source motion's (``end`` exclusive)."""

    width: int = 1280
    height: int = 720
    start: int | None = None
    end: int | None = None
    fps: float | None = None
    speed: float = 1.0
    camera: str = "side"
    style: str = "body"
    grid: bool = True
    grid_scale: float = 1.0
    traces: tuple[str, ...] = ()
    overlay: bool = True
    compare_mode: str = "ghost"
    shadows: bool = False
    msaa: int = 0
    fxaa: bool = True  # anti-aliasing post pass where there is no multisampling (msaa 0)
    quality: int = 20
    body_resolution: int = 96
    body: str = "auto"  # "stage": the input's own skinned meshes, "generated": usdmotion.skin.build_body, "auto": stage if any
    labels: tuple[str, str] = ("", "")
    angles: tuple[str, ...] = ()
    align: str = "start"
    panel: str | None = None
    layout: str | None = None
    contact_shadow: bool = True
    lod: bool = True  # fewer body triangles when the body is drawn small (usdmotion.render.lod); False: all
    focus: tuple[str, ...] = ()  # joints a preset camera frames (a close-up); () = the whole body


@dataclass(frozen=True)
class RenderPlan:
    """Which source frames each output frame shows, at what time, seen from where."""

    frames: np.ndarray              # (N,) source frame of the main motion
    other_frames: np.ndarray | None  # (N,) source frame of the compared motion
    times: np.ndarray               # (N,) seconds since the main motion's frame 0
    fps: float
    camera: object                  # usdmotion.render.camera.CameraTrack
    panel: tuple[int, int]          # (width, height) of one view
    ground: float                   # ground height, metres (render space)
    alignment: object = None        # usdmotion.render.compare.Alignment of the compared motion
    cameras: tuple = ()             # --layout: one CameraTrack per view, row by row (camera = cameras[0])
    grid_shape: tuple[int, int] = (1, 1)  # --layout rows, columns


@dataclass
class RenderResult:
    frames: int
    seconds: float
    timings: dict = field(default_factory=dict)

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def default_fps(motion_fps: float) -> float:
    """The motion's rate, or the largest integer fraction of it not above 60 fps."""
    return motion_fps / math.ceil(motion_fps / 60.0 - 1e-9)


#: Most frames a video may have (9 hours at 60 fps): a slow-motion factor that asks for more
#: is a typo, not a video.
MAX_VIDEO_FRAMES = 2_000_000


def output_frames(motion: Motion, options: RenderOptions) -> tuple[np.ndarray, np.ndarray, float]:
    """``(source_frames (N,), times (N,) s, fps)`` of the output, per options."""
    start = 0 if options.start is None else int(options.start)
    end = motion.n_frames if options.end is None else min(int(options.end), motion.n_frames)
    if motion.n_frames == 0 or end <= start or start >= motion.n_frames:
        raise UsdMotionError(f"no frames to render (the motion has {motion.n_frames} frames, "
                             f"range {start}:{end})")
    if not (options.speed > 0 and math.isfinite(options.speed)):
        raise UsdMotionError(f"--speed must be a positive number, got {options.speed}")
    fps = default_fps(motion.fps) if options.fps is None else float(options.fps)
    if not (fps > 0 and math.isfinite(fps)):
        raise UsdMotionError(f"--fps must be a positive number, got {options.fps}")
    span = (end - 1 - start) / motion.fps
    count = math.floor(span * fps / options.speed + 1e-6) + 1
    if count > MAX_VIDEO_FRAMES:  # checked before the frame arrays are allocated
        shown = f"{count:,}" if count < 10**12 else f"{float(count):.3g}"  # --speed 1e-300: 300 digits otherwise
        raise UsdMotionError(f"the video would have {shown} frames ({span:.3g} s of motion at --speed "
                             f"{options.speed:g}, {fps:g} fps); at most {MAX_VIDEO_FRAMES:,} (9 hours at 60 fps)")
    times = start / motion.fps + np.arange(count) * options.speed / fps
    frames = np.clip(np.rint(times * motion.fps).astype(np.int64), start, end - 1)
    return frames, times, fps


#: Multisample counts OpenGL drivers accept (0 = off).
MSAA_SAMPLES = (0, 1, 2, 4, 8, 16)


def check_options(options: RenderOptions) -> None:
    """Refuse any option out of range before work starts (raises ``UsdMotionError``)."""
    if options.style not in STYLES:
        raise UsdMotionError(f"unknown style {options.style!r} (use {', '.join(STYLES)})")
    if options.body not in ("auto", "stage", "generated"):
        raise UsdMotionError(f"--body must be auto, stage or generated, got {options.body!r}")
    if options.compare_mode not in COMPARE_MODES:
        raise UsdMotionError(f"unknown compare mode {options.compare_mode!r} (use {', '.join(COMPARE_MODES)})")
    if not (16 <= options.width <= 8192 and 16 <= options.height <= 8192):
        raise UsdMotionError(f"image size {options.width}x{options.height} is outside 16..8192")
    if not (math.isfinite(options.grid_scale) and options.grid_scale > 0):
        raise UsdMotionError(f"--grid-scale must be a positive number, got {options.grid_scale}")
    if not (math.isfinite(options.speed) and options.speed > 0):
        raise UsdMotionError(f"--speed must be a positive number, got {options.speed}")
    if options.fps is not None and not (math.isfinite(options.fps) and 0 < options.fps <= 1000):
        raise UsdMotionError(f"--fps must be a number in (0, 1000], got {options.fps}")
    if options.msaa not in MSAA_SAMPLES:
        raise UsdMotionError(f"--msaa must be one of {', '.join(map(str, MSAA_SAMPLES))}, got {options.msaa}")
    if not 0 <= options.quality <= 51:
        raise UsdMotionError(f"--quality (H.264 CRF) must be in 0..51, got {options.quality}")
    if not 4 <= options.body_resolution <= 1024:
        raise UsdMotionError(f"body resolution must be in 4..1024, got {options.body_resolution}")

    for name in camera_names(options):
        check_camera(name)
        if options.focus and is_usd_camera(name):
            raise UsdMotionError(f"--focus aims a preset (side, path, front, ...); leave it out with {name}")
    for name, value in (("start", options.start), ("stop", options.end)):
        if value is not None and value < 0:
            raise UsdMotionError(f"--frames: {name} {value} is negative; frames count from 0 "
                                 "(no Python-style negative indices)")


def camera_names(options: RenderOptions) -> list[str]:
    """The ``--camera`` names, one per view of ``--layout`` (row by row); ``UsdMotionError`` when the counts differ."""
    rows, cols = parse_layout(options.layout)
    names = [c.strip() for c in options.camera.split(",")] if "," in options.camera else [options.camera]
    if len(names) != rows * cols:
        raise UsdMotionError(f"--layout {rows}x{cols} needs {rows * cols} cameras (--camera side,front,top,follow), "
                             f"got {len(names)}" if options.layout else
                             "several cameras need --layout (e.g. --layout 2x2 --camera side,front,top,follow)")
    return names


def render_joints(motion: Motion, frames: np.ndarray) -> np.ndarray:
    """Joint positions ``(N, J, 3)`` at ``frames`` in render space (see :mod:`usdmotion.render.space`)."""
    from usdmotion.render.space import render_joints as joints  # here: this function has its name

    return joints(motion, frames)


def plan_render(motion: Motion, options: RenderOptions, other: Motion | None = None) -> RenderPlan:
    """Frames, times and camera of a render (no GL needed; tests project joints with it)."""
    check_options(options)
    check_traces(motion, options.traces)
    if other is None and options.align != "start":
        raise UsdMotionError("--align needs --compare OTHER")
    if options.angles:
        for text in options.angles:
            parse_angle(motion, text)
    frames, times, fps = output_frames(motion, options)
    other_frames = None
    joints = [to_render_space(_joint_positions(motion, frames), motion.meters_per_unit, motion.up_axis)]
    pad = framing_pad(motion, options)
    alignment = None
    if other is not None:
        if other.n_frames == 0:
            raise UsdMotionError("no frames to render: the compared motion has no frames")
        alignment = align_takes(motion, other, frames, times, options.align, render_joints)
        other_frames = alignment.frames
        joints.append(render_joints(other, other_frames) @ alignment.turn.T + alignment.shift)
        pad = max(pad, framing_pad(other, options))
    side = other is not None and options.compare_mode == "side"
    strip = 0
    if options.panel:
        strip = strip_height(options.height, len(parse_panel(options.panel)))
    rows, cols = parse_layout(options.layout)
    names = camera_names(options)
    if options.layout and side:
        raise UsdMotionError("--layout and --compare-mode side cannot be combined (use the ghost)")
    panel = (options.width // 2 if side else options.width // cols, (options.height - strip) // rows)
    cameras = []
    for name in names:
        if is_usd_camera(name):
            cameras.append(usd_camera_track(name, times))
        else:
            cameras.append(preset_track(name, np.concatenate(joints, axis=1), times, panel[0] / panel[1], pad,
                                        frame=focus_joints(motion, options.focus)))
    ground = min(0.0, float(min(j[..., 1].min() for j in joints)))
    return RenderPlan(frames, other_frames, times, fps, cameras[0], panel, ground, alignment,
                      tuple(cameras) if options.layout else (), (rows, cols))


def framing_pad(motion: Motion, options: RenderOptions) -> float:
    """Metres a preset camera's box around the joints is widened by to hold the flesh: 8 % of
    the body's size, 4 % around ``--focus`` joints (a close-up)."""
    return (0.04 if options.focus else 0.08) * body_size(motion) * motion.meters_per_unit


def focus_joints(motion: Motion, names: tuple[str, ...]) -> np.ndarray | None:
    """Indices ``(K,)`` of the ``--focus`` joints of ``motion`` (``None``: no focus, the whole body)."""
    if not names:
        return None
    try:
        return np.array([motion.joint_index(name) for name in names], dtype=np.int64)
    except KeyError as exc:
        raise UsdMotionError(f"--focus: {exc.args[0]}") from None


def parse_layout(text: str | None) -> tuple[int, int]:
    """``"2x2"`` → ``(2, 2)`` (rows, columns); ``None`` → ``(1, 1)``."""
    if not text:
        return 1, 1
    try:
        rows, cols = (int(v) for v in text.lower().split("x"))
    except ValueError:
        rows = cols = 0
    if not (1 <= rows <= 3 and 1 <= cols <= 3):
        raise UsdMotionError(f"--layout {text!r}: use ROWSxCOLUMNS from 1x1 to 3x3, e.g. 2x2")
    return rows, cols


def _joint_positions(motion: Motion, frames: np.ndarray) -> np.ndarray:
    return fk_arrays(motion.rotations[frames], local_translations(motion)[frames], motion.parents)[1]




def render_motion(motion: Motion, output: str | Path, options: RenderOptions = RenderOptions(),
                  other: Motion | None = None, progress: Progress | None = None) -> RenderResult:
    """Render ``motion`` (and ``other``, compared) to ``output`` (``.mp4`` or ``dir/####.png``).

    ``progress``: optional :class:`usdmotion.progress.Progress`, called ``(frames done, total, message)``
    once per frame.
    Nothing is left at ``output`` if anything fails.
    """
    output = Path(output)
    check_output(output, options.width, options.height)
    plan = plan_render(motion, options, other)
    from usdmotion.render.views import Views  # GL from here on

    started = time.perf_counter()

    def open_output():  # on the writer thread, while the body is built
        warm_up_text(plan.panel[1])
        return open_writer(output, options.width, options.height, plan.fps, options.quality)

    writer = WriterThread(open_output)
    committed = False
    try:
        views = Views(motion, other, plan, options)
        timings = {"build": time.perf_counter() - started}
        try:
            views.run(lambda images, index: writer.put(images, index, views.finish), progress, timings)
            committed = True
        finally:
            views.close()
    finally:
        writer.close(commit=committed)
    timings["encode"] = writer.busy
    timings["overlay"] = writer.finishing
    if views.angles is not None:
        write_sidecar(sidecar_path(output), plan, views.angles)
    return RenderResult(len(plan.frames), time.perf_counter() - started, timings)

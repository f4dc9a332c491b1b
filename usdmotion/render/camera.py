"""Cameras for offscreen rendering: presets (data in ``render/cameras.yaml``) and USD cameras.

Render space: metres, Y up (Z-up files are turned by ``(x, y, z) → (x, z, -y)``).
Camera poses are camera-to-world ``(4, 4)`` matrices in the OpenGL convention (the
camera looks along its −Z axis, +Y is up in the image), as pyrender and UsdGeom use.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.constants import MAX_ABS_VALUE
from usdmotion.errors import InputError, UsdMotionError
from usdmotion.resources import resource_path
from usdmotion.usd_diagnostics import usd_diagnostics

PRESETS_FILE = resource_path("render", "cameras.yaml")
_USD_CAMERA = re.compile(r"^(?P<file>.+\.usd[acz]?)(?::(?P<prim>/.*))?$", re.IGNORECASE)
UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class CameraTrack:
    """Per output frame camera poses ``(N, 4, 4)``, vertical field of view (radians), clip planes."""

    poses: np.ndarray
    yfov: float
    znear: float = 0.05
    zfar: float = 2000.0


def load_presets(path: Path | None = None) -> dict[str, dict]:
    """The camera presets, ``{name: settings}``."""
    import yaml

    path = PRESETS_FILE if path is None else Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise UsdMotionError(f"{path}: cannot read the camera presets: {exc}") from None
    return {str(k): dict(v) for k, v in (data or {}).items()}


def check_camera(spec: str) -> None:
    """Refuse an unknown preset or a missing camera file before any work."""
    if is_usd_camera(spec):
        path = Path(_USD_CAMERA.match(spec)["file"])
        if not path.is_file():
            raise InputError(path, "no such camera file")
        return
    presets = load_presets()
    if spec not in presets:
        raise UsdMotionError(f"unknown camera preset {spec!r} (use one of: {', '.join(sorted(presets))}, "
                             "or a USD file with a camera, e.g. cam.usda:/World/Camera)")


def is_usd_camera(spec: str) -> bool:
    """True if ``spec`` names a USD file (``cam.usda`` or ``cam.usda:/World/Camera``)."""
    return bool(_USD_CAMERA.match(spec))


def look_at(eye: np.ndarray, target: np.ndarray, up_hint: np.ndarray) -> np.ndarray:
    """Camera-to-world poses ``(..., 4, 4)`` looking from ``eye`` at ``target``."""
    back = eye - target
    back = back / np.linalg.norm(back, axis=-1, keepdims=True)
    right = np.cross(up_hint, back)
    right = right / np.linalg.norm(right, axis=-1, keepdims=True)
    up = np.cross(back, right)
    pose = np.zeros(back.shape[:-1] + (4, 4))
    pose[..., :3, 0], pose[..., :3, 1], pose[..., :3, 2], pose[..., :3, 3] = right, up, back, eye
    pose[..., 3, 3] = 1.0
    return pose


def forward_direction(root: np.ndarray, height: float) -> np.ndarray:
    """Horizontal unit travel direction of a root path ``(N, 3)`` (render space), or +Z."""
    travel = root[-1] - root[0]
    travel[1] = 0.0
    n = float(np.linalg.norm(travel))
    return travel / n if n > 0.3 * height else np.array([0.0, 0.0, 1.0])


def preset_track(name: str, joints: np.ndarray, times: np.ndarray, aspect: float, pad: float,
                 presets: dict[str, dict] | None = None, frame: np.ndarray | None = None) -> CameraTrack:
    """The camera of preset ``name`` for joint paths ``joints (N, J, 3)`` at ``times (N,)`` s.

    ``pad`` (metres) widens the joints' bounding box to hold the body's flesh; ``frame``:
    indices of the joints whose box is framed (default: all; ``--focus``, a close-up). The
    travel direction and a follow camera's path are the root's (joint 0) in either case.
    """
    presets = load_presets() if presets is None else presets
    if name not in presets:
        raise UsdMotionError(f"unknown camera preset {name!r} (use one of: {', '.join(sorted(presets))}, "
                             "or a USD file with a camera, e.g. cam.usda:/World/Camera)")
    p = presets[name]
    height = float(np.ptp(joints[..., 1]) or 1.0)
    forward = forward_direction(joints[:, 0], height)
    left = np.cross(UP, forward)
    follow = p.get("track", "fixed") == "follow"
    root = joints[:, 0].copy()
    if follow:
        from scipy.ndimage import uniform_filter1d

        fps = (len(times) - 1) / max(float(times[-1] - times[0]), 1e-9) if len(times) > 1 else 1.0
        window = max(int(round(float(p.get("smooth", 0.5)) * fps)), 1)
        root = uniform_filter1d(root, window, axis=0, mode="nearest")
        local = joints - root[:, None] * np.array([1.0, 0.0, 1.0])
    else:
        local = joints
    boxed = local if frame is None else local[:, np.asarray(frame, dtype=np.int64)]
    lo, hi = boxed.reshape(-1, 3).min(axis=0) - pad, boxed.reshape(-1, 3).max(axis=0) + pad
    corners = np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), axis=-1).reshape(-1, 3)
    centre = 0.5 * (lo + hi)
    azimuth = np.radians(float(p.get("azimuth", 90)) + float(p.get("orbit", 0.0)) * (times - times[0]))
    elevation = np.radians(min(float(p.get("elevation", 0.0)), 89.9))
    back = (np.cos(elevation) * (np.cos(azimuth)[:, None] * forward + np.sin(azimuth)[:, None] * left)
            + np.sin(elevation) * UP)
    yfov = math.radians(float(p.get("yfov", 35.0)))
    up_hint = np.where(abs(float(p.get("elevation", 0.0))) >= 89.0, forward, UP)
    distance = _fit_distance(corners - centre, back, up_hint, yfov, aspect, float(p.get("margin", 0.06)))
    target = centre + (root * np.array([1.0, 0.0, 1.0]) if follow else 0.0)
    target = np.broadcast_to(target, back.shape)
    eye = target + distance[:, None] * back
    return CameraTrack(look_at(eye, target, np.broadcast_to(up_hint, back.shape)), yfov,
                       znear=max(0.01, float(distance.min() - np.linalg.norm(hi - lo)) * 0.5),
                       zfar=float(distance.max() + 10 * np.linalg.norm(hi - lo) + 100.0))


def _fit_distance(points: np.ndarray, back: np.ndarray, up_hint: np.ndarray, yfov: float, aspect: float,
                  margin: float) -> np.ndarray:
    """Smallest distance ``(N,)`` along each ``back (N, 3)`` at which ``points`` (relative to
    the target) fit the view with ``margin`` free at each border."""
    right = np.cross(up_hint, back)
    right /= np.linalg.norm(right, axis=-1, keepdims=True)
    up = np.cross(back, right)
    ty = math.tan(yfov / 2) * (1 - 2 * margin)
    tx = ty * aspect
    x, y, z = (np.einsum("pi,ni->np", points, a) for a in (right, up, back))
    return np.maximum(z + np.abs(x) / tx, z + np.abs(y) / ty).max(axis=1)


def usd_camera_track(spec: str, times: np.ndarray) -> CameraTrack:
    """Poses of the camera in a USD file at ``times (N,)`` seconds (stage time = seconds ×
    timeCodesPerSecond), converted to render space (metres, Y up).

    Raises:
        InputError: naming the camera file: not USD, no camera, or a camera whose
            transform, field of view or clipping range is unusable (USD's own
            diagnostics become usdmotion warnings).
    """
    match = _USD_CAMERA.match(spec)
    path, prim_path = Path(match["file"]), match["prim"]
    if not path.is_file():
        raise InputError(path, "no such camera file")
    with usd_diagnostics(path), np.errstate(all="ignore"):  # a degenerate camera is refused below
        try:
            track = _usd_camera_track(path, prim_path, times)
        except (TypeError, ValueError, IndexError, ZeroDivisionError) as exc:
            raise InputError(path, f"unusable camera ({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
    ok = (bool(np.all(np.abs(track.poses) <= MAX_ABS_VALUE)) and 0 < track.yfov < math.pi
          and 0 < track.znear < track.zfar <= MAX_ABS_VALUE)  # the renderer works in float32
    if not ok:
        raise InputError(path, "the camera's transform, field of view or clipping range is not usable "
                               f"(fov {math.degrees(track.yfov):.3g} deg, clipping {track.znear:.3g}..{track.zfar:.3g} m)")
    return track


def _usd_camera_track(path: Path, prim_path: str | None, times: np.ndarray) -> CameraTrack:
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise InputError(path, "cannot open as USD")
    if prim_path:
        prim = stage.GetPrimAtPath(prim_path)
        if not prim or not prim.IsA(UsdGeom.Camera):
            raise InputError(path, f"no Camera prim at {prim_path}")
    else:
        prim = next((p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)), None)
        if prim is None:
            raise InputError(path, "the stage has no Camera prim")
    camera = UsdGeom.Camera(prim)
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    z_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    tcps = float(stage.GetTimeCodesPerSecond() or 24.0)
    poses, fovs = [], []
    for t in times:  # one USD query per frame: the USD API's unit
        gf = camera.GetCamera(Usd.TimeCode(float(t) * tcps))
        poses.append(np.array(gf.transform).T)
        fovs.append(gf.GetFieldOfView(Gf.Camera.FOVVertical))
    poses = np.stack(poses)
    rot = poses[:, :3, :3] / np.linalg.norm(poses[:, :3, :3], axis=1, keepdims=True)
    out = np.zeros_like(poses)
    turn = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]) if z_up else np.eye(3)
    out[:, :3, :3] = turn @ rot
    out[:, :3, 3] = (turn @ poses[:, :3, 3, None])[..., 0] * mpu
    out[:, 3, 3] = 1.0
    near, far = camera.GetClippingRangeAttr().Get() or Gf.Vec2f(0.1, 10000)
    return CameraTrack(out, math.radians(float(fovs[0])), znear=max(float(near) * mpu, 1e-3),
                       zfar=float(far) * mpu)


def project(points: np.ndarray, pose: np.ndarray, yfov: float, width: int, height: int) -> np.ndarray:
    """Pixel coordinates ``(..., 2)`` (x right, y down, pixel centres at +0.5) of world points."""
    view = np.linalg.inv(pose)
    cam = points @ view[:3, :3].T + view[:3, 3]
    f = (height / 2) / math.tan(yfov / 2)
    x = width / 2 + f * cam[..., 0] / -cam[..., 2]
    y = height / 2 - f * cam[..., 1] / -cam[..., 2]
    return np.stack([x, y], axis=-1)


def project_frames(points: np.ndarray, poses: np.ndarray, yfov: float, width: int, height: int) -> np.ndarray:
    """Pixel coordinates ``(N, P, 2)`` of points ``(N, P, 3)`` seen by cameras ``poses (N, 4, 4)``
    (one per frame; as :func:`project`)."""
    rotation, eye = poses[:, :3, :3], poses[:, :3, 3]
    cam = np.einsum("npi,nij->npj", points - eye[:, None], rotation)  # world → camera axes
    f = (height / 2) / math.tan(yfov / 2)
    depth = np.minimum(cam[..., 2], -1e-9)
    return np.stack([width / 2 + f * cam[..., 0] / -depth, height / 2 - f * cam[..., 1] / -depth], axis=-1)

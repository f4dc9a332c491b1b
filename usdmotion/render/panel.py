"""Plot strip under the picture (``render --panel angle:knee_left,speed:RightHand``): one row
per series over the rendered time range, units on the axes, and a cursor at the current
time that moves linearly with it.

Series: ``angle:NAME`` (degrees; any ``--angle`` name, values from
:mod:`usdmotion.render.angles`, i.e. analyze's bend) and ``speed:JOINT`` (m/s; the norm of
:func:`usdmotion.ops.analyse.analyse`'s filtered velocity, analyze's ``speed`` column). The
strip is drawn once (Pillow) from every source frame of the range; each output frame
copies it and draws the cursor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.motion import Motion
from usdmotion.ops.analyse import analyse
from usdmotion.render.angles import angle_values, parse_angle
from usdmotion.render.overlay import _font
from usdmotion.render.space import render_joints

KINDS = {"angle": "deg", "speed": "m/s"}
CURSOR = (220, 30, 30)
SERIES_COLORS = ((20, 110, 200), (20, 150, 60), (160, 60, 170), (200, 120, 0))
BACKGROUND, INK, GRID = (250, 250, 250), (40, 40, 40), (215, 215, 215)


@dataclass(frozen=True)
class Series:
    """One plotted quantity: ``values (N,)`` at the output frames, its label and unit."""

    label: str
    unit: str
    values: np.ndarray


def parse_panel(text: str) -> list[tuple[str, str]]:
    """``"angle:knee_left,speed:RightHand"`` → ``[("angle", "knee_left"), ("speed", "RightHand")]``.

    Three-joint angles are written with ``+``: ``angle:LeftUpLeg+LeftLeg+LeftFoot``.
    """
    items = []
    for part in (p.strip() for p in text.split(",")):
        kind, _, name = part.partition(":")
        if kind not in KINDS or not name:
            raise UsdMotionError(f"--panel {part!r}: use angle:NAME or speed:JOINT, comma-separated "
                                 "(e.g. angle:knee_left,speed:RightHand)")
        items.append((kind, name.replace("+", ",")))
    if not 1 <= len(items) <= 4:
        raise UsdMotionError(f"--panel: 1 to 4 series, got {len(items)}")
    return items


def panel_series(motion: Motion, items: list[tuple[str, str]], frames: np.ndarray) -> list[Series]:
    """The values of every series at the output ``frames (N,)``."""
    out = []
    kin = None
    for kind, name in items:
        if kind == "angle":
            spec = parse_angle(motion, name)

            values = angle_values([spec], render_joints(motion, frames), np.array([0.0, 1.0, 0.0]))[:, 0]
            out.append(Series(f"{spec.name} (deg)", "deg", values))
        else:
            try:
                joint = motion.joint_index(name)
            except KeyError as exc:
                raise UsdMotionError(f"--panel speed:{name}: {exc.args[0]}") from None
            if kin is None:
                if motion.n_frames < 2:
                    raise UsdMotionError("--panel speed needs at least 2 frames")
                kin = analyse(motion)
            speed = np.linalg.norm(kin.velocities[:, joint], axis=-1)
            out.append(Series(f"{name} speed (m/s)", "m/s", speed[frames]))
    return out


def strip_height(height: int, count: int) -> int:
    """Pixel rows of the strip for ``count`` series under a picture ``height`` tall (even)."""
    return 2 * int(round(height * min(0.2 + 0.08 * (count - 1), 0.45) / 2))


class PlotStrip:
    """The strip image ``(h, w, 3)`` and the cursor's column at each output frame."""

    def __init__(self, series: list[Series], times: np.ndarray, width: int, height: int,
                 cursor_times: np.ndarray | None = None):
        """``series`` sampled at ``times (M,)`` s; the cursor at ``cursor_times (N,)`` s (default: ``times``)."""
        from PIL import Image, ImageDraw

        self.times = times
        font = _font(max(10, height // (7 * len(series)) if len(series) > 1 else height // 8))
        canvas = Image.new("RGB", (width, height), BACKGROUND)
        pen = ImageDraw.Draw(canvas)
        left = int(pen.textlength("-000.0", font=font)) + 14
        right = width - 12
        self.x0, self.x1 = left, right
        rows = len(series)
        row_h = height / rows
        t0, t1 = float(times[0]), float(times[-1]) if len(times) > 1 else float(times[0]) + 1.0
        self.span = (t0, t1)
        x = left + (times - t0) / max(t1 - t0, 1e-12) * (right - left)
        self.rows = []
        for k, s in enumerate(series):
            top, bottom = int(k * row_h + 6), int((k + 1) * row_h - (18 if k == rows - 1 else 6))
            finite = s.values[np.isfinite(s.values)]
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
            if hi - lo < 1e-9:
                lo, hi = lo - 1.0, hi + 1.0
            pad = 0.08 * (hi - lo)
            lo, hi = lo - pad, hi + pad
            y = bottom - (s.values - lo) / (hi - lo) * (bottom - top)
            pen.rectangle([left, top, right, bottom], outline=GRID)
            for v in (lo + pad, hi - pad):
                yy = bottom - (v - lo) / (hi - lo) * (bottom - top)
                pen.line([left, yy, right, yy], fill=GRID)
                pen.text((4, yy - font.size / 2), f"{v:.1f}", fill=INK, font=font)
            pen.text((left + 6, top + 1), s.label, fill=SERIES_COLORS[k % 4], font=font)
            points = [(float(a), float(b)) for a, b in zip(x, y) if np.isfinite(b)]
            if len(points) > 1:
                pen.line(points, fill=SERIES_COLORS[k % 4], width=2)
            self.rows.append((top, bottom))
        pen.text((left, height - 16), f"{t0:.2f} s", fill=INK, font=font)
        end = f"{t1:.2f} s   time (s)"
        pen.text((right - pen.textlength(end, font=font), height - 16), end, fill=INK, font=font)
        self.image = np.asarray(canvas).copy()
        cursor = times if cursor_times is None else cursor_times
        self.columns = np.rint(left + (cursor - t0) / max(t1 - t0, 1e-12) * (right - left)).astype(np.int64)

    def frame(self, i: int) -> np.ndarray:
        """The strip with the cursor at output frame ``i``."""
        out = self.image.copy()
        c = int(self.columns[i])
        out[2:-18, max(c - 1, 0):c + 1] = CURSOR
        return out

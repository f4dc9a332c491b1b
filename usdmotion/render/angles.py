"""Joint angles drawn on the picture (``render --angle``): an arc at the joint and the value.

An angle is named by a role (``knee_left``, ``left_knee``, ``elbow_right``, ``hip_left``,
``shoulder_right``, ``ankle_left``, ``wrist_right``: joints found by
:func:`usdmotion.ops.segment.roles.find_roles`), ``trunk`` (lean of the root → chest line from
vertical), or three joint names ``A,B,C`` (the angle at ``B``).

Values are :func:`usdmotion.ops.analyse.measures.bend_angles` of the world positions, so they are
``usdmotion analyze``'s ``bend`` column: 0° = straight, e.g. knee flexion; for a role the
bones are those of analyze's own bend triple at that joint. Everything is computed for all
output frames at once; drawing is 2-D (Pillow) on the rendered image. The text drawn on
every frame is also kept per frame for the sidecar JSON (:func:`write_sidecar`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.io.atomic import atomic_output
from usdmotion.motion import Motion
from usdmotion.ops.analyse.measures import bend_angles, bend_triples
from usdmotion.ops.segment.roles import find_roles
from usdmotion.render.output import is_video
from usdmotion.render.overlay import _font

ROLE_WORDS = ("knee", "elbow", "hip", "shoulder", "ankle", "wrist")
COLORS = ((255, 214, 10), (0, 200, 255), (120, 255, 120), (255, 120, 220))


@dataclass(frozen=True)
class AngleSpec:
    """One angle: its name, the joint at its vertex and the two joints its bones point to.

    ``joints``: ``(vertex, proximal, distal)`` indices; for ``trunk`` ``(root, chest, -1)``.
    """

    name: str
    joints: tuple[int, int, int]
    trunk: bool = False


def parse_angle(motion: Motion, text: str) -> AngleSpec:
    """The :class:`AngleSpec` of one ``--angle`` value (see the module notes).

    Raises:
        UsdMotionError: an unknown name, a joint that is not in the motion, or a joint
            without a defined bend (a root, a leaf, a branching joint).
    """
    text = text.strip()
    if "," in text:
        names = [n.strip() for n in text.split(",")]
        if len(names) != 3:
            raise UsdMotionError(f"--angle {text!r}: give three joint names A,B,C (the angle at B)")
        try:
            a, b, c = (motion.joint_index(n) for n in names)
        except KeyError as exc:
            raise UsdMotionError(f"--angle {text!r}: {exc.args[0]}") from None
        return AngleSpec(text, (b, a, c))
    key = text.lower()
    if key == "trunk":
        roles = find_roles(motion)
        return AngleSpec("trunk", (roles["root"], roles["chest"], -1), trunk=True)
    parts = key.split("_")
    side = next((p for p in parts if p in ("left", "right")), None)
    word = next((p for p in parts if p in ROLE_WORDS), None)
    if side is None or word is None or len(parts) != 2:
        raise UsdMotionError(f"--angle {text!r}: unknown angle (use knee_left, elbow_right, hip_left, "
                             "shoulder_right, ankle_left, wrist_right, trunk, or three joint names A,B,C)")
    joint = find_roles(motion)[f"{side}_{word}"]
    triples = bend_triples(motion)
    row = np.flatnonzero(triples[:, 0] == joint)
    if not len(row):
        raise UsdMotionError(f"--angle {text!r}: joint {motion.joint_names[joint]} has no bend angle "
                             "(a root, a leaf or a branching joint)")
    j, before, after = (int(v) for v in triples[row[0]])
    return AngleSpec(f"{word}_{side}", (j, before, after))


def angle_values(specs: list[AngleSpec], positions: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Angles ``(N, K)`` in degrees at world positions ``positions (N, J, 3)``.

    Bends through :func:`usdmotion.ops.analyse.measures.bend_angles` (analyze's ``bend``); the trunk
    as the angle between root → chest and ``up (3,)``.
    """
    out = np.empty((positions.shape[0], len(specs)))
    bends = [k for k, s in enumerate(specs) if not s.trunk]
    if bends:
        triples = np.array([specs[k].joints for k in bends])
        values = bend_angles(positions, triples, positions.shape[1])
        out[:, bends] = values[:, triples[:, 0]]
    for k, s in enumerate(specs):
        if s.trunk:
            line = positions[:, s.joints[1]] - positions[:, s.joints[0]]
            cos = line @ up / np.maximum(np.linalg.norm(line, axis=-1), 1e-300)
            out[:, k] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def label(spec: AngleSpec, value: float) -> str:
    """The text drawn for an angle: ``knee_left 34.5°``."""
    return f"{spec.name} {value:.1f}°" if np.isfinite(value) else f"{spec.name} –"


class AngleOverlay:
    """Arcs and values of ``specs`` on every output frame of one view.

    ``points``: ``(N, K, 3, 2)`` pixel positions of each angle's vertex, proximal and
    distal point (render-space joints projected with the view's camera).
    """

    def __init__(self, specs: list[AngleSpec], values: np.ndarray, points: np.ndarray, height: int):
        self.specs, self.values, self.points = specs, values, points
        self.radius = max(10, height // 18)
        self.records: list[dict] = []

    def draw(self, image: np.ndarray, i: int) -> None:
        """Draw frame ``i``'s arcs and labels into ``image (H, W, 3) uint8`` in place; record the texts.

        Labels are laid out first (to the right of the joint, else to its left, below any
        label already placed); then only the rectangle holding all arcs and labels is
        converted for Pillow (a 720p frame costs a few milliseconds less)."""
        from PIL import Image, ImageDraw

        height, width = image.shape[:2]
        probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        font = _font(max(14, height // 30))
        r = self.radius
        record, taken, shapes = {}, [], []
        for k, spec in enumerate(self.specs):
            vertex, a, b = self.points[i, k]
            text = label(spec, float(self.values[i, k]))
            # the angle is between "straight on" (the incoming bone extended; the vertical for
            # the trunk) and the outgoing bone: the arc spans exactly the value shown
            straight, bone = (np.array([0.0, -1.0]), a - vertex) if spec.trunk else (vertex - a, b - vertex)
            rays = [d / max(float(np.linalg.norm(d)), 1e-9) for d in (straight, bone)]
            start, end = (math.degrees(math.atan2(d[1], d[0])) for d in rays)
            if (end - start) % 360.0 > 180.0:
                start, end = end, start
            spot = [float(vertex[0] + 1.5 * r), float(vertex[1] - 0.5 * r)]
            bbox = probe.textbbox(tuple(spot), text, font=font)
            if bbox[2] > width - 4:  # no room on the right: left of the joint
                spot[0] = float(vertex[0] - 1.5 * r - (bbox[2] - bbox[0]))
            spot = [min(max(spot[0], 4.0), width - 4.0 - (bbox[2] - bbox[0])),
                    min(max(spot[1], 4.0), height - 4.0 - (bbox[3] - bbox[1]))]
            bbox = probe.textbbox(tuple(spot), text, font=font)
            while any(bbox[0] < t[2] and t[0] < bbox[2] and bbox[1] < t[3] + 4 and t[1] < bbox[3] + 4 for t in taken):
                spot[1] += bbox[3] - bbox[1] + 6  # below the labels already placed
                bbox = probe.textbbox(tuple(spot), text, font=font)
            taken.append(bbox)
            shapes.append((COLORS[k % len(COLORS)], vertex, rays, start, end, spot, bbox, text))
            record[spec.name] = {"value": round(float(self.values[i, k]), 3), "text": text,
                                 "vertex_px": [round(float(vertex[0]), 2), round(float(vertex[1]), 2)],
                                 "label_box": [int(v) for v in bbox], "label_at": [round(v, 2) for v in spot],
                                 "arc_radius_px": r}
        self.records.append(record)
        reach = 1.5 * r + 4
        boxes = np.array([[s[1][0] - reach, s[1][1] - reach, s[1][0] + reach, s[1][1] + reach] for s in shapes]
                         + [[t[0] - 5, t[1] - 4, t[2] + 5, t[3] + 4] for t in taken])
        x0, y0 = (max(int(v), 0) for v in boxes[:, :2].min(axis=0))
        x1, y1 = min(int(boxes[:, 2].max()) + 1, width), min(int(boxes[:, 3].max()) + 1, height)
        if x1 <= x0 or y1 <= y0:
            return
        canvas = Image.fromarray(np.ascontiguousarray(image[y0:y1, x0:x1]))
        pen = ImageDraw.Draw(canvas)
        shift = np.array([x0, y0], float)
        for color, vertex, rays, start, end, spot, bbox, text in shapes:
            v = vertex - shift
            for d, line_width in zip(rays, (max(1, r // 12), max(2, r // 8))):
                pen.line([tuple(v), tuple(v + 1.4 * r * d)], fill=color, width=line_width)
            pen.arc([v[0] - r, v[1] - r, v[0] + r, v[1] + r], start, end, fill=color, width=max(2, r // 6))
            pen.rectangle([bbox[0] - 3 - x0, bbox[1] - 2 - y0, bbox[2] + 3 - x0, bbox[3] + 2 - y0], fill=(20, 20, 20))
            pen.text((spot[0] - x0, spot[1] - y0), text, fill=color, font=font)
        image[y0:y1, x0:x1] = np.asarray(canvas)


def sidecar_path(output: Path) -> Path:
    """``walk.mp4`` → ``walk.angles.json``; ``frames/####.png`` → ``frames/angles.json``."""
    return output.with_suffix(".angles.json") if is_video(output) else output.parent / "angles.json"


def write_sidecar(path: Path, plan, overlay: AngleOverlay) -> None:
    """The per-frame angle values and drawn texts as JSON, written atomically."""
    frames = [{"index": i, "source_frame": int(plan.frames[i]), "time": round(float(plan.times[i]), 6),
               "angles": record} for i, record in enumerate(overlay.records)]
    data = {"unit": "deg", "definition": "bend: 0 = straight (usdmotion analyze's bend); trunk: from vertical",
            "angles": [s.name for s in overlay.specs], "frames": frames}
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1, ensure_ascii=False))

"""Soft contact shadow: a dark disc on the ground under the body, opaque in the middle and
fading to nothing at its rim (per-vertex alpha), that follows the body's horizontal centre
and shrinks as the body rises (a jump lifts it off its shadow). One small transparent mesh,
drawn with pyrender's unlit shader (``usdmotion_shader``, see :mod:`usdmotion.render.gl`): the lit one cost about 4 ms
of CPU a 720p frame on llvmpipe for a black disc.
"""

from __future__ import annotations

import numpy as np

from usdmotion.render.gl import DynamicMesh
from usdmotion.render.scene import material

SEGMENTS = 40
DARKNESS = 0.42  # alpha at the centre


def disc(segments: int = SEGMENTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit disc in the XZ plane: ``(vertices (1 + 2S, 3), faces, alpha (1 + 2S,))``; centre,
    a ring at half the radius, the rim."""
    angle = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(angle), np.zeros(segments), np.sin(angle)], axis=-1)
    vertices = np.concatenate([np.zeros((1, 3)), 0.55 * ring, ring])
    k = np.arange(segments)
    n = (k + 1) % segments
    inner = np.stack([np.zeros(segments, int), 1 + n, 1 + k], axis=1)
    outer = np.concatenate([np.stack([1 + k, 1 + n, 1 + segments + k], 1),
                            np.stack([1 + n, 1 + segments + n, 1 + segments + k], 1)])
    alpha = np.concatenate([[DARKNESS], np.full(segments, 0.7 * DARKNESS), np.zeros(segments)])
    return vertices, np.concatenate([inner, outer]), alpha


class ContactShadow:
    """The shadow mesh; :meth:`update` places it for one frame's joints (render space)."""

    def __init__(self, radius: float, ground: float, rest_height: float):
        self.unit, faces, alpha = disc()
        self.radius, self.ground, self.rest_height = radius, ground + 0.002, rest_height
        colors = np.c_[np.zeros((len(alpha), 3)), alpha].astype(np.float32)
        normals = np.tile([0.0, 1.0, 0.0], (len(self.unit), 1))
        self.normals = normals
        self.dynamic = DynamicMesh(self.unit * radius, normals, faces, material((1.0, 1.0, 1.0, 0.99)),
                                   colors=colors)
        self.dynamic.primitive.usdmotion_shader = "unlit"  # black: no lighting to compute per pixel

    def placement(self, joints: np.ndarray) -> np.ndarray:
        """Vertices ``(V, 3)`` under joints ``(J, 3)``: centred on their horizontal mean, radius
        shrinking to half as the lowest joint rises one rest height above the ground."""
        centre = joints.mean(axis=0)
        lift = max(float(joints[:, 1].min()) - self.ground, 0.0)
        scale = self.radius * max(0.5, 1.0 - 0.5 * lift / max(self.rest_height, 1e-9))
        out = self.unit * scale
        out[:, 0] += centre[0]
        out[:, 2] += centre[2]
        out[:, 1] = self.ground
        return out

    def update(self, joints: np.ndarray) -> None:
        self.dynamic.update(self.placement(joints), self.normals)

"""Trajectory traces (``render --trace NAME``): the path of a joint or of the body's centre of
mass as a tube, in render space (metres, Y up). One implementation for the video
(:class:`usdmotion.render.views.Views`) and the stroboscope still (:mod:`usdmotion.render.strobe`).
"""

from __future__ import annotations

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.motion import Motion
from usdmotion.render.scene import COLORS, to_render_space, tube_mesh

#: ``--trace`` names of the centre of mass.
COM_NAMES = ("com", "centre_of_mass", "center_of_mass")


def is_com(name: str) -> bool:
    """True if ``--trace name`` means the centre of mass."""
    return name.lower() in COM_NAMES


def check_traces(motion: Motion, names) -> None:
    """Refuse a ``--trace`` name that is neither ``com`` nor a joint of ``motion`` (``UsdMotionError``)."""
    for name in names:
        if not is_com(name):
            try:
                motion.joint_index(name)
            except KeyError as exc:
                raise UsdMotionError(f"--trace: {exc.args[0]}") from None


def trace_path(motion: Motion, name: str, frames: np.ndarray, joints: np.ndarray, body=None) -> np.ndarray:
    """The path ``(N, 3)`` (metres, render space) of joint ``name`` or of the centre of mass
    (``com``) at source ``frames (N,)``; ``joints (N, J, 3)``: the joints at those frames in
    render space; ``body``: the :class:`usdmotion.skin.Body` whose volume the centre of mass
    is of (default: the generated body at a low resolution)."""
    check_traces(motion, [name])
    if not is_com(name):
        return joints[:, motion.joint_index(name)]
    from usdmotion.skin import build_body, centre_of_mass

    body = build_body(motion, resolution=48) if body is None else body
    return to_render_space(centre_of_mass(motion, body, frames), motion.meters_per_unit, motion.up_axis)


def trace_meshes(motion: Motion, names, frames: np.ndarray, joints: np.ndarray, distance: float,
                 body=None) -> list:
    """One tube mesh per ``--trace`` name (colours ``COLORS["traces"]`` in order), ``distance``
    (metres) from the camera: the tube's radius is 0.15 % of it, at least 3 mm."""
    colors = COLORS["traces"]
    return [tube_mesh(trace_path(motion, name, frames, joints, body), max(0.0015 * distance, 0.003),
                      colors[k % len(colors)]) for k, name in enumerate(names)]

"""Motion equaliser: multiresolution filtering after Bruderlin & Williams (1995).

Each degree of freedom is a 1-D signal ``G_0``. The à-trous pyramid smooths it with the
kernel ``w = [1/16, 1/4, 3/8, 1/4, 1/16]`` dilated by ``2^k`` at level ``k``:
``G_{k+1}(i) = Σ_m w(m) G_k(i + 2^k m)``. Band ``L_k = G_k − G_{k+1}`` (band 0 holds the
highest frequencies, about ``fps/4 .. fps/2``; band ``k`` about ``fps/2^(k+2) .. fps/2^(k+1)``),
and ``G_0 = G_K + Σ_k L_k``. The equalised signal is ``G_K + Σ_k g_k L_k``.

What the original got wrong, and what is done here instead:

* Borders: their filter read past the ends of the signal into zeros, pulling both ends
  towards 0. Here the signal is extended by point reflection about its first and last
  samples (``x[−i] = 2x[0] − x[i]``): constants and straight-line trends (a root walking
  at constant speed) pass unchanged, and the first and last frames keep their values.
  (Mirroring, ``x[−i] = x[i]``, would bend a trend into a V and pull a walking root's
  end back by ~0.4 units on a CMU walk.)
* Rotations: filtering Euler angles jumps where an angle wraps at ±180°. Here each
  joint's quaternions are made sign-continuous, a smooth reference rotation ``r(t)`` is
  taken (cubic spline through block means, below every edited band), and the pyramid
  runs on the rotation vector ``d(t) = log(r(t)⁻¹ q(t))`` (unwrapped: angle up to 2π),
  which is continuous wherever the rotation is. ``q' = r · exp(d')``.
"""

from __future__ import annotations

import math

import numpy as np

from usdmotion import quat_planes as Q
from usdmotion.motion import Motion
from usdmotion.ops.edit._common import EditError, animated_translation_joints, rebuild, select_joints

KERNEL = (1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0)

#: Presets: ``(low_hz, high_hz, gain)`` rules; a band whose centre frequency lies in
#: ``[low_hz, high_hz)`` gets ``gain`` (the last matching rule wins), others 1. Defined in
#: hertz so that a preset means the same at 30 and 120 fps.
PRESETS: dict[str, tuple[tuple[float, float, float], ...]] = {
    # remove capture noise: bands centred above 16 Hz off, 8-16 Hz halved (movement lives below)
    "denoise": ((8.0, math.inf, 0.5), (16.0, math.inf, 0.0)),
    # raise the middle bands: a smoother but more pronounced movement (paper: "exaggerated walk")
    "exaggerate": ((0.7, 6.0, 1.6),),
    # the middle bands down: a damped, restricted movement (the paper got it by raising the
    # low bands, i.e. the same balance between low and middle bands)
    "damp": ((0.7, 6.0, 0.6),),
    # raise the high bands: nervous twitching, hand-held-camera jitter
    "jitter": ((4.0, 8.0, 2.0), (8.0, math.inf, 4.0)),
}


def max_bands(n_frames: int) -> int:
    """Largest number of bands for ``n_frames`` (the widest kernel must fit the signal)."""
    if n_frames < 3:
        return 0
    return max(0, int(math.floor(math.log2(n_frames - 1))))


def band_frequencies(fps: float, n_bands: int) -> np.ndarray:
    """Nominal centre frequency (Hz) of each band: ``fps / 2^(k + 1.5)``."""
    return fps / 2.0 ** (np.arange(n_bands) + 1.5)


def preset_gains(preset: str, fps: float, n_frames: int) -> list[float]:
    """Band gains of a preset for a motion sampled at ``fps`` with ``n_frames`` frames."""
    if preset not in PRESETS:
        raise EditError(f"unknown equaliser preset {preset!r} (choose from {', '.join(PRESETS)})")
    centres = band_frequencies(fps, max_bands(n_frames))
    gains = np.ones_like(centres)
    for low, high, gain in PRESETS[preset]:
        gains[(centres >= low) & (centres < high)] = gain
    return [float(g) for g in gains]


def _index(axis: int, sl: slice) -> tuple:
    return (slice(None),) * axis + (sl,)


def atrous_level(x: np.ndarray, level: int, axis: int = 0) -> np.ndarray:
    """One à-trous smoothing step ``G_{k+1}`` of ``G_k = x`` at ``level`` k.

    Past the ends the signal is point-reflected (``x[−i] = 2x[0] − x[i]``); the interior
    is computed from slices of ``x`` directly, only the borders from a padded copy.
    """
    n = x.shape[axis]
    step = 1 << level
    a, b, c = KERNEL[2], KERNEL[1], KERNEL[0]
    out = np.empty_like(x, dtype=np.float64)
    reach = 2 * step
    if n > 2 * reach:  # interior: i ± 2·step inside the signal
        inner = _index(axis, slice(reach, n - reach))
        sl = lambda lo: x[_index(axis, slice(lo, lo + n - 2 * reach))]  # noqa: E731
        acc = out[inner]
        np.add(sl(0), sl(4 * step), out=acc)
        acc *= c
        near = sl(step) + sl(3 * step)
        near *= b
        acc += near
        acc += a * x[inner]
        edges = [(0, reach), (n - reach, n)]
    else:
        edges = [(0, n)]
    pad = [(0, 0)] * x.ndim
    pad[axis] = (reach, reach)
    for lo, hi in edges:  # borders: from a padded piece of the signal
        src_lo, src_hi = max(0, lo - 2 * reach), min(n, hi + 2 * reach)
        piece = x[_index(axis, slice(src_lo, src_hi))]
        padded = np.pad(piece, [(0, 0)] * axis + [(reach if src_lo == 0 else 0, reach if src_hi == n else 0)]
                        + [(0, 0)] * (x.ndim - axis - 1), mode="reflect", reflect_type="odd")
        start = lo - src_lo + (reach if src_lo == 0 else 0)  # position of x[lo] in padded
        width = hi - lo
        tap = lambda k: padded[_index(axis, slice(start + k * step, start + k * step + width))]  # noqa: E731
        out[_index(axis, slice(lo, hi))] = c * (tap(-2) + tap(2)) + b * (tap(-1) + tap(1)) + a * tap(0)
    return out


def atrous_bands(x: np.ndarray, n_bands: int, axis: int = 0) -> tuple[list[np.ndarray], np.ndarray]:
    """Bands ``[L_0, ..., L_{K-1}]`` and the remainder ``G_K`` of a signal along ``axis``."""
    _check_bands(x.shape[axis], n_bands)
    bands, g = [], np.asarray(x, dtype=np.float64)
    for k in range(n_bands):
        smoother = atrous_level(g, k, axis)
        bands.append(g - smoother)
        g = smoother
    return bands, g


def _check_bands(n_frames: int, n_bands: int) -> None:
    limit = max_bands(n_frames)
    if n_bands > limit:
        raise EditError(f"{n_bands} equaliser bands need at least {2 ** n_bands + 1} frames; "
                        f"this motion has {n_frames} (at most {limit} bands)")


def equalize_signal(x: np.ndarray, gains, axis: int = 0) -> np.ndarray:
    """``G_K + Σ_k g_k L_k`` of ``x`` along ``axis`` for gains ``g_0..g_{K-1}``.

    Computed as ``Σ_k (g_k − g_{k−1}) G_k`` (``g_{−1} = 0``, ``g_K = 1``), so levels past
    the last gain that differs from 1 are never built (they would cancel exactly).
    """
    gains = [float(g) for g in gains]
    needed = max((k + 1 for k, g in enumerate(gains) if g != 1.0), default=0)
    _check_bands(x.shape[axis], len(gains))
    g = np.asarray(x, dtype=np.float64)
    out = gains[0] * g if needed else g.copy()
    previous = gains[0] if needed else 1.0
    for k in range(needed):
        g = atrous_level(g, k, axis)
        coefficient = (gains[k + 1] if k + 1 < needed else 1.0) - previous
        if coefficient != 0.0:
            out += coefficient * g
        previous += coefficient
    return out


def _reference(q: np.ndarray, block: int) -> np.ndarray:
    """Smooth unit quaternions ``(4, F, S)`` near sign-continuous ``q (4, F, S)``.

    A cubic spline through the normalised means of ``block``-frame blocks; a joint that
    turns so fast that a block mean degenerates (norm < 0.25) gets halved blocks.
    """
    from scipy.interpolate import make_interp_spline

    n = q.shape[1]
    ref = np.empty_like(q)
    todo = np.arange(q.shape[2])
    size = max(1, min(block, n // 4))
    while todo.size:
        starts = np.arange(0, n, size)
        counts = np.diff(np.append(starts, n))
        part = q if todo.size == q.shape[2] else q[:, :, todo]
        means = np.add.reduceat(part, starts, axis=1) / counts[None, :, None]
        centres = starts + (counts - 1) / 2.0
        good = (np.sqrt(np.einsum("ibs,ibs->bs", means, means)).min(axis=0) > 0.25) | (size == 1)
        if size == 1:
            values = part
        else:
            spline = make_interp_spline(centres, np.moveaxis(means[:, :, good], 1, 0), k=min(3, len(starts) - 1),
                                        axis=0)
            values = np.moveaxis(spline(np.arange(n, dtype=np.float64)), 0, 1)
        ref[:, :, todo[good]] = Q.normalize(values)
        todo = todo[~good]
        size = max(1, size // 2)
    return ref


def equalize_rotations(rotations: np.ndarray, gains, joints: np.ndarray | None = None) -> np.ndarray:
    """Equalise local rotations ``(F, J, 4)`` wrap-safely (see the module docstring).

    ``joints``: indices to filter (default all); returns a new ``(F, J, 4)`` array.
    """
    joints = np.arange(rotations.shape[1]) if joints is None else np.asarray(joints)
    needed = max((k + 1 for k, g in enumerate(gains) if float(g) != 1.0), default=0)
    _check_bands(rotations.shape[0], len(gains))
    out = np.array(rotations)
    if joints.size == 0:
        return out

    def work(chunk: np.ndarray) -> None:
        q = Q.align_signs(Q.gather_c(rotations, chunk), axis=1)
        r = _reference(q, 2 ** (needed + 1))
        d = equalize_signal(Q.log(Q.mul(Q.conj(r), q)), gains, axis=1)
        Q.scatter_c(out, chunk, Q.mul(r, Q.exp(d)))

    Q.over_chunks(work, joints, rotations.shape[0])
    return out


def equalize(motion: Motion, gains=None, preset: str | None = None, joint: str | None = None,
             subtree: bool = False, translations: bool = True) -> Motion:
    """Equalise a motion: band gains on every rotation (and translation) signal.

    Args:
        gains: gain per band, band 0 first (highest frequencies); bands past the list
            keep gain 1. Exclusive with ``preset``.
        preset: ``"denoise"``, ``"exaggerate"``, ``"damp"`` or ``"jitter"`` (see
            :data:`PRESETS`; gains follow from the fps).
        joint, subtree: act on one joint (or its subtree) only; default the whole body.
        translations: also equalise the root trajectory and animated joint translations
            of the selected joints.
    """
    if (gains is None) == (preset is None):
        raise EditError("equalize needs exactly one of gains or preset")
    if preset is not None:
        gains = preset_gains(preset, motion.fps, motion.n_frames)
    gains = [float(g) for g in gains]
    if not gains or not all(math.isfinite(g) for g in gains):
        raise EditError(f"equaliser gains must be a non-empty list of finite numbers, got {gains}")
    _check_bands(motion.n_frames, len(gains))
    selected = select_joints(motion, joint, subtree)
    # a joint whose rotation never changes is its own equalised signal (the borders reflect
    # through the end values, which keeps constants exactly): skip it
    constant = np.all(motion.rotations == motion.rotations[:1], axis=(0, 2))
    rot_joints = np.flatnonzero(selected & ~motion.end_sites & ~constant)
    rotations = equalize_rotations(motion.rotations, gains, rot_joints)
    root = np.array(motion.root_translation)
    jt = None if motion.joint_translations is None else np.array(motion.joint_translations)
    if translations:
        if selected[0]:
            root = equalize_signal(root, gains, axis=0)
        moving = np.flatnonzero(animated_translation_joints(motion) & selected)
        if moving.size:
            jt[:, moving] = equalize_signal(jt[:, moving], gains, axis=0)
    return rebuild(motion, rotations, root, jt)

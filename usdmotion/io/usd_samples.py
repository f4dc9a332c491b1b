"""A ``SkelAnimation``'s time samples read in bulk and checked: ``(T, J, 4)`` rotations and
``(T, J, 3)`` translations over every frame, one NumPy array per attribute.

Each time sample is copied straight from its ``Vt`` array into a preallocated float32
array through the buffer protocol (no per-joint or per-value Python objects); an
attribute without time samples is read once and broadcast. Times are stage time codes
(USD has already applied layer offsets and scales), so the frame rate is
``timeCodesPerSecond / spacing``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from usdmotion.errors import UsdMotionWarning, UsdReadError

SPACING_TOL = 1e-6   # relative: sample spacings this close to the median count as even
UNIT_TOL = 1e-2      # |‖q‖ - 1| beyond this is a corrupt rotation, not float rounding


def stage_rate(stage, path: Path) -> float:
    """The stage's ``timeCodesPerSecond``, checked positive and finite."""
    tcps = float(stage.GetTimeCodesPerSecond())
    if not (np.isfinite(tcps) and tcps > 0):
        raise UsdReadError(path, f"timeCodesPerSecond must be a positive number, the stage says {tcps}")
    return tcps


def frame_times(anim, path: Path, resample: bool = False) -> tuple[np.ndarray, float]:
    """``(times (T,), step)``: the stage time codes to read as frames and their spacing.

    ``times`` is the union of the animation's time samples (empty: one frame from the
    default values); ``step`` the spacing in time codes (1 for fewer than 2 samples).
    Uneven spacing raises :class:`UsdReadError`, or with ``resample`` is replaced by
    even steps of the median spacing over the same range (USD interpolates).
    """
    if anim is None:
        return np.zeros(0), 1.0
    attrs = (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())
    times = np.unique(np.concatenate([np.asarray(a.GetTimeSamples(), np.float64) for a in attrs]))
    if times.size < 2:
        return times, 1.0
    steps = np.diff(times)
    step = float(np.median(steps))
    uneven = np.abs(steps - step) > SPACING_TOL * step
    if not uneven.any():
        return times, step
    if not resample:
        k = int(np.flatnonzero(uneven)[0])
        raise UsdReadError(path, f"{anim.GetPath()}: time samples are unevenly spaced (step {steps[k]:.6g} at time "
                                 f"{times[k]:.6g}, usually {step:.6g}); resample the animation evenly, or read it "
                                 "with --resample (USD's interpolation at the usual step)")
    count = int(np.floor((times[-1] - times[0]) / step + 1e-9)) + 1
    return times[0] + step * np.arange(count), step


def read_samples(attr, times: np.ndarray, n: int, width: int, path: Path, dtype=np.float32) -> np.ndarray:
    """``attr`` at every time in ``times`` as ``(max(T, 1), n, width)`` of ``dtype``, checked for
    length and finiteness; read once and broadcast (float32, read-only) when it has no time samples."""
    where = str(attr.GetPath())
    if attr.GetNumTimeSamples() == 0 or times.size == 0:
        out = _rows(attr.Get(), n, width, path, where, None)
        return np.broadcast_to(out, (max(times.size, 1), n, width))
    from pxr import Usd

    out = np.empty((times.size, n, width), dtype)
    query = Usd.AttributeQuery(attr)
    if not _copy_samples(query, times, out):
        _raise_first_bad_sample(query, times, n, width, path, where)
    _check_finite(out, path, where, times)
    return out


def _copy_samples(query, times: np.ndarray, out: np.ndarray) -> bool:
    """Copy the value of ``query`` at each of ``times (T,)`` into ``out (T, n, width)`` through the
    buffer protocol (nothing per sample in Python but a shape check and the copy); ``False`` at
    the first value that is not ``(n, width)`` numbers."""
    shape = out.shape[1:]
    try:
        for i, value in enumerate(map(np.asarray, map(query.Get, times.tolist()))):
            if value.shape != shape:
                return False
            out[i] = value
    except (ValueError, TypeError):
        return False
    return True


def _raise_first_bad_sample(query, times: np.ndarray, n: int, width: int, path: Path, where: str) -> None:
    """Raise the error naming the first sample at ``times`` that is not ``n`` ``width``-vectors
    (the slow, exact scan behind :func:`read_samples`'s bulk copy)."""
    for t in times.tolist():
        value = query.Get(t)
        if value is None or len(value) != n:
            raise UsdReadError(path, f"{where} at time {t:g} has {0 if value is None else len(value)} "
                                     f"values for {n} joints")
        try:
            np.asarray(value, np.float32).reshape(n, width)
        except (ValueError, TypeError) as exc:
            raise UsdReadError(path, f"{where} at time {t:g} is not an array of {width}-vectors ({exc})") from None
    raise UsdReadError(path, f"{where}: its time samples cannot be read as arrays of {width}-vectors")


def _rows(value, n: int, width: int, path: Path, where: str, t) -> np.ndarray:
    if value is None or len(value) != n:
        raise UsdReadError(path, f"{where} has {0 if value is None else len(value)} values for {n} joints")
    try:
        out = np.array(value, np.float32).reshape(n, width)
    except (ValueError, TypeError) as exc:
        raise UsdReadError(path, f"{where} is not an array of {width}-vectors ({exc})") from None
    _check_finite(out[None], path, where, np.zeros(1))
    return out


def _check_finite(values: np.ndarray, path: Path, where: str, times: np.ndarray) -> None:
    if values.size == 0 or np.isfinite(values.min()) and np.isfinite(values.max()):  # NaN propagates; no temporaries
        return
    bad = ~np.isfinite(values).all(axis=-1)
    if bad.any():
        f, j = np.argwhere(bad)[0]
        at = f" at time {times[f]:g}" if times.size else ""
        raise UsdReadError(path, f"{where}{at}: value {j} is not finite")


def animation_arrays(anim, tokens: list[str], times: np.ndarray, rest_rotations: np.ndarray,
                     rest_translations: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Local ``(rotations wxyz (T, J, 4) float64, translations (T, J, 3))`` of the skeleton
    joints ``tokens`` over ``times``: the animation's values where it animates a joint,
    the rest transform (``rest_rotations (J, 4)``, ``rest_translations (J, 3)``) elsewhere.
    ``translations`` is float32 as read when the animation animates every joint in order
    (exact in float64; half the memory of a long take's float64 copy), else float64.

    An animation without rotations or translations, or with arrays whose length is not
    its joint count, non-finite values or rotations far from unit length, is refused.
    """
    n_frames, n_joints = max(times.size, 1), len(tokens)
    if anim is None:
        return (np.broadcast_to(rest_rotations, (n_frames, n_joints, 4)).copy(),
                np.broadcast_to(rest_translations, (n_frames, n_joints, 3)).copy())
    anim_joints = anim.GetJointsAttr().Get()
    if anim_joints is None or len(anim_joints) == 0:
        raise UsdReadError(path, f"{anim.GetPath()}: the SkelAnimation names no joints")
    index = {t: j for j, t in enumerate(tokens)}
    pairs = [(a, index[str(t)]) for a, t in enumerate(anim_joints) if str(t) in index]
    if not pairs:
        raise UsdReadError(path, f"{anim.GetPath()}: none of its joints is a joint of the skeleton")
    src, dst = (np.array(x, np.int64) for x in zip(*pairs))
    same_order = len(pairs) == n_joints == len(anim_joints) and np.array_equal(src, dst)
    for attr, name in ((anim.GetRotationsAttr(), "rotations"), (anim.GetTranslationsAttr(), "translations")):
        if not attr.HasValue():
            raise UsdReadError(path, f"{anim.GetPath()}: the SkelAnimation has no {name} "
                                     "(usd-core would show the rest pose)")
    quats, shifts = _rotations_translations(anim, times, len(anim_joints), path)
    wxyz = _wxyz(quats if same_order else quats[:, src])
    del quats
    worst = max((_off_unit(wxyz[k:k + _BLOCK]) for k in range(0, wxyz.shape[0], _BLOCK)), default=0.0)
    if worst > UNIT_TOL:
        norms = _norms(wxyz)
        f, j = np.argwhere(np.abs(norms - 1.0) > UNIT_TOL)[0]
        at = f" at time {times[f]:g}" if times.size else ""
        raise UsdReadError(path, f"{anim.GetRotationsAttr().GetPath()}{at}: rotation of joint "
                                 f"{anim_joints[int(src[j])]} has length {norms[f, j]:.6g}, not a unit quaternion")
    if worst > 1e-6:
        for k in range(0, wxyz.shape[0], _BLOCK):
            wxyz[k:k + _BLOCK] /= _norms(wxyz[k:k + _BLOCK])[..., None]
    if same_order:
        rotations, translations = wxyz, shifts  # float32 as read: float64 only of what the Motion keeps
    else:
        rotations = np.broadcast_to(rest_rotations, (n_frames, n_joints, 4)).copy()
        translations = np.broadcast_to(rest_translations, (n_frames, n_joints, 3)).copy()
        rotations[:, dst] = wxyz
        translations[:, dst] = shifts[:, src]
    _check_scales(anim, times, len(anim_joints), path)
    return rotations, translations


#: Frames per block where a take-sized temporary would otherwise be made.
_BLOCK = 8192


def _norms(wxyz: np.ndarray) -> np.ndarray:
    """``(..., )`` lengths of quaternions ``(..., 4)`` (float64)."""
    out = np.einsum("...i,...i->...", wxyz, wxyz)
    return np.sqrt(out, out=out)


def _off_unit(wxyz: np.ndarray) -> float:
    """``max |‖q‖ - 1|`` over quaternions ``(..., 4)``, from the extreme lengths (0 when empty)."""
    norms = _norms(wxyz)
    return max(float(norms.max()) - 1.0, 1.0 - float(norms.min())) if norms.size else 0.0


def _rotations_translations(anim, times: np.ndarray, n: int, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``(rotations xyzw (T, n, 4) float64, translations (T, n, 3) float32)`` of ``anim`` at
    ``times`` (checked finite): both from one ``UsdSkel.AnimQuery`` call per time when both
    are time-sampled (a third less time than two attribute reads), else, or at the first
    value that is not ``n`` vectors, from :func:`read_samples` (whose scan names it)."""
    rotations, translations = anim.GetRotationsAttr(), anim.GetTranslationsAttr()
    if times.size and rotations.GetNumTimeSamples() and translations.GetNumTimeSamples():
        from pxr import UsdSkel

        quats, shifts = np.empty((times.size, n, 4)), np.empty((times.size, n, 3), np.float32)
        if _copy_components(UsdSkel.Cache().GetAnimQuery(anim), times, quats, shifts):
            _check_finite(quats, path, str(rotations.GetPath()), times)
            _check_finite(shifts, path, str(translations.GetPath()), times)
            return quats, shifts
        del quats, shifts
    return (read_samples(rotations, times, n, 4, path, np.float64), read_samples(translations, times, n, 3, path))


def _copy_components(anim_query, times: np.ndarray, rotations: np.ndarray, translations: np.ndarray) -> bool:
    """Copy the animation's rotations and translations at each of ``times`` into ``rotations
    (T, n, 4)`` and ``translations (T, n, 3)``; ``False`` at the first that is not ``n`` vectors."""
    rotation_shape, translation_shape = rotations.shape[1:], translations.shape[1:]
    try:
        for i, parts in enumerate(map(anim_query.ComputeJointLocalTransformComponents, times.tolist())):
            if not parts:
                return False
            shift, turn = np.asarray(parts[0]), np.asarray(parts[1])
            if turn.shape != rotation_shape or shift.shape != translation_shape:
                return False
            rotations[i], translations[i] = turn, shift
    except (ValueError, TypeError):
        return False
    return True


def _wxyz(xyzw: np.ndarray, block: int = _BLOCK) -> np.ndarray:
    """Float64 wxyz ``(T, J, 4)`` from xyzw quaternions: reordered in place, ``block`` frames at
    a time, when ``xyzw`` is a writable float64 array (no second copy of a long take)."""
    if not (xyzw.dtype == np.float64 and xyzw.flags.writeable and xyzw.flags.c_contiguous):
        out = np.empty(xyzw.shape, np.float64)
        out[..., 0], out[..., 1:] = xyzw[..., 3], xyzw[..., :3]
        return out
    for start in range(0, xyzw.shape[0], block):
        part = xyzw[start:start + block]
        w = part[..., 3].copy()
        part[..., 1:] = part[..., :3].copy()
        part[..., 0] = w
    return xyzw


def _check_scales(anim, times: np.ndarray, n: int, path: Path) -> None:
    import warnings

    attr = anim.GetScalesAttr()
    if not attr.HasValue():
        return
    scales = read_samples(attr, times, n, 3, path)
    scales = scales[:1] if scales.strides[0] == 0 else scales  # one value broadcast over the frames
    worst = max(float(scales.max()) - 1.0, 1.0 - float(scales.min())) if scales.size else 0.0
    if worst > 1e-3:
        warnings.warn(f"{path}: {attr.GetPath()}: joint scales (up to {1 + worst:.4g}) are ignored",
                      UsdMotionWarning, stacklevel=5)


def blend_shape_weights(anim, times: np.ndarray, path: Path) -> tuple[tuple[str, ...], np.ndarray | None]:
    """``(names (S,), weights (max(T, 1), S) float64 or None)``: a SkelAnimation's animated
    blend-shape weights at ``times`` (``blendShapes`` names them; ``None`` when it has none).
    A weights array whose length is not the number of names, or non-finite, is refused."""
    if anim is None:
        return (), None
    names = anim.GetBlendShapesAttr().Get()
    attr = anim.GetBlendShapeWeightsAttr()
    if not names or not attr.HasValue():
        return (), None
    where = str(attr.GetPath())
    values = read_samples_scalar(attr, times, len(names), path, where)
    return tuple(str(n) for n in names), values


def read_samples_scalar(attr, times: np.ndarray, n: int, path: Path, where: str) -> np.ndarray:
    """A float-array attribute at every time in ``times``: ``(max(T, 1), n)`` float64."""
    from pxr import Usd

    if attr.GetNumTimeSamples() == 0 or times.size == 0:
        rows = [attr.Get()]
        at = [None]
    else:
        query = Usd.AttributeQuery(attr)
        at = times.tolist()
        rows = [query.Get(t) for t in at]
    out = np.empty((len(rows), n), np.float64)
    for i, (value, t) in enumerate(zip(rows, at)):
        when = "" if t is None else f" at time {t:g}"
        if value is None or len(value) != n:
            raise UsdReadError(path, f"{where}{when} has {0 if value is None else len(value)} weights for {n} "
                                     "blend shapes")
        out[i] = value
    if not np.isfinite(out).all():
        f = int(np.argwhere(~np.isfinite(out))[0][0])
        raise UsdReadError(path, f"{where}{'' if at[f] is None else f' at time {at[f]:g}'}: a weight is not finite")
    return np.broadcast_to(out, (max(times.size, 1), n)).copy() if len(rows) == 1 else out

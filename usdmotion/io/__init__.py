"""File formats: extension → reader / writer registry.

``read_motion(path, **options)`` and ``write_motion(motion, path, **options)`` dispatch on
the extension; options a format does not use are ignored (e.g. ``root_offset`` for USD).
"""

from __future__ import annotations

import os
from pathlib import Path

from usdmotion.channels import override_units_axis
from usdmotion.constants import MAX_ABS_VALUE
from usdmotion.errors import InputError, OutputError, TopologyError, UsdMotionWarning
from usdmotion.motion import Motion
from usdmotion.units_guess import apply_body_guess

BVH_EXTENSIONS = (".bvh",)
USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
AMC_EXTENSIONS = (".amc",)
GLTF_EXTENSIONS = (".glb", ".gltf")
KNOWN = f".bvh, {', '.join(USD_EXTENSIONS)}, {', '.join(GLTF_EXTENSIONS)}"
READABLE = f"{KNOWN}, {', '.join(AMC_EXTENSIONS)}"


def _kind(path: Path) -> str | None:
    ext = path.suffix.lower()
    if ext in BVH_EXTENSIONS:
        return "bvh"
    if ext in USD_EXTENSIONS:
        return "usd"
    if ext in AMC_EXTENSIONS:
        return "amc"
    if ext in GLTF_EXTENSIONS:
        return "gltf"
    return None


def _is_auto(value) -> bool:
    return isinstance(value, str) and value.strip().lower() == "auto"


def read_motion(path: str | os.PathLike, root_offset: str = "auto", units: str | float | None = None,
                up_axis: str | None = None, lenient: bool = False, ignore_joint_positions: bool = False,
                skeleton: str | os.PathLike | None = None, resample: bool = False) -> Motion:
    """Read a BVH, UsdSkel, glTF 2.0 (.glb/.gltf) or Acclaim AMC file.

    For BVH, ``units`` and ``up_axis`` state what the file does not; by default (``None``)
    both are guessed from the body (:mod:`usdmotion.units_guess`; right on all 34 files of
    the shared data, see ``docs/units_guess.md``), with a warning where the guess is not
    the nominal cm / Y-up, and cm / Y-up kept when the skeleton is not recognisably human;
    ``"auto"`` guesses them too and always states the guess and its reason. For USD and glTF they come from the file (glTF:
    metres, Y up, or the source's where usdmotion wrote it) and, if given (not
    ``"auto"``), override it. For AMC, units come from the ASF unless given.
    ``skeleton`` names the ASF skeleton file of ``.amc`` input (default: the one beside it, see
    :func:`usdmotion.io.amc.find_skeleton`), the Skeleton prim path of a USD stage with several
    skeletons, or the skin (index or name) of a glTF file with several; inputs that cannot take
    it raise ``InputError``. ``resample`` reads a USD animation's unevenly spaced time samples
    at even steps. Whatever the format, a human skeleton whose height in the chosen units is
    outside 0.5–3 m warns.

    Raises:
        InputError: anything wrong with the file, always naming it: besides the readers'
            own errors, an invalid skeleton or frame rate, a NumPy warning or error
            (``invalid value in divide``, a non-converging SVD: the numbers are broken),
            any non-finite or absurd number (beyond ``MAX_ABS_VALUE``) in the motion read,
            and an ``IndexError``, ``KeyError`` or ``TypeError`` of a reader tripping over
            inconsistent content. USD's C++ diagnostics become usdmotion warnings.
    """
    import warnings

    import numpy as np

    path = Path(path)
    try:
        with warnings.catch_warnings(), np.errstate(all="warn"):
            warnings.simplefilter("error", RuntimeWarning)  # NumPy's: the input is numerically broken
            motion = _read(path, root_offset, units, up_axis, lenient, ignore_joint_positions, skeleton, resample)
    except InputError:
        raise
    except (TopologyError, ValueError, RuntimeWarning, FloatingPointError, np.linalg.LinAlgError,
            IndexError, KeyError, TypeError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, (RuntimeWarning, FloatingPointError, np.linalg.LinAlgError)):
            text = "invalid numbers in the motion: a rotation or transform is NaN, infinite or degenerate"
        elif isinstance(exc, (IndexError, KeyError, TypeError)):  # a reader tripped over the content
            text = f"inconsistent data the reader cannot use ({type(exc).__name__}: {text})"
        raise InputError(path, text) from None
    check_magnitudes(motion, path)
    return motion


def check_magnitudes(motion: Motion, path: str | os.PathLike | None) -> None:
    """Refuse a motion holding NaN, ±inf or any value beyond ``MAX_ABS_VALUE``.

    Checks offsets, root and joint translations and rotations with ``min``/``max`` only
    (no temporary arrays of the motion's size).

    Raises:
        InputError: names ``path``, the array and (for per-frame data) the first bad frame.
    """
    import numpy as np

    arrays = {"joint offsets": motion.offsets, "root translation": motion.root_translation,
              "joint translations": motion.joint_translations, "rotations": motion.rotations}
    for name, a in arrays.items():
        if a is None or a.size == 0 or -MAX_ABS_VALUE <= a.min() <= a.max() <= MAX_ABS_VALUE:
            continue
        bad = np.argwhere(~(np.abs(a) <= MAX_ABS_VALUE))[0]
        where = "" if name == "joint offsets" else f" at frame {int(bad[0])}"
        raise InputError(path, f"{name}{where}: {float(a[tuple(bad)])!r} is not a finite number within "
                               f"±{MAX_ABS_VALUE:g}")


def _check_writable_values(motion: Motion, path: Path) -> None:
    """Refuse to write what no reader accepts (:func:`check_magnitudes`, usdmotion's readers
    included): an edit can move a take past ±1e15 (``reorient --translate 1e16,0,0`` wrote a
    BVH that ``usdmotion info`` then refused, with exit 0)."""
    try:
        check_magnitudes(motion, None)
    except InputError as exc:
        raise OutputError(f"{path}: not written: the result's {exc.message}, which no reader accepts") from None


def _read(path: Path, root_offset: str, units, up_axis, lenient: bool, ignore_joint_positions: bool,
          skeleton: str | None, resample: bool) -> Motion:
    kind = _kind(path)
    # Each format's reader is imported where it is used (here and in write_motion), deliberately:
    # reading a BVH imports no USD or glTF module (start-up, tests/test_startup.py).
    if skeleton is not None:
        if kind == "bvh":
            raise InputError(path, "--skeleton does not apply to BVH input (a BVH file holds one skeleton)")
    if kind == "bvh":
        from usdmotion.io.bvh import read_bvh

        motion = read_bvh(path, root_offset=root_offset, units="cm" if units is None or _is_auto(units) else units,
                          up_axis="Y" if up_axis is None or _is_auto(up_axis) else up_axis, lenient=lenient,
                          ignore_joint_positions=ignore_joint_positions)
        return apply_body_guess(motion, path, units is None or _is_auto(units), up_axis is None or _is_auto(up_axis),
                                implicit_units=units is None, implicit_up=up_axis is None)
    if kind == "usd":
        from usdmotion.io.usd import read_usd
        from usdmotion.usd_diagnostics import usd_diagnostics

        with usd_diagnostics(path):
            motion = read_usd(path, skeleton=skeleton, resample=resample)
        motion = override_units_axis(motion, None if _is_auto(units) else units, None if _is_auto(up_axis) else up_axis)
        return apply_body_guess(motion, path, False, False)
    if kind == "gltf":
        from usdmotion.io.gltf_read import read_gltf

        motion = override_units_axis(read_gltf(path, skin=skeleton), None if _is_auto(units) else units,
                                     None if _is_auto(up_axis) else up_axis)
        return apply_body_guess(motion, path, False, False)
    if kind == "amc":
        from usdmotion.io.amc import read_amc

        return apply_body_guess(read_amc(path, skeleton=skeleton, units=None if _is_auto(units) else units),
                                path, False, False)
    if path.suffix.lower() == ".asf":
        raise InputError(path, "an .asf file holds only a skeleton: read its .amc motion (with --skeleton FILE.asf)")
    raise InputError(path, f"unknown input format {path.suffix!r} (use {READABLE})")


def _say_meshes_dropped(motion: Motion, path: Path, why: str) -> None:
    if motion.meshes:
        import warnings

        warnings.warn(f"{path}: the skinned meshes ({', '.join(m.name for m in motion.meshes)}) are not written: "
                      f"{why} (write .usd/.usda/.usdc/.usdz to keep them)", UsdMotionWarning, stacklevel=3)


def write_motion(motion: Motion | list[Motion], path: str | os.PathLike, **options) -> Path:
    """Write ``motion`` as BVH, USD or glTF, chosen by the extension of ``path`` (atomically).

    ``motion`` may be a one-item list handing the motion over (the USD writer frees a long
    take's arrays before filling its layer, see :func:`usdmotion.io.usd.write_usd`)."""
    path = Path(path)
    kind = _kind(path)  # only the writer of that format is imported (see _read)
    _check_writable_values(motion[0] if isinstance(motion, list) else motion, path)
    if kind != "usd" and isinstance(motion, list):
        motion = motion.pop()
    if kind == "bvh":
        from usdmotion.io.bvh_write import write_bvh

        _say_meshes_dropped(motion, path, "BVH holds no geometry")
        return write_bvh(motion, path, **{k: v for k, v in options.items() if k in ("decimals",)})
    if kind == "usd":
        from usdmotion.io.usd import write_usd

        return write_usd(motion, path, **{k: v for k, v in options.items() if k in ("name", "decorate", "validate")})
    if kind == "gltf":
        from usdmotion.io.gltf import write_gltf

        _say_meshes_dropped(motion, path, "the glTF writer does not carry an input's skinned meshes yet")
        return write_gltf(motion, path, **{k: v for k, v in options.items() if k in ("name", "mesh", "fps", "body")})
    raise OutputError(f"{path}: unknown output format {path.suffix!r} (use {KNOWN})")

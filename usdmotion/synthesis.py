"""Motion from numbers: build a skeleton and its animation from tables of joint angles.

The paper behind ALGORITHMS.md §2 writes a BVH by hand for a 3-segment gymnast; here the
same model is built through an API (or a small JSON/YAML document validated against
``schemas/synthesis.schema.json``), so it cannot come out malformed, and is then written
with the ordinary BVH/USD writers::

    from usdmotion.synthesis import JointSpec, synthesize
    motion = synthesize(
        [JointSpec("Arms"), JointSpec("Body", "Arms", (0, 10, 0)),
         JointSpec("Legs", "Body", (0, 12, 0), end_site=(0, 16, 0))],
        angles={"Arms": {"Z": [16.6, 27.8, ...]}, "Body": {"Z": [...]}, "Legs": {"Z": [...]}},
        fps=30)

Conventions: angles are each joint's rotation relative to its parent (degrees unless
``degrees=False``), intrinsic in the joint's ``rotation_order`` (BVH channel order, e.g.
``ZXY`` ⇒ ``R = Rz Rx Ry``); axes without a column are 0; a joint without a table keeps
its rest orientation. Offsets are the joint's position in its parent's frame at rest.
The root moves by ``root_position`` (added to its offset). The BVH written keeps the
table values exactly (e.g. 363.3°, not 3.3°).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from usdmotion.channels import resolve_units
from usdmotion.errors import InputError
from usdmotion.motion import Motion
from usdmotion.rotations import check_euler_order, euler_to_quat
from usdmotion.schemas import load_document

EXAMPLES = ("giant_swing",)
_AXES = ("X", "Y", "Z")


@dataclass(frozen=True)
class JointSpec:
    """One joint of a synthesised skeleton.

    Attributes:
        name: unique joint name (BVH-safe: no spaces or braces).
        parent: parent joint name; ``None`` for the root (exactly one, listed first).
        offset: position in the parent's frame at rest (root: world position at rest).
        end_site: optional end point of the joint's bone, in the joint's frame.
        rotation_order: Euler order of this joint's angles (default: the motion's).
    """

    name: str
    parent: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    end_site: tuple[float, float, float] | None = None
    rotation_order: str | None = None


def _series(values, what: str, source: str | None) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise InputError(source, f"{what}: a list of numbers is needed")
    if not np.all(np.isfinite(a)):
        raise InputError(source, f"{what}: value {int(np.flatnonzero(~np.isfinite(a))[0])} is not a finite number")
    return a


def _frame_count(tables: list[tuple[str, np.ndarray]], n_frames: int | None, source: str | None) -> int:
    lengths = {len(a) for _, a in tables}
    if n_frames is not None:
        lengths.add(int(n_frames))
    if len(lengths) > 1:
        detail = ", ".join(f"{w} has {len(a)}" for w, a in tables[:4])
        raise InputError(source, f"tables differ in length ({detail}"
                                 + (f", frames = {n_frames}" if n_frames is not None else "") + ")")
    count = lengths.pop() if lengths else 1
    if count < 1:
        raise InputError(source, "a motion needs at least one frame")
    return count


def _check_joints(joints: Sequence[JointSpec], source: str | None) -> dict[str, int]:
    index: dict[str, int] = {}
    for k, joint in enumerate(joints):
        where = f"/joints/{k}"
        if not joint.name or any(c.isspace() or c in "{}" for c in joint.name):
            raise InputError(source, f"{where}/name: {joint.name!r} is not a usable joint name")
        if joint.name in index or joint.name.endswith("_End") and joint.name[:-4] in index:
            raise InputError(source, f"{where}/name: joint {joint.name!r} is defined twice")
        if k == 0 and joint.parent is not None:
            raise InputError(source, f"{where}/parent: the first joint is the root and has no parent")
        if k > 0 and joint.parent not in index:
            what = "is missing" if joint.parent is None else f"{joint.parent!r} is not defined before it"
            raise InputError(source, f"{where}/parent: parent of {joint.name!r} {what}")
        for key, value in (("offset", joint.offset), ("end_site", joint.end_site)):
            if value is not None and (np.shape(value) != (3,) or not np.all(np.isfinite(value))):
                raise InputError(source, f"{where}/{key}: three finite numbers are needed")
        index[joint.name] = k
    if not index:
        raise InputError(source, "/joints: at least one joint is needed")
    return index


def synthesize(joints: Sequence[JointSpec], angles: Mapping[str, Mapping[str, Sequence[float]]] | None = None,
               fps: float = 30.0, n_frames: int | None = None, root_position=None,
               rotation_order: str = "ZXY", degrees: bool = True, meters_per_unit: float = 0.01,
               up_axis: str = "Y", source: str | None = None) -> Motion:
    """Build a :class:`~usdmotion.motion.Motion` from joints and angle tables.

    Args:
        joints: the skeleton, root first, parents before children.
        angles: ``{joint: {"X"|"Y"|"Z": [one value per frame]}}``.
        fps: frames per second.
        n_frames: frame count (default: the tables' length; 1 without tables).
        root_position: ``(3,)`` constant, or ``{"X": [...], ...}`` per frame, or ``(F, 3)``;
            added to the root's offset.
        rotation_order: default Euler order of the angles.
        degrees: angles in degrees (else radians).
        meters_per_unit: length of one unit, in metres.
        up_axis: ``"Y"`` or ``"Z"``.
        source: file name for error messages.

    Raises:
        InputError: inconsistent joints or tables, unknown joint/axis names, NaN values.
    """
    index = _check_joints(joints, source)
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(source, f"/fps: must be a positive number, got {fps}")
    try:
        default_order = check_euler_order(rotation_order)
        orders = [check_euler_order(j.rotation_order or default_order) for j in joints]
    except ValueError as exc:
        raise InputError(source, f"rotation_order: {exc}") from None
    tables: list[tuple[str, np.ndarray]] = []
    columns: dict[tuple[int, int], np.ndarray] = {}
    for name, per_axis in (angles or {}).items():
        if name not in index:
            import difflib

            close = difflib.get_close_matches(name, list(index), n=2)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise InputError(source, f"/angles/{name}: no joint named {name!r}{hint}")
        for axis, values in per_axis.items():
            if str(axis).upper() not in _AXES:
                raise InputError(source, f"/angles/{name}/{axis}: axis must be X, Y or Z")
            series = _series(values, f"/angles/{name}/{axis}", source)
            tables.append((f"/angles/{name}/{axis}", series))
            columns[(index[name], _AXES.index(str(axis).upper()))] = series
    root_series = None
    if isinstance(root_position, Mapping):
        root_series = {}
        for axis, values in root_position.items():
            if str(axis).upper() not in _AXES:
                raise InputError(source, f"/root_position/{axis}: axis must be X, Y or Z")
            root_series[_AXES.index(str(axis).upper())] = _series(values, f"/root_position/{axis}", source)
            tables.append((f"/root_position/{axis}", root_series[_AXES.index(str(axis).upper())]))
    count = _frame_count(tables, n_frames, source)
    return _build(joints, index, orders, columns, root_series, root_position, count, fps, degrees,
                  meters_per_unit, up_axis, source)


def _build(joints, index, orders, columns, root_series, root_position, count, fps, degrees,
           meters_per_unit, up_axis, source) -> Motion:
    names, parents, offsets, channels, ends = [], [], [], [], []
    joint_row: dict[int, int] = {}
    for k, joint in enumerate(joints):  # topology only
        joint_row[k] = len(names)
        names.append(joint.name)
        parents.append(-1 if joint.parent is None else joint_row[index[joint.parent]])
        offsets.append(np.asarray(joint.offset, dtype=np.float64))
        rotation = tuple(f"{a}rotation" for a in orders[k])
        channels.append((("Xposition", "Yposition", "Zposition") if k == 0 else ()) + rotation)
        ends.append(False)
        if joint.end_site is not None:
            names.append(f"{joint.name}_End")
            parents.append(joint_row[k])
            offsets.append(np.asarray(joint.end_site, dtype=np.float64))
            channels.append(())
            ends.append(True)
    n_rows = len(names)
    euler = np.zeros((count, len(joints), 3))  # in each joint's order
    for (k, axis), series in columns.items():
        euler[:, k, orders[k].index(_AXES[axis])] = series
    euler_rad = euler if not degrees else np.deg2rad(euler)
    rotations = np.zeros((count, n_rows, 4))
    rotations[..., 0] = 1.0
    for order in set(orders):  # at most six groups
        ks = [k for k in range(len(joints)) if orders[k] == order]
        rotations[:, [joint_row[k] for k in ks]] = euler_to_quat(euler_rad[:, ks], order)
    root = np.zeros((count, 3))
    if root_series is not None:
        for axis, series in root_series.items():
            root[:, axis] = series
    elif root_position is not None:
        root = np.broadcast_to(np.asarray(root_position, dtype=np.float64), (count, 3)).copy()
        if not np.all(np.isfinite(root)):
            raise InputError(source, "/root_position: non-finite value")
    values = [root] + [np.degrees(euler_rad[:, k]) for k in range(len(joints))]
    try:
        return Motion(joint_names=tuple(names), parents=np.asarray(parents), offsets=np.stack(offsets),
                      rotations=rotations, root_translation=offsets[0][None] + root, fps=fps,
                      end_sites=np.asarray(ends), meters_per_unit=meters_per_unit, up_axis=up_axis,
                      channels=tuple(channels), root_offset="add",
                      source_channels=np.concatenate(values, axis=1))
    except ValueError as exc:
        raise InputError(source, str(exc)) from None


# ------------------------------------------------------------------ documents


def motion_from_spec(spec: Mapping, source: str | os.PathLike | None = None,
                     base_dir: str | os.PathLike | None = None) -> Motion:
    """A motion from a validated synthesis document (see ``schemas/synthesis.schema.json``).

    ``"table": "file.csv"`` (relative to ``base_dir``) adds columns ``Joint.X`` and
    ``root.X``... to the inline ``angles`` / ``root_position``.
    """
    source = None if source is None else str(source)
    joints = [JointSpec(j["name"], j.get("parent"), tuple(j.get("offset", (0.0, 0.0, 0.0))),
                        None if j.get("end_site") is None else tuple(j["end_site"]), j.get("rotation_order"))
              for j in spec["joints"]]
    angles = {name: dict(axes) for name, axes in spec.get("angles", {}).items()}
    root = spec.get("root_position")
    if "table" in spec:
        angles, root = _read_table(spec["table"], base_dir, angles, root, source)
    try:
        units = resolve_units(spec.get("units", "cm"))
    except ValueError as exc:
        raise InputError(source, f"/units: {exc}") from None
    return synthesize(joints, angles, fps=float(spec["fps"]), n_frames=spec.get("frames"), root_position=root,
                      rotation_order=spec.get("rotation_order", "ZXY"), degrees=spec.get("angle_unit", "deg") == "deg",
                      meters_per_unit=units, up_axis=spec.get("up_axis", "Y"), source=source)


def _read_table(name: str, base_dir, angles: dict, root, source: str | None):
    import pandas as pd

    path = Path(base_dir or ".") / name
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(source, f"/table: {path} does not exist") from None
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, f"cannot read the angle table: {str(exc).splitlines()[0]}") from None
    root = dict(root) if isinstance(root, Mapping) else ({} if root is None else root)
    for column in frame.columns:
        joint, _, axis = str(column).rpartition(".")
        if not joint or axis.upper() not in _AXES:
            raise InputError(path, f"column {column!r}: name columns Joint.X, Joint.Y, Joint.Z or root.X ...")
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=np.float64)
        if joint == "root":
            if not isinstance(root, dict):
                raise InputError(source, "/root_position: give it per axis when the table has root columns")
            root[axis.upper()] = values
        else:
            angles.setdefault(joint, {})[axis.upper()] = values
    return angles, root or None


def example_path(name: str) -> Path:
    """Path of a shipped example document (``giant_swing``...)."""
    if name not in EXAMPLES:
        raise InputError(name, f"no such example (shipped: {', '.join(EXAMPLES)})")
    return Path(str(resources.files("usdmotion").joinpath("data", "examples", f"{name}.json")))


def load_synthesis(path: str | os.PathLike) -> Motion:
    """Read, validate and build a synthesis document (``.json``, ``.yaml``, ``.yml``)."""
    path = Path(path)
    spec = load_document(path, "synthesis")
    return motion_from_spec(spec, path, path.parent)

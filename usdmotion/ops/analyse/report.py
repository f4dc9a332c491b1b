"""Tables, summary statistics and files from a :class:`~usdmotion.ops.analyse.Kinematics`.

* :func:`kinematics_table` — one row per (frame, joint), long ("tidy") format; the whole
  body COM and the segment COMs are extra rows named ``COM`` and ``COM:<segment>``.
* :func:`summary` — JSON-ready peak speeds, accelerations, ranges of motion, COM figures.
* :func:`write_kinematics` — ``.csv`` / ``.parquet`` (the table, units in the Parquet
  schema metadata) or ``.json`` (``meta`` + ``summary`` + the table as columns), written
  atomically.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError
from usdmotion.io.atomic import atomic_output
from usdmotion.ops.analyse.measures import AXES, Kinematics

TABLE_FORMATS = (".csv", ".parquet", ".json")


def units(kin: Kinematics) -> dict[str, str]:
    """Unit of every quantity in the table."""
    length = kin.length_unit
    return {"time": "s", "position": length, "velocity": f"{length}/s", "speed": f"{length}/s",
            "acceleration": f"{length}/s^2", "angle": "deg", "bend": "deg", "orientation": "wxyz quaternion",
            "omega": "deg/s", "alpha": "deg/s^2", "momentum": "kg m/s"}


def _columns(kin: Kinematics, idx: list[int]) -> dict[str, np.ndarray]:
    """Per-joint columns ``(F * len(idx),)`` in frame-major order."""
    n = kin.n_frames * len(idx)

    def flat(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a[:, idx]).reshape(n, -1)

    cols: dict[str, np.ndarray] = {}
    _motion_columns(cols, flat(kin.positions), flat(kin.velocities), flat(kin.accelerations))
    cols["euler_order"] = np.tile(np.asarray([kin.euler_orders[j] for j in idx], dtype="U3"), kin.n_frames)
    euler = flat(kin.euler)
    for k, axis in enumerate(AXES):
        cols[f"angle_{axis}"] = euler[:, k]
    cols["bend"] = np.ascontiguousarray(kin.bend[:, idx]).reshape(n)
    orientation = flat(kin.orientations)
    for k, axis in enumerate(("w", "x", "y", "z")):
        cols[f"orient_{axis}"] = orientation[:, k]
    for name, array in (("omega", kin.omega), ("alpha", kin.alpha), ("omega_rel", kin.omega_rel),
                        ("alpha_rel", kin.alpha_rel)):
        values = flat(array)
        for k, axis in enumerate(AXES):
            cols[f"{name}_{axis}"] = values[:, k]
        cols[name] = np.linalg.norm(values, axis=1)
    return cols


def _motion_columns(cols: dict[str, np.ndarray], pos: np.ndarray, vel: np.ndarray, acc: np.ndarray) -> None:
    """Set ``pos_{x,y,z}``, ``vel_{x,y,z}``, ``speed``, ``acc_{x,y,z}``, ``acc`` (in that
    column order) from ``(N, 3)`` rows."""
    for name, values, norm in (("pos", pos, None), ("vel", vel, "speed"), ("acc", acc, "acc")):
        for k, axis in enumerate(AXES):
            cols[f"{name}_{axis}"] = values[:, k]
        if norm is not None:
            cols[norm] = np.linalg.norm(values, axis=1)


def _com_columns(kin: Kinematics, template: dict[str, np.ndarray]) -> tuple[list[str], dict[str, np.ndarray]]:
    """Rows for the whole-body COM and every segment COM (other columns NaN)."""
    names = ["COM"] + [f"COM:{s}" for s in kin.body.segment_names]
    pos = np.concatenate([kin.com[:, None], kin.segment_com], axis=1)  # (F, 1+S, 3)
    weights = np.concatenate([kin.body.com_weights[None], kin.body.weights])  # (1+S, J)
    vel = np.einsum("sj,fjd->fsd", weights, kin.velocities)
    acc = np.einsum("sj,fjd->fsd", weights, kin.accelerations)
    n = kin.n_frames * len(names)
    cols = {}
    for key, value in template.items():
        cols[key] = np.full(n, np.nan) if value.dtype.kind == "f" else np.full(n, "", dtype=value.dtype)
    _motion_columns(cols, pos.reshape(n, 3), vel.reshape(n, 3), acc.reshape(n, 3))
    if kin.momentum is not None:
        momentum = np.zeros((kin.n_frames, len(names), 3)) * np.nan
        momentum[:, 0] = kin.momentum
        for k, axis in enumerate(AXES):
            cols[f"momentum_{axis}"] = momentum.reshape(n, 3)[:, k]
    return names, cols


def kinematics_table(kin: Kinematics, joints: list[int] | None = None, com: bool = True):
    """A ``pyarrow.Table``: columns ``frame, time, joint`` then the quantities (see ``units``)."""
    import pyarrow as pa

    idx = list(range(len(kin.joint_names))) if joints is None else list(joints)
    cols = _columns(kin, idx)
    names = [kin.joint_names[j] for j in idx]
    if com and kin.com is not None:
        com_names, com_cols = _com_columns(kin, cols)
        if kin.momentum is not None:
            for axis in AXES:
                cols[f"momentum_{axis}"] = np.full(len(cols["pos_x"]), np.nan)
        cols = {k: _interleave(v, com_cols[k], len(names), len(com_names)) for k, v in cols.items()}
        names = names + com_names
    frames = np.repeat(kin.frames, len(names))
    table = {"frame": frames, "time": frames / kin.fps,
             "joint": pa.DictionaryArray.from_arrays(np.tile(np.arange(len(names), dtype=np.int32), kin.n_frames),
                                                     pa.array(names))}
    for key, value in cols.items():
        if value.dtype.kind == "U":
            labels, codes = np.unique(value, return_inverse=True)
            value = pa.DictionaryArray.from_arrays(codes.astype(np.int32), pa.array(labels.tolist()))
        table[key] = value
    return pa.table(table)


def _interleave(a: np.ndarray, b: np.ndarray, na: int, nb: int) -> np.ndarray:
    """Rows of ``a`` (F*na) and ``b`` (F*nb) merged frame by frame."""
    frames = len(a) // na if na else len(b) // nb
    return np.concatenate([a.reshape(frames, na), b.reshape(frames, nb)], axis=1).reshape(-1)


def _peak(values: np.ndarray, kin: Kinematics) -> dict:
    if values.size == 0 or not np.any(np.isfinite(values)):
        return {"value": None, "frame": None, "time": None}
    i = int(np.nanargmax(values))
    return {"value": round(float(values[i]), 6), "frame": int(kin.frames[i]), "time": round(float(kin.time[i]), 6)}


def _range(values: np.ndarray) -> dict:
    return {"min": round(float(np.min(values)), 4), "max": round(float(np.max(values)), 4),
            "range": round(float(np.ptp(values)), 4)}


def angle_range(degrees: np.ndarray) -> dict:
    """:func:`_range` of an angle series ``(F,)`` in degrees, unwrapped first: a joint
    swinging from 170° to -170° (through 180°) has a 20° range, not 340°. The series is
    shifted by whole turns so its median lies in [-180°, 180°]."""
    unwrapped = np.unwrap(np.asarray(degrees, np.float64), period=360.0)
    return _range(unwrapped - 360.0 * np.round(np.median(unwrapped) / 360.0))


def joint_summary(kin: Kinematics, j: int) -> dict:
    """Peaks and ranges of one joint (see :func:`summary`)."""
    speed = np.linalg.norm(kin.velocities[:, j], axis=1)
    step = np.linalg.norm(np.diff(kin.positions[:, j], axis=0), axis=1)
    out = {
        "peak_speed": _peak(speed, kin),
        "mean_speed": round(float(speed.mean()), 6),
        "path_length": round(float(step.sum()), 6),
        "peak_acceleration": _peak(np.linalg.norm(kin.accelerations[:, j], axis=1), kin),
        "peak_angular_speed": _peak(np.linalg.norm(kin.omega[:, j], axis=1), kin),
    }
    if not kin.end_sites[j]:
        order = kin.euler_orders[j]
        out["peak_relative_angular_speed"] = _peak(np.linalg.norm(kin.omega_rel[:, j], axis=1), kin)
        out["range_of_motion"] = {"euler_order": order, **{axis: angle_range(kin.euler[:, j, "xyz".index(axis)])
                                                           for axis in AXES}}
    bend = kin.bend[:, j]
    if np.all(np.isfinite(bend)):
        out["bend"] = _range(bend)
    return out


def com_summary(kin: Kinematics) -> dict | None:
    """COM figures: vertical range, speeds, momentum peak (``None`` without a body model)."""
    if kin.com is None:
        return None
    up = kin.up_index
    horizontal = [a for a in range(3) if a != up]
    speed = np.linalg.norm(kin.com_velocity, axis=1)
    out = {
        "model": kin.body.source,
        "notes": list(kin.body.notes),
        "landmarks": kin.body.landmarks,
        "segments": {name: round(float(m), 6) for name, m in zip(kin.body.segment_names, kin.body.mass_fractions)},
        "vertical": _range(kin.com[:, up]),
        "peak_speed": _peak(speed, kin),
        "mean_horizontal_speed": round(float(np.linalg.norm(kin.com_velocity[:, horizontal], axis=1).mean()), 6),
        "peak_acceleration": _peak(np.linalg.norm(kin.com_acceleration, axis=1), kin),
    }
    if kin.momentum is not None:
        out["mass_kg"] = kin.mass
        out["peak_momentum"] = _peak(np.linalg.norm(kin.momentum, axis=1), kin)
    return out


def meta(kin: Kinematics, source: str | None = None) -> dict:
    """What the numbers are: file, frames, units and every convention used."""
    return {
        "file": source,
        "frames": kin.n_frames,
        "first_frame": kin.first_frame,
        "fps": kin.fps,
        "duration_s": round((kin.n_frames - 1) / kin.fps, 6),
        "up_axis": kin.up_axis,
        "meters_per_unit": kin.meters_per_unit,
        "units": units(kin),
        "filter": kin.filter.describe(kin.fps),
        "conventions": {
            "angle": "joint rotation relative to its parent, zero in the file's rest pose, intrinsic Euler angles "
                     "in euler_order (BVH channel order), columns per axis",
            "bend": "angle between the bone into the joint and the bone out of it; 0 = straight",
            "orientation": "world rotation of the joint (= its segment), wxyz",
            "omega": "segment angular velocity in the world frame, from quaternions",
            "omega_rel": "joint angular velocity relative to the parent, in the joint's own frame",
        },
        "notes": list(kin.notes),
    }


def summary(kin: Kinematics, joints: list[int] | None = None, source: str | None = None) -> dict:
    """JSON-ready summary: ``meta``, per-joint peaks and ranges, and ``com``."""
    idx = list(range(len(kin.joint_names))) if joints is None else list(joints)
    return {"meta": meta(kin, source), "joints": {kin.joint_names[j]: joint_summary(kin, j) for j in idx},
            "com": com_summary(kin)}


def write_summary(data: dict, path: str | os.PathLike) -> Path:
    """Write a summary dict as JSON (atomically)."""
    path = Path(path)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1, allow_nan=False, default=_json_default) + "\n", encoding="utf-8")
    return path


def _json_default(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def table_path(path: str | os.PathLike) -> Path:
    """``path`` if its extension is a table format we write, else ``OutputError``."""
    path = Path(path)
    if path.suffix.lower() not in TABLE_FORMATS:
        raise OutputError(f"{path}: unknown table format {path.suffix!r} (use {', '.join(TABLE_FORMATS)})")
    return path


def write_kinematics(kin: Kinematics, path: str | os.PathLike, joints: list[int] | None = None,
                     source: str | None = None) -> Path:
    """Write the per-frame table as ``.csv``, ``.parquet`` or ``.json`` (with the summary)."""
    path = table_path(path)
    ext = path.suffix.lower()
    table = kinematics_table(kin, joints)
    with atomic_output(path) as tmp:
        if ext == ".csv":
            import pyarrow.csv as pcsv

            pcsv.write_csv(table, str(tmp))
        elif ext == ".parquet":
            import pyarrow.parquet as pq

            info = {"usdmotion": json.dumps(meta(kin, source), default=_json_default)}
            pq.write_table(table.replace_schema_metadata(info), str(tmp))
        else:
            data = summary(kin, joints, source)
            data["table"] = {name: _json_column(column) for name, column in zip(table.column_names, table.columns)}
            tmp.write_text(json.dumps(data, allow_nan=False, default=_json_default), encoding="utf-8")
    return path


def _json_column(column) -> list:
    import pyarrow as pa

    if pa.types.is_dictionary(column.type):
        column = column.cast(pa.string())
    values = column.to_numpy(zero_copy_only=False)
    if values.dtype.kind == "f":
        rounded = np.round(values, 7)
        return [None if not np.isfinite(v) else v for v in rounded.tolist()]
    return values.tolist()

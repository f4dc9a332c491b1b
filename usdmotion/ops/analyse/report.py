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
    """:func:`_peaks` of one series ``(F,)``."""
    return _peaks(np.asarray(values)[None], kin)[0]


def _peaks(values: np.ndarray, kin: Kinematics) -> list[dict]:
    """:func:`_peak` of every row of ``values (J, F)`` at once: the first frame of each
    row's largest value, NaN ignored; all ``None`` for a row without a finite value."""
    n_rows, n_frames = values.shape
    if n_frames == 0:
        return [{"value": None, "frame": None, "time": None} for _ in range(n_rows)]
    best = np.argmax(np.where(np.isnan(values), -np.inf, values), axis=1)  # (J,) nanargmax, NaN-only rows aside
    found = np.isfinite(values).any(axis=1).tolist()
    peak = values[np.arange(n_rows), best].tolist()
    frames, times = kin.frames[best].tolist(), kin.time[best].tolist()
    return [{"value": round(v, 6), "frame": f, "time": round(t, 6)} if ok else {"value": None, "frame": None, "time": None}
            for ok, v, f, t in zip(found, peak, frames, times)]


def _range(values: np.ndarray) -> dict:
    """:func:`_ranges` of one series ``(F,)``."""
    return _ranges(np.asarray(values)[None])[0]


def _ranges(values: np.ndarray) -> list[dict]:
    """:func:`_range` of every row of ``values (N, F)`` at once."""
    low, high = values.min(axis=1), values.max(axis=1)
    return [{"min": round(a, 4), "max": round(b, 4), "range": round(r, 4)}
            for a, b, r in zip(low.tolist(), high.tolist(), (high - low).tolist())]


def angle_range(degrees: np.ndarray) -> dict:
    """:func:`_range` of an angle series ``(F,)`` in degrees, unwrapped first: a joint
    swinging from 170° to -170° (through 180°) has a 20° range, not 340°. The series is
    shifted by whole turns so its median lies in [-180°, 180°]."""
    return _ranges(_unwrapped_rows(np.asarray(degrees, np.float64)[None]))[0]


def _unwrapped_rows(degrees: np.ndarray) -> np.ndarray:
    """Angle series ``(N, F)`` in degrees, each unwrapped and shifted by whole turns so its
    median lies in [-180°, 180°] (see :func:`angle_range`)."""
    unwrapped = np.unwrap(degrees, period=360.0, axis=1)
    return unwrapped - 360.0 * np.round(np.median(unwrapped, axis=1, keepdims=True) / 360.0)


def _row_norms(vectors: np.ndarray) -> np.ndarray:
    """Lengths of ``vectors (F, J, 3)`` as contiguous rows ``(J, F)``."""
    return np.ascontiguousarray(np.linalg.norm(vectors, axis=2).T)


def joint_summaries(kin: Kinematics, joints: list[int]) -> list[dict]:
    """Peaks and ranges of the ``joints`` (see :func:`summary`), one dict each, computed over
    all frames and joints at once: speeds (length units/s) and accelerations from
    ``(F, J, 3)`` vectors, angular speeds (deg/s), Euler ranges of motion (deg, unwrapped),
    bend ranges (deg) of joints whose bend is defined at every frame."""
    idx = np.asarray(joints, dtype=np.intp)
    speed = _row_norms(kin.velocities[:, idx])                                  # (J, F)
    path = _row_norms(np.diff(kin.positions[:, idx], axis=0)).sum(axis=1)      # (J,)
    peaks = {"peak_speed": _peaks(speed, kin)} | {key: _peaks(_row_norms(vectors[:, idx]), kin) for key, vectors in (
        ("peak_acceleration", kin.accelerations), ("peak_angular_speed", kin.omega))}
    out = [{"peak_speed": s, "mean_speed": round(m, 6), "path_length": round(p, 6), "peak_acceleration": a,
            "peak_angular_speed": w}
           for s, m, p, a, w in zip(peaks["peak_speed"], speed.mean(axis=1).tolist(), path.tolist(),
                                    peaks["peak_acceleration"], peaks["peak_angular_speed"])]
    real = [k for k, j in enumerate(joints) if not kin.end_sites[j]]
    if real:
        ridx = idx[real]
        relative = _peaks(_row_norms(kin.omega_rel[:, ridx]), kin)
        euler = np.ascontiguousarray(np.moveaxis(kin.euler[:, ridx], 0, -1), dtype=np.float64)  # (R, 3, F)
        ranges = _ranges(_unwrapped_rows(euler.reshape(-1, kin.n_frames)))
        for n, k in enumerate(real):
            out[k]["peak_relative_angular_speed"] = relative[n]
            out[k]["range_of_motion"] = {"euler_order": kin.euler_orders[joints[k]],
                                         **{axis: ranges[3 * n + "xyz".index(axis)] for axis in AXES}}
    bend = np.ascontiguousarray(kin.bend[:, idx].T)                              # (J, F)
    whole = np.flatnonzero(np.isfinite(bend).all(axis=1))
    for k, entry in zip(whole.tolist(), _ranges(bend[whole])):
        out[k]["bend"] = entry
    return out


def joint_summary(kin: Kinematics, j: int) -> dict:
    """Peaks and ranges of one joint (see :func:`joint_summaries`)."""
    return joint_summaries(kin, [j])[0]


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
    return {"meta": meta(kin, source),
            "joints": {kin.joint_names[j]: entry for j, entry in zip(idx, joint_summaries(kin, idx))},
            "com": com_summary(kin)}


def write_summary(data: dict, path: str | os.PathLike) -> Path:
    """Write a summary dict as JSON (atomically)."""
    path = Path(path)
    with atomic_output(path) as tmp:
        tmp.write_text(_json_text(data) + "\n", encoding="utf-8")
    return path


def _json_text(value, depth: int = 2, margin: str = "") -> str:
    """JSON of ``value`` with its first ``depth`` levels of objects one key per line and what
    lies deeper on one line (a joint per line in a summary). Python's encoder indents in pure
    Python (7.5 ms of a 160-frame take's 48 ms); the compact lines use its C encoder."""
    if depth == 0 or not isinstance(value, dict) or not value:
        return json.dumps(value, allow_nan=False, default=_json_default)
    inner = margin + " "
    items = (f"{inner}{json.dumps(str(key))}: {_json_text(item, depth - 1, inner)}" for key, item in value.items())
    return "{\n" + ",\n".join(items) + f"\n{margin}}}"


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
            import pyarrow as pa
            import pyarrow.parquet as pq

            info = {"usdmotion": json.dumps(meta(kin, source), default=_json_default)}
            # dictionary pages only for the label columns: Arrow's default tries a dictionary for
            # every column, and on measured floats it only falls back after hashing them (a
            # 160-frame take wrote in 12 ms that way, 4.6 ms so, and its file is 15 % smaller)
            labels = [f.name for f in table.schema if pa.types.is_dictionary(f.type)]
            pq.write_table(table.replace_schema_metadata(info), str(tmp), use_dictionary=labels)
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

"""``OUT_DIR/catalogue.parquet``: one row per (operation, take), written atomically.

Columns common to every operation are in :data:`COLUMNS`; ``analyze`` adds its kinematic
summary columns (:data:`ANALYZE_COLUMNS`). Units: bytes, seconds, metres, m/s.
"""

from __future__ import annotations

from pathlib import Path

from usdmotion.io.atomic import atomic_output

#: name → pyarrow type name (see :func:`schema`).
COLUMNS = {
    "operation": "string", "take": "string", "source": "string", "relpath": "string",
    "size_bytes": "int64", "mtime": "float64", "sha256": "string",
    "rig_family": "string", "joints": "int32", "end_sites": "int32", "frames": "int32", "fps": "float64",
    "duration_s": "float64", "meters_per_unit": "float64", "units": "string", "up_axis": "string",
    "outputs": "list<string>", "status": "string", "error": "string", "warnings": "string",
    "seconds": "float64", "cpu_seconds": "float64", "worker": "string", "options": "string",
}
ANALYZE_COLUMNS = {
    "peak_joint_speed": "float64", "peak_joint_speed_joint": "string", "peak_joint_speed_time_s": "float64",
    "com_peak_speed": "float64", "com_mean_horizontal_speed": "float64",
    "com_vertical_min": "float64", "com_vertical_max": "float64", "com_vertical_range": "float64",
}
ALL_COLUMNS = {**COLUMNS, **ANALYZE_COLUMNS}


def schema():
    """The ``pyarrow.Schema`` of the catalogue."""
    import pyarrow as pa

    types = {"string": pa.string(), "int64": pa.int64(), "int32": pa.int32(), "float64": pa.float64(),
             "list<string>": pa.list_(pa.string())}
    return pa.schema([(name, types[kind]) for name, kind in ALL_COLUMNS.items()])


def read_catalogue(path: str | Path) -> dict[tuple[str, str], dict]:
    """Rows of an existing catalogue by ``(operation, take)``; empty when there is none
    (or it cannot be read: the batch then redoes every take)."""
    path = Path(path)
    if not path.is_file():  # a first run: no pyarrow import (0.15 s) before the first takes
        return {}
    import pyarrow.parquet as pq

    try:
        rows = pq.ParquetFile(path).read().to_pylist()  # not read_table: it imports pandas (0.24 s)
    except Exception:  # noqa: BLE001 - an unreadable catalogue only costs a full re-run
        return {}
    return {(r.get("operation"), r.get("take")): r for r in rows}


def load_arrow() -> None:
    """Import what :func:`write_catalogue` needs (``pyarrow.parquet``, ``pyarrow.json``; 0.25 s of
    CPU). A run calls this in a thread while the workers run."""
    import pyarrow.json  # noqa: F401
    import pyarrow.parquet  # noqa: F401


def write_catalogue(rows: dict[tuple[str, str], dict], path: str | Path) -> Path:
    """Write all rows (sorted by operation, source path) atomically.

    The rows reach Arrow as JSON lines parsed against :func:`schema` (C++, values exact: floats
    print and parse round-trip, NaN and infinities included), not through ``pa.Table.from_pylist``,
    whose first call imports pandas (0.24 s of CPU in the client, beside the busy workers, for a
    library pyarrow only checks the values against)."""
    import io
    import json

    import pyarrow.json as pj
    import pyarrow.parquet as pq

    ordered = sorted(rows.values(), key=lambda r: (r.get("operation") or "", r.get("relpath") or ""))
    names = list(ALL_COLUMNS)
    lines = "\n".join(json.dumps({k: r.get(k) for k in names}, default=_item) for r in ordered).encode()
    table = (pj.read_json(io.BytesIO(lines), read_options=pj.ReadOptions(use_threads=False),
                          parse_options=pj.ParseOptions(explicit_schema=schema(), unexpected_field_behavior="error"))
             if ordered else schema().empty_table())
    with atomic_output(path) as tmp:
        pq.write_table(table, str(tmp))
    return Path(path)


def _item(value):
    """A NumPy scalar as the Python number it holds (``json.dumps``' fallback; the tasks' rows
    hold nothing else that JSON lacks)."""
    return value.item()

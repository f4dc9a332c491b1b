"""The local cluster's workers (real Dask worker processes): one thread inside a take (usdmotion's
own, BLAS/Arrow via ``OMP_NUM_THREADS``, USD's work pool), no USD banner about it, and a warm-up
that runs a real take of the bundled walk in each worker, leaving nothing behind, and then freezes
the worker's objects out of the garbage collector's walks; the local cluster's Dask settings reach them."""

from __future__ import annotations

import os
import sys

from usdmotion.batch.engine import dask_client, warm_up


def _worker_state() -> dict:
    import gc

    import dask
    import pyarrow
    from pxr import Work

    from usdmotion import parallel
    from usdmotion.batch import engine

    return {"usd_threads": Work.GetConcurrencyLimit(), "usdmotion_threads": parallel.workers(),
            "arrow_threads": pyarrow.cpu_count(), "omp": os.environ.get("OMP_NUM_THREADS"),
            "prepared": sorted(engine._PREPARED),
            "validation_loaded": "pxr.UsdValidation" in sys.modules,  # only a written USD take loads it
            "filters_loaded": "scipy.signal" in sys.modules, "frozen_objects": gc.get_freeze_count(),
            "memory_checks": dask.config.get("distributed.worker.memory.monitor-interval"),
            "work_stealing": dask.config.get("distributed.scheduler.work-stealing")}


def test_workers_run_one_thread_and_warm_up_on_a_real_take(tmp_path, monkeypatch, capfd):
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))  # the workers' temporary folders, inherited when they start
    with dask_client(2) as client:
        before = client.run(_worker_state)
        warm_up(client, "convert")
        after_convert = client.run(_worker_state)
        warm_up(client, "analyze")
        after_analyze = client.run(_worker_state)
    assert len(before) == 2
    for state in before.values():
        assert (state["usd_threads"], state["usdmotion_threads"], state["arrow_threads"], state["omp"]) == (1, 1, 1, "1")
        assert state["prepared"] == [] and not state["validation_loaded"] and state["frozen_objects"] == 0
        assert (state["memory_checks"], state["work_stealing"]) == ("500ms", False)  # LOCAL_CLUSTER_CONFIG reached it
    for state in after_convert.values():
        assert state["prepared"] == ["convert"] and state["validation_loaded"]
        assert state["frozen_objects"] > 10_000  # the warm worker's modules and Dask's objects, out of the GC's walks
    for state in after_analyze.values():
        assert state["prepared"] == ["analyze", "convert"] and state["filters_loaded"]
    assert list(scratch.iterdir()) == []  # the warm-up takes' folders are gone
    err = capfd.readouterr().err
    assert "PXR_WORK_THREAD_LIMIT" not in err and "####" not in err


def test_catalogue_values_round_trip_exactly_without_pandas(tmp_path):
    """``write_catalogue`` (rows as JSON lines parsed against the schema) and
    ``read_catalogue`` give back every value exactly — floats to the last bit, NaN, infinities,
    NumPy scalars, lists, text with newlines and non-ASCII — and, in a fresh process, never
    import pandas (0.24 s of CPU in the client beside the workers); ``pa.Table.from_pylist``
    is the independent reference for the table."""
    import math
    import subprocess

    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from usdmotion.batch.catalogue import ALL_COLUMNS, read_catalogue, schema, write_catalogue

    rows = {("analyze", f"s{i}__take.bvh"): {
        "operation": "analyze", "take": f"s{i}__take.bvh", "relpath": f"s{i}/täke.bvh", "source": f"/lib/s{i}/täke.bvh",
        "size_bytes": 2**40 + i, "mtime": 1732812345.123456789 + i / 7, "frames": np.int64(240 + i),
        "fps": np.float64(120.0), "duration_s": (240 + i) / 120, "meters_per_unit": 0.0254 * 0.45,
        "outputs": [f"/out/s{i}/a.json", "/out/b.parquet"], "status": "ok" if i else "error",
        "error": None if i else "bad.bvh:3: no HIERARCHY", "warnings": "line one\nline \"two\"",
        "peak_joint_speed": [math.nan, math.inf, -math.inf, 5e-324][i], "com_peak_speed": None,
        "not_a_column": "dropped"} for i in range(4)}
    path = tmp_path / "catalogue.parquet"
    write_catalogue(rows, path)
    reference = pa.Table.from_pylist(sorted(({k: r.get(k) for k in ALL_COLUMNS} for r in rows.values()),
                                            key=lambda r: r["relpath"]), schema=schema())
    table = pq.read_table(path)
    assert table.schema.equals(schema())
    for name in ALL_COLUMNS:
        assert table.column(name).to_pylist() == reference.column(name).to_pylist() or name == "peak_joint_speed"
    back = read_catalogue(path)
    assert set(back) == set(rows)
    for key, row in rows.items():
        for name in ALL_COLUMNS:
            want, got = row.get(name), back[key][name]
            assert (math.isnan(got) if isinstance(want, float) and math.isnan(want) else got == want), (name, got, want)
    write_catalogue({}, path)
    assert pq.read_table(path).num_rows == 0
    code = ("import sys; from pathlib import Path; from usdmotion.batch.catalogue import write_catalogue, read_catalogue;"
            f"p = Path({str(tmp_path / 'c2.parquet')!r}); "
            "write_catalogue({('convert', 't'): {'operation': 'convert', 'take': 't', 'outputs': ['x']}}, p); "
            "assert len(read_catalogue(p)) == 1; print('pandas' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.stdout.strip() == "False", done.stderr[-2000:]

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

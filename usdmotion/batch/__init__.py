"""Batch processing of a motion library on a Dask cluster (``usdmotion batch ...``).

Data flow: :mod:`plan` finds the takes under a source folder and decides which are up to
date; :mod:`tasks` runs one take on a worker through the same library functions the
single-file commands call; :mod:`engine` submits the takes to a local or remote Dask
cluster; :mod:`catalogue` keeps ``OUT_DIR/catalogue.parquet`` (one row per take and
operation); :mod:`runner` ties them together.
"""

from __future__ import annotations

from usdmotion.batch.plan import OPERATIONS, Job, plan_jobs
from usdmotion.batch.runner import BatchResult, run_batch

__all__ = ["OPERATIONS", "BatchResult", "Job", "plan_jobs", "run_batch"]

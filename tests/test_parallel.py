"""Threads over slices of an array (``usdmotion.parallel``)."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion import parallel


def test_threads_over_slices_cover_the_range_once_and_raise_a_workers_error(monkeypatch):
    """``parallel.over_slices`` (the BVH reader's and position_bounds' threads): every index
    once, and an exception in a worker thread reaches the caller."""
    monkeypatch.setenv("USDMOTION_THREADS", "3")
    seen = np.zeros(1000, int)
    parallel.over_slices(lambda part: np.add.at(seen, np.arange(part.start, part.stop), 1), 1000, min_items=100)
    assert (seen == 1).all()

    def fail_late(part: slice) -> None:
        if part.start > 0:
            raise ValueError(f"bad slice {part.start}")

    with pytest.raises(ValueError, match="bad slice"):
        parallel.over_slices(fail_late, 1000, min_items=100)

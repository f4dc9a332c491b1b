"""Shared fixtures: where the shared BVH corpus lives, and a skip when it is missing."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("USDMOTION_SHARED_DATA", REPO.parent / "shared" / "data"))
TEST_DATA = REPO / "tests" / "data"


def shared_path(relative: str) -> Path:
    """Path of a file in ``../shared/data``; skips the test with a reason if it is missing."""
    path = SHARED_DATA / relative
    if not path.is_file():
        pytest.skip(f"shared data file {relative} not found under {SHARED_DATA} "
                    "(set USDMOTION_SHARED_DATA to the folder holding the shared BVH corpus)")
    return path


def walk_and_daz():
    """``(walk, daz)``: the CMU walk (cgspeed, ASF units) and the DAZ rig's take, the
    retargeting benchmark's walk → DAZ pair (skips when absent; reader warnings silenced)."""
    import warnings

    from usdmotion.io import read_motion

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return (read_motion(shared_path("cmu/cgspeed_12_01_walk.bvh"), units="asf"),
                read_motion(shared_path("cmu/daz_10_01_soccer_kick.bvh")))


@pytest.fixture
def shared_file():
    """``shared_file("cmu/cgspeed_12_01_walk.bvh") -> Path`` (skips when absent)."""
    return shared_path


@pytest.fixture(autouse=True, scope="session")
def _jax_on_every_core():
    """JAX with one CPU device per core before any test computes with it, as in a
    command-line run (the LM solve splits its frames over them; test_retarget_shards.py)."""
    from usdmotion.ops.retarget.jax_runtime import use_cpu_cores

    use_cpu_cores()
    yield


@pytest.fixture(autouse=True, scope="session")
def _headless_rendering():
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    yield


def without_warnings(err: str) -> list[str]:
    """The stderr lines of a CLI run other than ``usdmotion: warning:`` ones (a file read
    with implausible default units warns before the error a test is about)."""
    return [line for line in err.strip().splitlines() if not line.startswith("usdmotion: warning: ")]

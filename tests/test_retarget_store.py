"""The store of traced solvers beside JAX's compilation cache (``jax_runtime.lower_stored``).

Each case runs a small LM solve (48 walk frames, the paper's joints removed) in a fresh
process, as a command does. Independent computation: the first process traces the solver;
a later one must give the same bits without tracing it (``jax.export.export`` made to
fail there), a changed code version must trace again into a second file, and a file cut
short must be traced again and replaced.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"

CHILD = """
import hashlib, json, sys, warnings
sys.path.insert(0, {tests!r})
import numpy as np
from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache
import usdmotion.ops.retarget.jax_runtime as runtime
enable_compilation_cache()
mode = sys.argv[1]
import jax
if mode == "no-tracing":
    def refuse(*args, **kwargs):
        raise AssertionError("traced although the store holds the solver")
    jax.export.export = refuse
if mode == "new-code":
    runtime._code_version = lambda: "another version of the code"
from usdmotion.io import read_motion
from usdmotion.ops.retarget.pipeline import _problem, prepare
from usdmotion.ops.retarget.solve import solve
from test_retarget import PAPER_REMOVE, frames
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    walk = frames(read_motion({walk!r}), 100, 48)
setup = prepare(walk, remove=list(PAPER_REMOVE))
centre = setup.translations[:, 0]
t0 = setup.translations.copy()
t0[:, 0] -= centre
s = solve(_problem(setup), setup.inits["compose"], t0, setup.targets[:, setup.mapped] - centre[:, None], shards=1)
if mode == "x64-after":  # the float64 reference checks of the LM, in the same process after the store's export
    import jax.numpy as jnp
    from usdmotion.kinematics import fk_arrays
    from usdmotion.ops.retarget.solve import make_residuals
    problem = _problem(setup)
    with jax.enable_x64(True):
        world_p = make_residuals(problem)(*(jnp.asarray(a, jnp.float64) for a in (s.q, s.t, s.t[:, :1])))[1]
    np.testing.assert_allclose(np.asarray(world_p), fk_arrays(s.q, s.t, problem.parents)[1], rtol=1e-12, atol=1e-9)
print(json.dumps({{"q": hashlib.sha256(np.ascontiguousarray(s.q).tobytes()).hexdigest(),
                   "loss": float(s.loss.sum()), "iterations": s.iterations}}))
"""


def run(cache: Path, mode: str = "", **environ) -> dict:
    env = {**os.environ, "USDMOTION_JAX_CACHE": str(cache), "PYTHONPATH": str(REPO), **environ}
    done = subprocess.run([sys.executable, "-c", CHILD.format(tests=str(HERE), walk=str(WALK)), mode],
                          capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not WALK.is_file(), reason="the bundled walk is missing")
def test_a_later_process_reads_the_traced_solver_back_and_gets_the_same_bits(tmp_path):
    cache = tmp_path / "jax"
    first = run(cache)
    files = sorted((cache / "exported").glob("*.jaxexport"))
    assert len(files) == 1 and files[0].stat().st_size > 10_000
    assert first["loss"] > 0 and first["iterations"] > 0

    assert run(cache, "no-tracing") == first  # read back, not traced: the same bits

    assert run(cache, "new-code") == first  # another code version: traced again, a file of its own
    assert len(list((cache / "exported").glob("*.jaxexport"))) == 2

    size = files[0].stat().st_size
    files[0].write_bytes(files[0].read_bytes()[: size // 3])  # cut short: traced again and replaced
    assert run(cache) == first
    assert files[0].stat().st_size == size
    assert [p.name for p in (cache / "exported").iterdir() if p.name.startswith(".")] == []  # no temporary left


@pytest.mark.skipif(not WALK.is_file(), reason="the bundled walk is missing")
def test_float64_checks_run_in_a_process_whose_solver_went_into_the_store(tmp_path):
    """JAX keeps its conversion of a NumPy index array per array object, in the integer width
    of its first use: forward kinematics' cached depth levels, traced by the store's export in
    32-bit mode, failed (``lax.add``, int32 + int64) when the same process then ran forward
    kinematics in 64-bit mode, as the float64 reference checks of the LM do. Independent
    computation: NumPy's float64 positions of the solved frames."""
    assert run(tmp_path / "jax", "x64-after")["iterations"] > 0


def _entry(path: Path, size: int, age_s: float, now: float) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x" * size)
    os.utime(path, (now - age_s, now - age_s))
    return path


def test_trim_removes_the_least_recently_used_entries_down_to_three_quarters(tmp_path):
    """Ten 100 kB entries (compiled executables and traced solvers), used 1..10 hours ago,
    and one written a minute ago, against a 700 kB limit: the oldest go until 3/4 of the
    limit is left (525 kB: five 100 kB files and the new one); the new one stays though it
    alone would not fit a lower limit; files of other names are not touched."""
    from usdmotion.ops.retarget.jax_runtime import trim_cache

    now = 1.8e9
    old = [_entry(tmp_path / (f"jit_f{i}-cache" if i % 2 else f"exported/s{i}.jaxexport"), 100_000, 3600.0 * (i + 1),
                  now) for i in range(10)]
    fresh = _entry(tmp_path / "jit_new-cache", 100_000, 60.0, now)
    other = _entry(tmp_path / "notes.txt", 100_000, 1e6, now)
    assert trim_cache(tmp_path, 2_000_000, now) == 0  # under the limit: nothing
    assert trim_cache(tmp_path, 700_000, now) == 600_000
    assert [p.exists() for p in old] == [True] * 4 + [False] * 6  # the six oldest (used 5..10 hours ago)
    assert fresh.exists() and other.exists()
    assert trim_cache(tmp_path, 0, now) == 400_000  # everything but what was used in the last 10 minutes
    assert fresh.exists() and not any(p.exists() for p in old)


@pytest.mark.skipif(not WALK.is_file(), reason="the bundled walk is missing")
def test_a_command_keeps_the_cache_folder_under_its_bound(tmp_path):
    """A process started with ``USDMOTION_JAX_CACHE_MB`` below what the folder holds removes
    the entries unused for long (here: made a day old) and still solves, to the same bits."""
    cache = tmp_path / "jax"
    first = run(cache)
    entries = [*cache.glob("*-cache"), *(cache / "exported").glob("*.jaxexport")]
    assert entries
    day_ago = entries[0].stat().st_mtime - 86_400
    for path in entries:
        os.utime(path, (day_ago, day_ago))
    assert run(cache, USDMOTION_JAX_CACHE_MB="0.001") == first  # trimmed at start, then compiled and traced again
    assert not any(p.exists() and p.stat().st_mtime == day_ago for p in entries)
    assert list((cache / "exported").glob("*.jaxexport"))  # the new process's own entries are there


@pytest.mark.parametrize("setting, megabytes, warns", [("", 2000.0, False), ("5", 5.0, False), ("0", 0.0, False),
                                                       ("abc", 2000.0, True), ("nan", 2000.0, True),
                                                       ("inf", 2000.0, True), ("-3", 2000.0, True)])
def test_the_cache_bound_setting(monkeypatch, setting, megabytes, warns):
    """``USDMOTION_JAX_CACHE_MB``: megabytes ≥ 0; anything else warns and keeps the default
    (``nan`` had reached ``int()``: a traceback)."""
    import warnings

    from usdmotion.errors import UsdMotionWarning
    from usdmotion.ops.retarget.jax_runtime import CACHE_MB, _cache_megabytes

    monkeypatch.setenv("USDMOTION_JAX_CACHE_MB", setting)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert _cache_megabytes() == megabytes
    assert CACHE_MB == 2000
    said = [w for w in caught if issubclass(w.category, UsdMotionWarning) and "USDMOTION_JAX_CACHE_MB" in str(w.message)]
    assert bool(said) == warns

"""The LM solve split over CPU devices (``solve(..., shards=2)``) is the one-device solve.

XLA:CPU runs the solve's small per-frame operations on one core, so on a CPU the frames of a
chunk are split into blocks, one per device, run in lockstep (``usdmotion.ops.retarget.solve``).
Independent computation: the same solve on one device. Control: the same frames solved as
two separate chunks, whose temporal term is cut at the boundary: the blocks' neighbour
exchange is what keeps the sharded result equal to the one-device one there.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FRAMES = 128


def compare(walk_path: str) -> dict:
    """One-device, two-device and two-chunk solves of 128 walk frames from a noisy start with
    the temporal term on: the largest joint distance (cm) of each from the one-device
    result, overall and on the four frames around the block boundary, and the iterations."""
    import importlib

    from usdmotion.io import read_motion
    from usdmotion.kinematics import fk_arrays
    from usdmotion.ops.retarget.pipeline import _problem, prepare
    from usdmotion.rotations import euler_to_quat, quat_mul

    sys.path.insert(0, str(HERE))
    from test_retarget import PAPER_REMOVE, frames

    solve_module = importlib.import_module("usdmotion.ops.retarget.solve")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        walk = frames(read_motion(walk_path), 100, FRAMES)
    setup = prepare(walk, remove=list(PAPER_REMOVE))
    problem = _problem(setup, smooth=1.0)
    noise = euler_to_quat(np.random.default_rng(1).uniform(-0.3, 0.3, (FRAMES, len(problem.rot_joints), 3)), "XYZ")
    q0 = np.array(setup.inits["compose"])
    q0[:, problem.rot_joints] = quat_mul(q0[:, problem.rot_joints], noise)
    centre = setup.translations[:, 0]
    t0 = setup.translations - np.eye(setup.rig.n_joints)[0][None, :, None] * centre[:, None]
    targets = setup.targets[:, setup.mapped] - centre[:, None]
    runs = {name: solve_module.solve(problem, q0, t0, targets, chunk=chunk, shards=shards, iterations=40)
            for name, chunk, shards in (("one", FRAMES, 1), ("sharded", FRAMES, 2), ("two chunks", FRAMES // 2, 1))}
    cm = walk.meters_per_unit * 100.0
    world = {name: fk_arrays(s.q, s.t, setup.rig.parents)[1] for name, s in runs.items()}
    out = {"iterations": {name: s.iterations for name, s in runs.items()}}
    boundary = slice(FRAMES // 2 - 2, FRAMES // 2 + 2)
    for name in ("sharded", "two chunks"):
        distance = np.linalg.norm(world[name] - world["one"], axis=-1).max(axis=1) * cm
        out[name] = {"max_cm": float(distance.max()), "boundary_cm": float(distance[boundary].max())}
    return out


def test_two_cpu_devices_give_the_one_device_solve(shared_file):
    walk = str(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    import jax

    if len(jax.devices("cpu")) >= 2:  # conftest gave this process one device per core
        result = compare(walk)
    else:  # a one-core machine: a process with two CPU devices
        env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2")
        code = f"import json, sys; sys.path.insert(0, {str(HERE)!r}); " \
               f"from test_retarget_shards import compare; print(json.dumps(compare({walk!r})))"
        done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=False, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["iterations"]["sharded"] == result["iterations"]["one"]
    assert result["sharded"]["max_cm"] < 0.01, result  # float32 summation order only
    # the control: without the neighbour exchange the boundary frames move by far more
    assert result["two chunks"]["boundary_cm"] > 0.05, result
    assert result["two chunks"]["boundary_cm"] > 20 * result["sharded"]["boundary_cm"], result


def test_use_cpu_cores_leaves_a_started_jax_alone():
    """After JAX's first computation the device count cannot change: ``use_cpu_cores``
    reports what JAX has instead of failing (a host application that already uses JAX);
    before it, one device per CPU."""
    code = ("import jax, jax.numpy as jnp; jnp.ones(2).block_until_ready(); "
            "from usdmotion.ops.retarget.jax_runtime import use_cpu_cores; print(use_cpu_cores())")
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | {"USDMOTION_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=False, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "1"
    # a fresh one gets a device per CPU, whatever USDMOTION_THREADS says (a batch worker's
    # split, hence its float32 rounding, is the single-file command's)
    code = "from usdmotion.ops.retarget.jax_runtime import use_cpu_cores; print(use_cpu_cores())"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=False, timeout=300)
    assert done.stdout.strip() == str(len(os.sched_getaffinity(0))), done.stderr[-2000:]


def test_the_cpu_compile_options_give_the_default_compiles_result():
    """``solve.CPU_COMPILER_OPTIONS`` (XLA:CPU's loop emitters instead of its fusion emitters,
    ~40 % less compile time) must not change what the solve computes: the LM of a small
    problem compiled both ways, run on the same inputs, gives the same rotations and losses
    to float32 rounding (the losses, and the points they measure: a random small
    problem has flat directions in which the rotations themselves may wander apart)."""
    import importlib

    import jax
    import jax.numpy as jnp

    sys.path.insert(0, str(HERE))
    from test_retarget import small_problem

    solve_module = importlib.import_module("usdmotion.ops.retarget.solve")
    assert solve_module.CPU_COMPILER_OPTIONS  # the option this test is about is in use
    problem, q, t, targets = small_problem()
    frames = 64
    rng = np.random.default_rng(5)
    q = np.repeat(q, frames // 2, axis=0) * np.sign(rng.normal(size=(frames, 1, 1)))  # both hemispheres
    t = np.repeat(t, frames // 2, axis=0)
    targets = np.repeat(targets, frames // 2, axis=0) + rng.normal(scale=0.1, size=(frames,) + targets.shape[1:])
    args = [jnp.asarray(a, jnp.float32) for a in (q, t, targets)]
    args += [jnp.ones(targets.shape[:2], jnp.float32), jnp.zeros(frames, jnp.float32),
             jnp.zeros(frames, jnp.float32), jnp.int32(50)]
    lowered = solve_module._make_lm(problem).lower(*args)
    ours = jax.block_until_ready(solve_module.compile_lowered(lowered)(*args))
    default = jax.block_until_ready(lowered.compile()(*args))
    assert int(ours[4]) == int(default[4]) > 1
    np.testing.assert_allclose(np.asarray(ours[2]), np.asarray(default[2]), rtol=1e-4, atol=1e-6)
    from usdmotion.kinematics import fk_arrays

    points = [fk_arrays(np.asarray(out[0], np.float64), np.asarray(out[1], np.float64), problem.parents)[1][
        :, problem.mapped] for out in (ours, default)]
    size = np.ptp(points[1], axis=1).max()
    np.testing.assert_allclose(points[0], points[1], atol=2e-3 * size)  # solver tolerance; broken code is far off
    assert float(np.asarray(ours[2]).sum()) < 0.5 * float(np.asarray(ours[3]).sum())  # it did solve something

"""Within-rig residuals (benchmarks/retarget_residual.py): the shipped solve's loss is close
to the best a much longer solve finds (the gap is small), and the remaining loss (the floor)
comes from removed joints that rotate — it vanishes when the removed joints hold still, and
it sits on the joints below the removed one."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from usdmotion.io import read_motion
from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from retarget_residual import Residual, joint_errors  # noqa: E402

WALK = "cmu/cgspeed_12_01_walk.bvh"
FRAMES = 24
CHUNK = None  # the chunk retarget() itself uses: one XLA compile for the whole file
REMOVED = ["LHipJoint", "RHipJoint", "LowerBack"]  # the hip triangle and the spine's base become rigid


@pytest.fixture(scope="module")
def walk():
    from conftest import shared_path

    enable_compilation_cache()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        motion = read_motion(shared_path(WALK))
    keep = np.arange(100, 100 + 4 * FRAMES, 4)  # a stride of 4: a larger part of the gait in few frames
    jt = None if motion.joint_translations is None else motion.joint_translations[keep]
    return motion.with_frames(motion.rotations[keep], motion.root_translation[keep], jt)

def test_shipped_solve_is_within_a_few_percent_of_a_much_longer_solve(walk):
    """The hip joints and LowerBack removed from the walk: the floor is positive (they rotate, so
    the legs' and the spine's roots no longer move apart from the Hips) and the
    shipped solve stays within 2 % of what 5 starts x 4 LM restarts find, frame by frame."""
    res = Residual(walk, REMOVED, rounds=4, chunk=CHUNK)
    assert (res.best <= res.shipped + 1e-12).all()
    assert (res.best > 1e-6).all()  # no rotation reaches the source: the removed joints rotate
    assert res.gap.sum() <= 0.02 * res.shipped.sum()
    assert (res.gap <= 0.05 * res.shipped + 1e-9).all()
    # the floor sits on the re-parented joints (and what hangs below them), never on the root
    floor = res.per_joint_floor()
    assert sum(floor.values()) == pytest.approx(res.best.sum(), rel=1e-9)
    worst = next(iter(floor))
    assert worst in ("Spine", "LeftUpLeg", "RightUpLeg")
    assert floor.get("Hips", 0.0) == 0.0  # the root translation is the source's


def test_floor_vanishes_when_the_removed_joints_hold_still(walk):
    """The same removals on a copy of the walk whose removed joints keep a constant
    rotation: a constant offset represents them exactly, the best found (and the shipped
    solve) reach ~0, while the original's floor (the removed joints rotate) stays."""
    removed = REMOVED
    index = [walk.joint_names.index(n) for n in removed]
    rotations = walk.rotations.copy()
    rotations[:, index] = walk.rotations[:1, index]  # hold the first frame's rotation
    still = walk.with_frames(rotations, walk.root_translation, walk.joint_translations)
    moving = Residual(walk, removed, rounds=2, neighbours=False, chunk=CHUNK)
    held = Residual(still, removed, rounds=2, neighbours=False, chunk=CHUNK)
    size = float(np.mean(np.einsum("fjk,fjk->f", held.setup.targets, held.setup.targets)))
    assert held.best.max() < 1e-8 * size
    assert held.shipped.max() < 1e-8 * size  # the shipped solve finds it too
    assert moving.best.min() > 1e3 * held.best.max()
    errors = joint_errors(moving.setup, moving.best_q, moving.t)
    assert errors.sum(axis=1) == pytest.approx(moving.best, rel=1e-9)

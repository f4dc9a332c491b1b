"""The ``aim`` initial guess of retargeting (``usdmotion.ops.retarget.aim.aim_init``), one depth
level of joints at a time.

Independent checks: forward kinematics of the returned local rotations (``fk_arrays``), not
the function's own world arrays; the aimed directions from the setup's targets.
"""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.kinematics import fk_arrays
from usdmotion.rotations import quat_mul, quat_rotate

@pytest.fixture(scope="module")
def walk_onto_daz():
    from conftest import walk_and_daz

    from usdmotion.ops.retarget.aim import _rays, aim_init
    from usdmotion.ops.retarget.pipeline import prepare

    walk, daz = walk_and_daz()
    setup = prepare(walk, daz)
    mapped = np.zeros(setup.rig.n_joints, bool)
    mapped[setup.mapped] = True
    return setup, _rays(setup.rig, setup.offsets, mapped), aim_init(setup, setup.inits["copy"])


def _aimed(setup, count, wanted) -> list[int]:
    return [int(j) for j in setup.rot_joints if wanted(count[j])]


def test_one_ray_joints_point_their_rest_bone_at_the_target(walk_onto_daz):
    """A joint with one mapped descendant turns its rest vector onto that joint's target, on
    every frame (to 1e-6 degrees): forward kinematics of the result, the source's positions."""
    setup, (ends, vectors, count), local = walk_onto_daz
    world_q, world_p = fk_arrays(local, setup.translations, setup.rig.parents)
    joints = _aimed(setup, count, lambda c: c == 1)
    assert len(joints) >= 6  # DAZ's neck, head, arms, forearms, hands... in this map
    for j in joints:
        bone = quat_rotate(world_q[:, j], vectors[j, 0])
        want = setup.targets[:, ends[j, 0]] - world_p[:, j]
        angle = np.arctan2(np.linalg.norm(np.cross(bone, want), axis=1), np.einsum("fk,fk->f", bone, want))
        assert np.degrees(angle).max() < 1e-6, setup.rig.joint_names[j]


def test_several_ray_joints_take_the_least_squares_rotation(walk_onto_daz):
    """A joint with several mapped descendants in a plane (the hips: thighs and spine) takes the
    rotation that best aligns its rest vectors with the target directions: no small turn of it
    (random axes, 0.01 rad) raises Σ vᵣ·(R uᵣ) on any frame."""
    setup, (ends, vectors, count), local = walk_onto_daz
    world_q, world_p = fk_arrays(local, setup.translations, setup.rig.parents)
    joints = _aimed(setup, count, lambda c: c >= 2)
    assert joints
    rng = np.random.default_rng(7)
    for j in joints:
        u = vectors[j, : count[j]]
        v = setup.targets[:, ends[j, : count[j]]] - world_p[:, j, None]  # (F, R, 3)

        def score(q):
            return np.einsum("frk,frk->f", v, quat_rotate(q[:, None], u[None]))

        best = score(world_q[:, j])
        axes = rng.normal(size=(20, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        for axis in axes:
            turn = np.r_[np.cos(0.005), np.sin(0.005) * axis]
            assert (score(quat_mul(turn, world_q[:, j])) <= best + 1e-9 * np.abs(best)).all(), setup.rig.joint_names[j]


def test_joints_that_aim_at_nothing_keep_their_parents_frame(walk_onto_daz):
    """Joints not optimised or with no mapped descendant (DAZ's fingers past the mapped
    one, face bones) keep the identity: the parent's frame."""
    setup, (_, _, count), local = walk_onto_daz
    optimised = np.zeros(setup.rig.n_joints, bool)
    optimised[setup.rot_joints] = True
    idle = ~optimised | (count == 0)
    assert idle.sum() > 10
    np.testing.assert_array_equal(local[:, idle], np.broadcast_to([1.0, 0.0, 0.0, 0.0], local[:, idle].shape))

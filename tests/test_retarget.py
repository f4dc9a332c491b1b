"""Retargeting: the loss and its derivatives, the solvers, step 1, and real cross-rig cases.

Independent checks: finite differences in float64, ``jax.jacfwd``/``jax.jacrev``,
NumPy forward kinematics written out here, hand-built exact solutions. Frame counts
stay ≤ 16 so every solve reuses one compiled chunk size.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from usdmotion.errors import UsdMotionWarning
from usdmotion.io import read_motion
from usdmotion.kinematics import fk_arrays, joint_positions, local_translations
from usdmotion.motion import Motion
from usdmotion.ops.retarget.hierarchy import AddSpec, derive_rig, rig_from_motion
from usdmotion.ops.retarget.pipeline import frame_losses, prepare, retarget
from usdmotion.rotations import euler_to_quat, quat_mul, quat_rotate

WALK = "cmu/cgspeed_12_01_walk.bvh"
#: The paper experiment's list (docs/retarget.md): 13 of 31 CMU joints.
PAPER_REMOVE = ("LHipJoint RHipJoint LowerBack Spine1 Neck LeftShoulder RightShoulder LeftFingerBase "
                "RightFingerBase LeftHandIndex1 RightHandIndex1 LThumb RThumb").split()


def frames(motion: Motion, start: int, count: int) -> Motion:
    sl = slice(start, start + count)
    jt = None if motion.joint_translations is None else motion.joint_translations[sl]
    return motion.with_frames(motion.rotations[sl], motion.root_translation[sl], jt)


@pytest.fixture(scope="module")
def walk(request) -> Motion:
    from conftest import shared_path

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return frames(read_motion(shared_path(WALK)), 100, 16)


def reference_positions(rotations, translations, parents):
    """World positions by walking each joint's chain (independent of ``fk_arrays``)."""
    out = np.zeros(translations.shape)
    for j in range(len(parents)):
        chain = []
        k = j
        while k >= 0:
            chain.insert(0, k)
            k = parents[k]
        q = np.zeros(rotations.shape[:1] + (4,))
        q[:, 0] = 1.0
        p = np.zeros(translations.shape[:1] + (3,))
        for k in chain:
            p = p + quat_rotate(q, translations[:, k])
            q = quat_mul(q, rotations[:, k])
        out[:, j] = p
    return out


# ------------------------------------------------------------- derivatives (float64)


def small_problem():
    from usdmotion.ops.retarget.solve import Problem

    parents = np.array([-1, 0, 1, 2, 1, 4, 0])
    rng = np.random.default_rng(3)
    q = euler_to_quat(rng.uniform(-1.0, 1.0, (2, 7, 3)), "ZXY")
    t = rng.normal(size=(2, 7, 3))
    targets = rng.normal(size=(2, 6, 3))
    problem = Problem(parents, np.array([1, 2, 3, 4, 5, 6]), np.array([1.0, 0.5, 2.0, 1.0, 3.0, 1.0]),
                      np.array([0, 1, 2, 4]), np.array([0]), ("ZXY",) * 4)
    return problem, q, t, targets


def test_loss_gradient_matches_finite_differences():
    import jax
    import jax.numpy as jnp

    from usdmotion.ops.retarget.solve import make_apply, make_residuals

    problem, q, t, targets = small_problem()
    with jax.enable_x64(True):
        q, t, targets = (jnp.asarray(a, jnp.float64) for a in (q, t, targets))
        residuals, apply = make_residuals(problem), make_apply(problem)
        world_q = residuals(q, t, targets)[0]

        def loss(step):  # loss of frame 0 after a tangent step (B=1)
            q2, t2 = apply(q[:1], t[:1], world_q[:1], step[None])
            return residuals(q2, t2, targets[:1])[3][0]

        grad = jax.jit(jax.grad(loss))
        h = 1e-6
        eye = jnp.eye(problem.n_params)
        central = jax.jit(jax.vmap(lambda x, e: (loss(x + h * e) - loss(x - h * e)) / (2 * h), in_axes=(None, 0)))
        away = jnp.asarray(np.random.default_rng(0).normal(0, 0.3, problem.n_params))
        for point in (jnp.zeros(problem.n_params), away):
            g, fd = np.asarray(grad(point)), np.asarray(central(point, eye))
            assert np.all(np.isfinite(g)) and np.abs(fd).max() > 1e-3
            np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max())


def test_solve_leaves_out_joints_that_move_no_point():
    """Unmapped branches (fingers, face bones) are cut out of the solve: the same solution
    on the other joints as the problem without them, and their own rotations and
    translations returned as given."""
    from usdmotion.ops.retarget.solve import Problem, needed_joints, solve

    problem, q, t, targets = small_problem()
    # the same skeleton with an unmapped branch X (child of 1, index 3) -> Y (index 8) inserted
    old_to_new = np.array([0, 1, 2, 4, 5, 6, 7])
    parents = np.array([-1, 0, 1, 1, 2, 1, 5, 0, 3])
    rng = np.random.default_rng(5)
    q_big, t_big = euler_to_quat(rng.uniform(-1.0, 1.0, (2, 9, 3)), "ZXY"), rng.normal(size=(2, 9, 3))
    q_big[:, old_to_new], t_big[:, old_to_new] = q, t
    big = Problem(parents, old_to_new[problem.mapped], problem.weights, old_to_new[problem.rot_joints],
                  old_to_new[problem.trans_joints], problem.orders)
    reduced, keep = needed_joints(big)
    np.testing.assert_array_equal(np.flatnonzero(keep), old_to_new)
    np.testing.assert_array_equal(reduced.parents, problem.parents)
    expected, got = solve(problem, q, t, targets), solve(big, q_big, t_big, targets)
    assert expected.loss.sum() < 0.5 * expected.initial.sum()  # it did solve something
    np.testing.assert_allclose(got.q[:, old_to_new], expected.q, atol=1e-6)
    np.testing.assert_allclose(got.t[:, old_to_new], expected.t, atol=1e-6)
    np.testing.assert_allclose(got.loss, expected.loss, rtol=1e-6)
    np.testing.assert_allclose(got.q[:, [3, 8]], q_big[:, [3, 8]], atol=1e-12)
    np.testing.assert_array_equal(got.t[:, [3, 8]], t_big[:, [3, 8]])


@pytest.mark.parametrize("trans", [[0], []])
def test_tree_lm_step_equals_the_dense_solve_of_the_autodiff_jacobian(trans):
    import jax
    import jax.numpy as jnp
    from lm_reference import reference_lm_step

    from usdmotion.ops.retarget.dense_step import make_dense_step, make_jacobian
    from usdmotion.ops.retarget.solve import Problem, make_apply, make_residuals
    from usdmotion.ops.retarget.tree_step import make_tree_step

    problem, q, t, targets = small_problem()
    problem = Problem(problem.parents, problem.mapped, problem.weights, problem.rot_joints, np.array(trans, int),
                      problem.orders)
    with jax.enable_x64(True):
        q, t, targets = (jnp.asarray(a, jnp.float64) for a in (q, t, targets))
        residuals, apply = make_residuals(problem), make_apply(problem)
        world_q, world_p, r, _, _ = residuals(q, t, targets)
        sqrt_w = jnp.sqrt(jnp.asarray(problem.weights))

        def weighted(step):  # (B, P) -> (B, 3M) weighted residuals after the step
            q2, t2 = apply(q, t, world_q, step)
            return (residuals(q2, t2, targets)[2] * sqrt_w[:, None]).reshape(2, -1)

        zero = jnp.zeros((2, problem.n_params))
        auto_f, auto_r = jax.jit(lambda z: (jax.jacfwd(weighted)(z), jax.jacrev(weighted)(z)))(zero)  # (B,3M,B,P)
        auto = np.stack([np.asarray(auto_f)[b, :, b] for b in range(2)])
        np.testing.assert_allclose(auto, np.stack([np.asarray(auto_r)[b, :, b] for b in range(2)]), atol=1e-12)
        analytic = np.asarray(jax.jit(make_jacobian(problem))(world_p))
        np.testing.assert_allclose(analytic, auto, rtol=1e-6, atol=1e-6 * np.abs(auto).max())
        # the LM step from the autodiff Jacobian, in float64 NumPy
        lam = np.array([0.01, 3.0])
        expected = reference_lm_step(auto, np.asarray(weighted(zero)), lam)
        for make in (make_tree_step, make_dense_step):
            got = np.asarray(jax.jit(make(problem))(world_p, r, jnp.asarray(lam)))
            np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


@pytest.mark.parametrize("trans", [[0], []])
def test_model_gain_is_the_reduction_of_the_autodiff_linearisation(trans):
    """The loss reduction Nielsen's damping update compares with (``make_model_gain``) is the
    Gauss–Newton model's: ``‖r‖² − ‖r + J x‖²`` with ``J`` the autodiff Jacobian of the
    weighted position residuals, plus the same for world-rotation residuals with the
    autodiff Jacobian of the world rotations' axis-angle change."""
    import jax
    import jax.numpy as jnp

    from usdmotion.ops.retarget.lm_model import make_model_gain
    from usdmotion.ops.retarget.solve import Problem, make_apply, make_residuals
    from usdmotion.rotations import quat_log

    problem, q, t, targets = small_problem()
    problem = Problem(problem.parents, problem.mapped, problem.weights, problem.rot_joints, np.array(trans, int),
                      problem.orders)
    rng = np.random.default_rng(7)
    with jax.enable_x64(True):
        q, t, targets = (jnp.asarray(a, jnp.float64) for a in (q, t, targets))
        residuals, apply = make_residuals(problem), make_apply(problem)
        world_q, world_p, r, _, w = residuals(q, t, targets)
        sqrt_w = jnp.sqrt(jnp.asarray(problem.weights))
        rot_j = np.asarray(problem.rot_joints)
        conj = jnp.asarray([1.0, -1.0, -1.0, -1.0])

        def linear_parts(step):  # (B, 3M) weighted residuals and (B, 3R) world rotation changes
            q2, t2 = apply(q, t, world_q, step)
            world_q2, _, r2, _, _ = residuals(q2, t2, targets)
            turn = quat_log(quat_mul(world_q2[:, rot_j], world_q[:, rot_j] * conj))
            return (r2 * sqrt_w[:, None]).reshape(2, -1), turn.reshape(2, -1)

        zero = jnp.zeros((2, problem.n_params))
        jac_p, jac_r = jax.jacfwd(linear_parts)(zero)
        jac_p = np.stack([np.asarray(jac_p)[b, :, b] for b in range(2)])
        jac_r = np.stack([np.asarray(jac_r)[b, :, b] for b in range(2)])
        step = rng.normal(0, 0.2, (2, problem.n_params))
        rot_r, rot_w = rng.normal(0, 0.3, (2, len(rot_j), 3)), rng.uniform(0.5, 2.0, (2, len(rot_j)))
        rw = np.asarray(r * sqrt_w[:, None]).reshape(2, -1)
        moved = np.einsum("bij,bj->bi", jac_p, step)
        turned = np.einsum("bij,bj->bi", jac_r, step).reshape(2, -1, 3)
        expected = (np.sum(rw ** 2, -1) - np.sum((rw + moved) ** 2, -1)
                    + np.einsum("bk,bkc->b", rot_w, rot_r ** 2 - (rot_r + turned) ** 2))
        got = np.asarray(make_model_gain(problem)(world_p, r, w, jnp.asarray(step), jnp.asarray(rot_r),
                                                  jnp.asarray(rot_w)))
        assert np.abs(expected).max() > 1e-2
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())


def test_lm_step_drops_only_the_invisible_twist():
    import jax
    import jax.numpy as jnp

    from usdmotion.ops.retarget.solve import make_lm_step, make_residuals, single_point_joints
    from usdmotion.ops.retarget.tree_step import make_tree_step

    problem, q, t, targets = small_problem()  # joint 2 has one mapped descendant (3), joint 4 one (5)
    slot, joint, point = single_point_joints(problem)
    assert joint.tolist() == [2, 4] and point.tolist() == [3, 5]
    _, world_p, r, _, _ = make_residuals(problem)(jnp.asarray(q, jnp.float32), jnp.asarray(t, jnp.float32),
                                               jnp.asarray(targets, jnp.float32))
    lam = jnp.asarray([0.01, 1.0], jnp.float32)
    full = np.asarray(jax.jit(make_tree_step(problem))(world_p, r, lam)).reshape(2, -1, 3)
    step = np.asarray(jax.jit(make_lm_step(problem))(world_p, r, lam)).reshape(2, -1, 3)
    p = np.asarray(world_p)
    axis = p[:, point] - p[:, joint]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    np.testing.assert_allclose(np.sum(step[:, slot] * axis, -1), 0.0, atol=1e-6)
    np.testing.assert_allclose(step[:, slot], full[:, slot] - np.sum(full[:, slot] * axis, -1, keepdims=True) * axis,
                               atol=1e-6)
    others = [k for k in range(len(problem.rot_joints)) if k not in slot]
    np.testing.assert_array_equal(step[:, others], full[:, others])


# ---------------------------------------------------------------- exact solutions


def test_removed_identity_joint_has_an_exact_solution(walk):
    # LHipJoint never rotates in the cgspeed files: removing it must cost nothing.
    assert np.allclose(np.abs(walk.rotations[:, walk.joint_index("LHipJoint"), 0]), 1.0)
    result = retarget(walk, remove=["LHipJoint"])
    motion = result.motion
    assert "LHipJoint" not in motion.joint_names
    assert motion.parents[motion.joint_index("LeftUpLeg")] == motion.joint_index("Hips")
    source = joint_positions(walk)
    translations = np.broadcast_to(motion.offsets, (16,) + motion.offsets.shape).copy()
    translations[:, 0] = motion.root_translation
    mine = reference_positions(motion.rotations, translations, motion.parents)
    idx = [walk.joint_index(n) for n in motion.joint_names]
    height = np.ptp(source[0], axis=0).max()
    assert np.abs(mine - source[:, idx]).max() < 1e-6 * height
    assert result.report["loss"]["final"]["rms"] < 1e-6 * height


def test_lm_finds_the_exact_solution_from_a_poor_start(walk):
    from usdmotion.ops.retarget.pipeline import _problem
    from usdmotion.ops.retarget.solve import solve

    setup = prepare(walk, remove=["LHipJoint"])
    problem = _problem(setup)
    rng = np.random.default_rng(1)
    noise = euler_to_quat(rng.uniform(-0.4, 0.4, (16, len(problem.rot_joints), 3)), "XYZ")
    q0 = np.array(setup.inits["compose"])
    q0[:, problem.rot_joints] = quat_mul(q0[:, problem.rot_joints], noise)
    centre = setup.translations[:, 0]
    t0 = setup.translations - np.eye(setup.rig.n_joints)[0][None, :, None] * centre[:, None]
    solution = solve(problem, q0, t0, setup.targets[:, setup.mapped] - centre[:, None])
    height = np.ptp(joint_positions(walk)[0], axis=0).max()
    start = frame_losses(t0, q0, setup.rig.parents, setup.mapped, setup.targets - centre[:, None], setup.weights)
    final = frame_losses(solution.t, solution.q, setup.rig.parents, setup.mapped, setup.targets - centre[:, None],
                         setup.weights)
    assert np.sqrt(start.min() / len(problem.mapped)) > 0.05 * height  # a poor start indeed
    assert np.sqrt(final.max() / len(problem.mapped)) < 1e-5 * height
    np.testing.assert_allclose(final, solution.loss, rtol=1e-2, atol=1e-9 * height**2)


def test_mean_directions_make_constant_removed_rotations_exact(walk):
    # Removed joints with constant, non-identity rotations: with directions="mean" every
    # re-parented bone points where it always pointed in its new parent's frame, so a
    # zero-loss solution exists; with the paper's "direction kept" the hip triangle bends.
    rotations = np.array(walk.rotations)
    rng = np.random.default_rng(5)
    for name in PAPER_REMOVE:
        rotations[:, walk.joint_index(name)] = euler_to_quat(rng.uniform(-0.3, 0.3, 3), "ZYX")
    motion = walk.with_frames(rotations, walk.root_translation)
    rest = retarget(motion, remove=PAPER_REMOVE, directions="rest")
    mean = retarget(motion, remove=PAPER_REMOVE, directions="mean")
    height = np.ptp(joint_positions(motion)[0], axis=0).max()
    assert mean.report["loss"]["final"]["rms"] < 1e-6 * height
    assert rest.report["loss"]["final"]["rms"] > 1e-3 * height
    # both lengths are the (constant) source distance
    p = joint_positions(motion)
    d = np.linalg.norm(p[:, motion.joint_index("LeftUpLeg")] - p[:, motion.joint_index("Hips")], axis=-1)
    for result in (rest, mean):
        m = result.motion
        assert np.linalg.norm(m.offsets[m.joint_index("LeftUpLeg")]) == pytest.approx(d.mean(), rel=1e-9)


# ---------------------------------------------------------------- hierarchy, step 1


def test_remove_and_add_keep_topology_and_rest_pose(walk):
    rig = rig_from_motion(walk)
    derived = derive_rig(rig, ["Spine1", "LeftHandIndex1"], [AddSpec("Chest", "Spine", (0.0, 1.0, 0.0), ("Neck",)),
                                                             AddSpec("Prop", "RightHand", (1.0, 2.0, 3.0))])
    new = derived.rig
    names = new.joint_names
    assert "Spine1" not in names and "LeftHandIndex1_End" not in names  # End Sites go with their joint
    assert names[new.parents[names.index("Chest")]] == "Spine"
    assert names[new.parents[names.index("Neck")]] == "Chest"
    assert names[new.parents[names.index("LeftShoulder")]] == "Spine"
    assert names[new.parents[names.index("Prop")]] == "RightHand"
    assert all(p < j for j, p in enumerate(new.parents) if j)
    # rest pose of the kept joints unchanged: compare with the source rest pose
    from usdmotion.kinematics import rest_positions

    old_rest = rest_positions(walk)
    identity = np.zeros((new.n_joints, 4))
    identity[:, 0] = 1
    new_rest = fk_arrays(identity, new.offsets, new.parents)[1]
    for j, o in enumerate(derived.origin):
        if o >= 0:
            np.testing.assert_allclose(new_rest[j], old_rest[o], atol=1e-12)
    assert derived.compose[names.index("Neck")] == (walk.joint_index("Spine1"), walk.joint_index("Neck"))


def test_step1_lengths_are_mean_source_distances(walk):
    setup = prepare(walk, remove=PAPER_REMOVE, directions="rest")
    p = joint_positions(walk)
    names = setup.rig.joint_names
    for child, parent in (("Neck1", "Spine"), ("LeftArm", "Spine"), ("LeftUpLeg", "Hips"), ("LeftLeg", "LeftUpLeg")):
        d = np.linalg.norm(p[:, walk.joint_index(child)] - p[:, walk.joint_index(parent)], axis=-1).mean()
        assert np.linalg.norm(setup.offsets[names.index(child)]) == pytest.approx(d, rel=1e-9)
        composed = setup.rig.offsets[names.index(child)]  # "rest": direction kept
        np.testing.assert_allclose(np.cross(setup.offsets[names.index(child)], composed), 0, atol=1e-9)


def test_bandai_source_zero_length_end_sites_and_animated_hips(shared_file):
    # Bandai's End Sites have zero offsets: Head's and the hands' only mapped descendants
    # sit on them, so their rotations are invisible and must not be optimised (they would
    # drift); Hips carries the trajectory in its position channels and keeps its OFFSET.
    from usdmotion.io.bvh import read_bvh

    bandai = frames(read_bvh(shared_file("bandai1/dataset-1_kick_normal_001.bvh")), 0, 16)
    setup = prepare(bandai, remove=["Neck", "Shoulder_L"])
    moved = {setup.rig.joint_names[j] for j in setup.rot_joints}
    assert not moved & {"Head", "Hand_L", "Hand_R", "Toes_L", "Toes_R"}
    assert {"Chest", "UpperArm_L", "LowerArm_L", "Foot_L"} <= moved
    hips = setup.rig.joint_names.index("Hips")
    np.testing.assert_array_equal(setup.offsets[hips], bandai.offsets[bandai.joint_index("Hips")])
    # its per-frame translation is the exact source one
    np.testing.assert_allclose(setup.translations[:, hips], bandai.joint_translations[:, bandai.joint_index("Hips")],
                               atol=1e-9)


def test_lm_keeps_going_while_its_first_steps_are_rejected(shared_file):
    """AnimatedDrawings' karate BVH read as it is (its thorax and head position channels hold
    world positions: the skeleton is distorted, the reader warns) onto the Rokoko rig: the
    targets lie far from any pose of the target, and the LM's first two steps were rejected.
    Two rejections counted as convergence, so the LM stopped after 2 iterations with the
    loss unchanged (100.0 % of the initial guess, RMS 107 cm, exit 0); rejections now only
    raise λ until a frame has moved. Independent computation: the float64 loss of the
    initial guess and of the result, by NumPy forward kinematics."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        karate = frames(read_motion(shared_file("other_rigs/ad_karate_mawashigeri.bvh")), 0, 16)
        rokoko = read_motion(shared_file("other_rigs/ad_rokoko_jesse_dance.bvh"))
    from usdmotion.ops.retarget.jointmap import JointMap

    # the automatic map of then (normalised names; the asf profile maps 17 joints now)
    five = JointMap({"LeftHand": "lhand", "Head": "head", "RightHand": "rhand", "LeftFoot": "lfoot",
                     "RightFoot": "rfoot"})
    with pytest.warns(UsdMotionWarning, match=r"the result lies far from the source: .* with 5 of 60 target joints"):
        result = retarget(karate, rokoko, joint_map=five)  # the distorted targets stay out of reach
    setup = prepare(karate, rokoko, joint_map=five)
    args = (rokoko.parents, setup.mapped, setup.targets, setup.weights)
    start = frame_losses(setup.translations, setup.inits[result.report["init"]], *args).sum()
    final = frame_losses(local_translations(result.motion), result.motion.rotations, *args).sum()
    assert result.report["iterations_run"] > 2
    assert final < 0.9 * start


def test_the_karate_rig_maps_by_its_asf_profile_and_lands_near_its_source(shared_file):
    """The same 16 frames read with ``--ignore-joint-positions`` (the OFFSETs: an undistorted
    skeleton), mapped automatically through the ``asf`` profile (17 joints: hips, spine,
    head, arms, legs; by normalised names 5): the result lies within a few cm of the source,
    and no far-result warning is given. Independent computation: NumPy forward kinematics of
    the result against the source positions the solve was given."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        karate = frames(read_motion(shared_file("other_rigs/ad_karate_mawashigeri.bvh"),
                                    ignore_joint_positions=True), 0, 16)
        rokoko = read_motion(shared_file("other_rigs/ad_rokoko_jesse_dance.bvh"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UsdMotionWarning)
        result = retarget(karate, rokoko)
    assert result.report["map"]["how"] == "rig profiles asf -> rokoko"
    setup = prepare(karate, rokoko)
    assert len(setup.mapped) >= 17
    world = fk_arrays(result.motion.rotations, local_translations(result.motion), rokoko.parents)[1]
    rms_cm = np.sqrt(np.mean(np.sum((world[:, setup.mapped] - setup.targets[:, setup.mapped]) ** 2, -1))) * 100 \
        * rokoko.meters_per_unit
    assert rms_cm < 5.0


def test_a_cmu_walk_onto_the_optitrack_rig_maps_its_limbs_and_is_not_refused(shared_file):
    """The OptiTrack Arena rig (Biovision-style names: LeftCollar, LeftShoulder at the shoulder,
    LeftElbow, LeftHip, LeftKnee) was mapped by normalised names onto 6 CMU joints, cgspeed's
    zero-length ``LeftShoulder`` clavicle onto its shoulder joint, and the walk was refused as
    "2.06x the size of the source: the units look mismatched" (exit 2) though both files state
    their units. Through the ``optitrack`` profile it maps every limb, and the sizes agree
    (1.73 m against the walk's 1.43 m: ratio ≈ 1.2). Independent computation: the skeletons'
    heights by forward kinematics of their rest poses."""
    from usdmotion.kinematics import skeleton_height

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        walk = frames(read_motion(shared_file(WALK), units="asf"), 1, 16)
        louise = read_motion(shared_file("other_rigs/wspr_louise_optitrack_arena.bvh"))
    result = retarget(walk, louise, contacts=None)
    assert result.report["map"]["how"] == "rig profiles cmu_cgspeed -> optitrack"
    pairs = result.report["map"]["pairs"]
    assert pairs["LeftShoulder"] == "LeftArm" and pairs["LeftKnee"] == "LeftLeg" and pairs["RightWrist"] == "RightHand"
    assert sum(v is not None for v in pairs.values()) >= 17
    ratio = (skeleton_height(louise) * louise.meters_per_unit) / (skeleton_height(walk) * walk.meters_per_unit)
    assert 1.1 < ratio < 1.35
    assert result.report["loss"]["final"]["rms"] < 0.05 * skeleton_height(louise)


# ----------------------------------------------------------------- methods, modes


def test_lm_reaches_at_least_adams_loss_on_the_paper_case(walk):
    lm = retarget(walk, remove=PAPER_REMOVE)
    adam = retarget(walk, remove=PAPER_REMOVE, method="adam")
    assert adam.report["init"] == "copy" and lm.report["init"] == "compose"
    copied = lm.report["loss"]["copied"]["total"]
    assert adam.report["loss"]["copied"]["total"] == pytest.approx(copied)
    assert adam.report["loss"]["final"]["total"] < 0.05 * copied  # Adam works ...
    assert lm.report["loss"]["final"]["total"] <= adam.report["loss"]["final"]["total"] * (1 + 1e-3)  # ... LM as well
    assert lm.report["loss"]["final_over_copied"] < 0.01
    # report numbers are the NumPy float64 loss of the returned motion
    setup = prepare(walk, remove=PAPER_REMOVE)
    from usdmotion.kinematics import local_translations

    m = lm.motion
    recomputed = frame_losses(local_translations(m), m.rotations, m.parents, setup.mapped, setup.targets, setup.weights)
    assert recomputed.sum() == pytest.approx(lm.report["loss"]["final"]["total"], rel=1e-12)


def test_local_mode_moves_only_joints_around_changed_bones(walk):
    full = retarget(walk, remove=PAPER_REMOVE)
    local = retarget(walk, remove=PAPER_REMOVE, local=True)
    moved = set(local.report["optimised_rotations"])
    # changed bones hang under Hips (legs, spine) and Spine (neck, arms): those two and
    # their ancestors move, and the children of those compensate
    assert moved == {"Hips", "Spine", "LeftUpLeg", "RightUpLeg", "Neck1", "LeftArm", "RightArm"}
    setup = prepare(walk, remove=PAPER_REMOVE)
    still = [j for j, n in enumerate(setup.rig.joint_names) if n not in moved]
    np.testing.assert_allclose(np.abs(np.sum(local.motion.rotations[:, still] * setup.inits["compose"][:, still], -1)),
                               1.0, atol=1e-6)
    final_full, final_local = full.report["loss"]["final"]["total"], local.report["loss"]["final"]["total"]
    assert final_local < 0.5 * local.report["loss"]["initial"]["total"]
    assert final_full <= final_local * (1 + 1e-4)


# ---------------------------------------------------------------------- cross-rig


@pytest.mark.parametrize("target_file, profile", [("bandai1/dataset-1_walk_normal_001.bvh", "bandai"),
                                                  ("cmu/daz_10_01_soccer_kick.bvh", "daz")])
def test_cross_rig_errors_are_what_the_report_says(walk, shared_file, target_file, profile):
    from usdmotion.io.bvh import read_bvh

    source = read_bvh(shared_file(WALK), units="asf")
    source = frames(source, 480, 16)  # around frame 493, where DAZ's neck once flipped 145°
    target = read_bvh(shared_file(target_file))
    result = retarget(source, target, target_path=target_file)
    rep, m = result.report, result.motion
    assert rep["map"]["how"] == f"rig profiles cmu_cgspeed -> {profile}"
    why = rep["map"]["unmapped_why"]  # every unmapped joint has its reason (the source has no clavicle point)
    assert sorted(why) == sorted(rep["map"]["unmapped_target_joints"])
    assert why[{"bandai": "Shoulder_L", "daz": "lCollar"}[profile]] == "no l_clavicle in the source"
    assert rep["units"]["source_scale"] == pytest.approx(0.0254 / 0.45 / 0.01)
    assert m.joint_names == target.joint_names and m.channels == target.channels
    # independent: world positions of the output vs the scaled source positions
    translations = np.broadcast_to(m.offsets, (16,) + m.offsets.shape).copy()
    if m.joint_translations is not None:
        translations = np.array(m.joint_translations)
    translations[:, 0] = m.root_translation
    mine = reference_positions(m.rotations, translations, m.parents)
    src = joint_positions(source) * rep["units"]["source_scale"]
    for name, rms in rep["per_joint_rms"].items():
        err = mine[:, m.joint_index(name)] - src[:, source.joint_index(rep["map"]["pairs"][name])]
        assert np.sqrt(np.mean(np.sum(err**2, -1))) == pytest.approx(rms, rel=1e-9, abs=1e-9)
    assert rep["loss"]["final"]["total"] < 0.9 * rep["loss"]["initial"]["total"]
    assert rep["loss"]["final"]["rms"] < 15.0  # cm: different joint centres, but the same body
    # no joint flips between frames (the loss cannot see a bone's twist about its only child)
    change = rep["largest_rotation_change_deg"]
    assert max(change["target"].values()) < 45.0, change
    dot = np.abs(np.sum(m.rotations[1:] * m.rotations[:-1], -1)).clip(0, 1)
    assert np.degrees(2 * np.arccos(dot)).max() == pytest.approx(max(change["target"].values()))
    if profile == "bandai":  # the trajectory rides on Hips' position channels; the unmapped floor root
        assert rep["optimised_translations"] == ["Hips"]  # bone joint_Root follows under the hips, turned
        hips = m.joint_index("Hips")                       # by their heading (docs/retarget.md)
        np.testing.assert_allclose(m.rotations[:, 0][:, [1, 3]], 0.0, atol=1e-12)  # a turn about Y only
        np.testing.assert_allclose(m.root_translation[:, [0, 2]], mine[:, hips][:, [0, 2]], atol=1e-9)
        assert np.ptp(m.root_translation[:, 1]) < 1e-9  # on one floor height
        moved = np.linalg.norm(mine[-1, hips] - mine[0, hips])
        assert moved > 5.0  # cm of walking in 16 frames at 120 fps


def test_keeping_target_lengths_keeps_the_target_offsets(walk, shared_file):
    from usdmotion.io.bvh import read_bvh

    source = frames(read_bvh(shared_file(WALK), units="asf"), 100, 16)
    target = read_bvh(shared_file("cmu/daz_10_01_soccer_kick.bvh"))
    result = retarget(source, target, lengths="target")
    np.testing.assert_array_equal(result.motion.offsets, target.offsets)
    bones = result.report["bone_lengths"]
    assert all(b["change"] == 0.0 for b in bones.values())


def test_up_axis_is_converted(walk):
    # the same skeleton declared Z-up: the source is rotated +90° about X into it, and the
    # copied rotations (the root turned by the same +90°) then fit exactly
    import dataclasses

    target = dataclasses.replace(walk, up_axis="Z")
    setup = prepare(walk, target)
    p = joint_positions(walk)
    rotated = np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)
    np.testing.assert_allclose(setup.targets, rotated, atol=1e-9)
    assert setup.joint_map.how == "same names"
    losses = frame_losses(setup.translations, setup.inits["copy"], setup.rig.parents, setup.mapped, setup.targets,
                          setup.weights)
    assert losses.max() < 1e-18 * np.ptp(p[0], axis=0).max() ** 2 + 1e-20

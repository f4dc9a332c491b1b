"""Contact-aware retargeting, temporal coherence and the unmapped-joint rules (issue 17).

Independent checks: float64 finite differences of the loss (new terms included) against
the analytic Jacobian the LM step uses; the tree step against a dense solve of the
autodiff Jacobian with contact and floor points; a real CMU walk onto its own skeleton
with 1.2x longer legs, measured with NumPy forward kinematics written out in the test
and the contact detector's intervals; hand-built flips and twists.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from usdmotion.kinematics import fk_arrays, joint_positions
from usdmotion.rotations import axis_angle_quat, euler_to_quat, quat_mul, quat_rotate

WALK = "cmu/cgspeed_12_01_walk.bvh"


def contact_problem(prior: bool):
    from usdmotion.ops.retarget.problem import Problem

    parents = np.array([-1, 0, 1, 2, 1, 4, 0])
    rng = np.random.default_rng(5)
    q = euler_to_quat(rng.uniform(-1.0, 1.0, (2, 7, 3)), "ZXY")
    t = rng.normal(size=(2, 7, 3))
    extra = {"prior": rng.uniform(0.5, 2.0, 4)} if prior else {}
    problem = Problem(parents, np.array([1, 2, 3, 4, 5, 6]), np.array([1.0, 0.5, 2.0, 1.0, 3.0, 1.0]),
                      np.array([0, 1, 2, 4]), np.array([0]), ("ZXY",) * 4, contact_joints=np.array([3, 5]),
                      floor_joints=np.array([2, 3, 5, 6]), up=1, floor_weight=7.0, **extra)
    targets = rng.normal(size=(2, 8, 3))
    weights = np.c_[np.broadcast_to(problem.weights, (2, 6)), rng.uniform(1.0, 5.0, (2, 2))]
    # a floor through the middle of the joints, none of them on it (the one-sided term's kink)
    _, world_p = fk_arrays(q, t, parents)
    heights = np.sort(world_p[:, [2, 3, 5, 6], 1], axis=1)
    floor = (heights[:, 1] + heights[:, 2]) / 2
    return problem, q, t, targets, weights, floor


@pytest.mark.parametrize("prior", [False, True])
def test_new_terms_gradient_matches_finite_differences(prior):
    import jax
    import jax.numpy as jnp

    from usdmotion.ops.retarget.hierarchy import ancestor_matrix
    from usdmotion.ops.retarget.rotation_terms import make_rotation_terms as make_smoothness
    from usdmotion.ops.retarget.dense_step import make_jacobian
    from usdmotion.ops.retarget.solve import make_apply, make_residuals

    problem, q, t, targets, weights, floor = contact_problem(prior)
    with jax.enable_x64(True):
        q, t, targets, weights, floor = (jnp.asarray(a, jnp.float64) for a in (q, t, targets, weights, floor))
        residuals, apply = make_residuals(problem), make_apply(problem)
        rot_terms = make_smoothness(problem)
        prior_q = residuals(q, t, targets, weights, floor)[0][:, problem.rot_joints]  # the initial guess
        if prior:  # move off the initial guess so the prior's residual is not 0
            away = jnp.asarray(np.random.default_rng(1).normal(0, 0.3, (2, problem.n_params)))
            q, t = apply(q, t, residuals(q, t, targets, weights, floor)[0], away)
        world_q, world_p, r, _, w = residuals(q, t, targets, weights, floor)
        active = np.asarray(w)[:, -4:] > 0
        assert active.any() and not active.all()  # some joints below the floor, some above

        def loss(step):  # total loss of both frames after a tangent step (B·P,)
            q2, t2 = apply(q, t, world_q, step.reshape(2, -1))
            wq2, _, _, total, _ = residuals(q2, t2, targets, weights, floor)
            if prior:
                total = total + rot_terms(wq2, jnp.zeros(2), None, prior_q)[2]
            return jnp.sum(total)

        # the analytic gradient the LM step uses: 2 Jᵀ W r (points), 2 Σ w r over rotations at or below
        jac = np.asarray(make_jacobian(problem)(world_p, w))  # √w-weighted rows
        g = 2 * np.einsum("bri,br->bi", jac, np.asarray(r * jnp.sqrt(w)[..., None]).reshape(2, -1))
        if prior:
            rot_r, rot_w, _ = rot_terms(world_q, jnp.zeros(2), None, prior_q)
            anc = ancestor_matrix(problem.parents)[problem.rot_joints][:, problem.rot_joints]
            at_or_below = (anc | np.eye(len(problem.rot_joints), dtype=bool)).astype(float)  # (R, R)
            g_rot = 2 * np.einsum("jk,bkc->bjc", at_or_below, np.asarray(rot_r * rot_w[..., None]))
            g[:, : 3 * len(problem.rot_joints)] += g_rot.reshape(2, -1)
        h = 1e-6
        eye = jnp.eye(2 * problem.n_params)
        fd = np.asarray(jax.jit(jax.vmap(lambda e: (loss(h * e) - loss(-h * e)) / (2 * h)))(eye)).reshape(2, -1)
        assert np.abs(fd).max() > 1e-2
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_tree_step_with_contact_and_floor_points_equals_the_dense_solve():
    import jax
    import jax.numpy as jnp
    from lm_reference import reference_lm_step

    from usdmotion.ops.retarget.dense_step import make_dense_step
    from usdmotion.ops.retarget.solve import make_apply, make_residuals
    from usdmotion.ops.retarget.tree_step import make_tree_step

    problem, q, t, targets, weights, floor = contact_problem(False)
    with jax.enable_x64(True):
        q, t, targets, weights, floor = (jnp.asarray(a, jnp.float64) for a in (q, t, targets, weights, floor))
        residuals, apply = make_residuals(problem), make_apply(problem)
        world_q, world_p, r, _, w = residuals(q, t, targets, weights, floor)
        below = np.asarray(w) > 0  # the active set of this iterate, held for the linear model

        def weighted(step):
            q2, t2 = apply(q, t, world_q, step)
            _, wp2, _, _, _ = residuals(q2, t2, targets, weights, floor)
            near = wp2[:, np.r_[problem.mapped, problem.contact_joints]] - targets
            # the floor term's Gauss–Newton model: the joint's projection onto the floor at this
            # iterate is held (so the step also prefers not to slide a joint that is below it)
            held = world_p[:, problem.floor_joints].at[..., 1].set(jnp.broadcast_to(floor[:, None], (2, 4)))
            lowest = wp2[:, problem.floor_joints] - held
            res = jnp.concatenate([near, lowest], axis=1)
            return (res * jnp.sqrt(jnp.where(below, w, 0.0))[..., None]).reshape(2, -1)

        zero = jnp.zeros((2, problem.n_params))
        auto = np.asarray(jax.jit(jax.jacfwd(weighted))(zero))
        auto = np.stack([auto[b, :, b] for b in range(2)])
        lam = np.array([0.01, 3.0])
        expected = reference_lm_step(auto, np.asarray(weighted(zero)), lam)
        got = np.asarray(jax.jit(make_tree_step(problem))(world_p, r, jnp.asarray(lam), w))
        np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())
        dense = np.asarray(jax.jit(make_dense_step(problem))(world_p, r, jnp.asarray(lam), w))
        np.testing.assert_allclose(dense, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


# ------------------------------------------------------- a real walk, longer legs


def scaled_legs(motion, factor: float):
    names = motion.joint_names
    offsets = motion.offsets.copy()
    for j in range(1, len(names)):
        if any(k in names[motion.parents[j]] for k in ("UpLeg", "Leg", "Foot", "Toe")):
            offsets[j] = offsets[j] * factor
    return dataclasses.replace(motion, offsets=offsets)


@pytest.fixture(scope="module")
def long_legs():
    from conftest import shared_path

    from usdmotion.io import read_motion
    from usdmotion.ops.contacts import detect_contacts
    from usdmotion.ops.retarget.pipeline import retarget

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        walk = read_motion(shared_path(WALK), units="asf")
    source = walk.with_frames(walk.rotations[1:129], walk.root_translation[1:129], None)  # 128 frames, 1.07 s
    contacts = detect_contacts(source)
    target = scaled_legs(source, 1.2)
    result = retarget(source, target, contacts=contacts, lengths="target", root_scale="legs", compare=True)
    return source, contacts, result


def test_longer_legs_keep_the_stance_feet_fixed_and_above_the_floor(long_legs):
    source, contacts, result = long_legs
    rep = result.report
    motion = result.motion

    def leg(m, name):  # summed bone lengths from the contact joint up to the hips
        j, total = m.joint_index(name), 0.0
        while m.parents[j] >= 0:
            total, j = total + np.linalg.norm(m.offsets[j]), m.parents[j]
        return total

    names = rep["contacts"]["joints"]  # same joint names on both rigs
    expected = sum(leg(motion, n) for n in names) / sum(leg(source, n) for n in names)
    assert 1.1 < expected < 1.2  # the hip offsets are not scaled
    assert rep["contacts"]["leg_ratio"] == pytest.approx(expected, rel=1e-9)
    world = joint_positions(motion) * motion.meters_per_unit  # float64 FK of the written motion
    tc_joints = [motion.joint_names.index(n) for n in rep["contacts"]["joints"]]
    up = 1
    checked = 0
    for c, j in enumerate(tc_joints):
        for a, b in contacts.intervals(c):
            if b - a < 2:
                continue
            horizontal = np.delete(world[a:b, j], up, axis=1)
            drift = np.linalg.norm(horizontal - horizontal[0], axis=1).max()
            assert drift <= 1e-2, (rep["contacts"]["joints"][c], a, b, drift)  # 1 cm (the 1 mm goal: below)
            checked += 1
    assert checked >= 2
    floor = rep["contacts"]["floor_m"]
    assert world[..., up].min() >= floor - 1e-4  # no joint below the floor (0.1 mm float32 slack)
    assert rep["quality"]["feet"]["skate_mean_cm_s"] <= 1.0
    assert rep["quality"]["floor"]["frames_below"] == 0


def test_stance_feet_fixed_to_1mm(long_legs):
    source, contacts, result = long_legs
    motion = result.motion
    world = joint_positions(motion) * motion.meters_per_unit
    for c, name in enumerate(result.report["contacts"]["joints"]):
        j = motion.joint_names.index(name)
        for a, b in contacts.intervals(c):
            horizontal = np.delete(world[a:b, j], 1, axis=1)
            assert np.linalg.norm(horizontal - horizontal[0], axis=1).max() <= 1e-3


def test_the_lm_contact_phase_wins_back_rms(long_legs, monkeypatch):
    from usdmotion.ops.retarget import pipeline

    source, contacts, result = long_legs
    monkeypatch.setattr(pipeline, "CONTACT_ITERATIONS", 0)  # the leg IK alone
    ik_only = pipeline.retarget(source, scaled_legs(source, 1.2), contacts=contacts, lengths="target",
                                root_scale="legs")
    with_phase, without = result.report["quality"], ik_only.report["quality"]
    assert with_phase["rms_cm"] < without["rms_cm"]
    assert with_phase["feet"]["skate_mean_cm_s"] <= without["feet"]["skate_mean_cm_s"] + 0.01


def test_the_upper_body_turns_back_towards_the_source_in_the_contact_phase(long_legs, monkeypatch):
    """With ``UPPER_BODY_PRIOR`` set (off by default) the contact phase also turns the spine,
    neck and arms (held near their world rotations): the body above the tilted hips matches the
    source better than with the plain solve's rotations, with no rotation step above its no-flip
    limit here."""
    from usdmotion.ops.retarget import contact_phase

    source, contacts, result = long_legs
    from usdmotion.ops.retarget.pipeline import retarget

    assert contact_phase.UPPER_BODY_PRIOR is None  # the default: the upper body keeps the plain solve's
    monkeypatch.setattr(contact_phase, "UPPER_BODY_PRIOR", 0.3)
    pulled = retarget(source, scaled_legs(source, 1.2), contacts=contacts, lengths="target", root_scale="legs")
    turned, still = pulled.report["quality"], result.report["quality"]
    assert turned["rms_cm"] < still["rms_cm"] - 0.01, (turned["rms_cm"], still["rms_cm"])
    assert not turned["flips"], turned["flips"]
    assert turned["feet"]["skate_mean_cm_s"] <= 1.0


def test_the_temporal_term_runs_with_contacts(long_legs):
    """``smooth=`` with contacts: the LM contact phase turns a subset of the joints, and the
    temporal term's per-joint weights must be cut to the same subset (they were not: a shape
    error from JAX). The result still plants the feet as the solve without the term does."""
    from usdmotion.ops.retarget.pipeline import retarget

    source, contacts, result = long_legs
    smoothed = retarget(source, scaled_legs(source, 1.2), contacts=contacts, lengths="target", root_scale="legs",
                        smooth=0.05)
    assert np.isfinite(smoothed.motion.rotations).all()
    feet, plain_feet = smoothed.report["quality"]["feet"], result.report["quality"]["feet"]
    assert feet["skate_mean_cm_s"] <= max(1.0, plain_feet["skate_mean_cm_s"] + 0.01)
    assert feet["penetration_max_cm"] <= 0.5


def test_longer_legs_scale_the_root_trajectory(long_legs):
    source, contacts, result = long_legs
    src = joint_positions(source) * source.meters_per_unit
    out = joint_positions(result.motion) * result.motion.meters_per_unit
    travelled_src = np.linalg.norm((src[-1, 0] - src[0, 0])[[0, 2]])
    travelled_out = np.linalg.norm((out[-1, 0] - out[0, 0])[[0, 2]])
    assert travelled_out == pytest.approx(result.report["contacts"]["leg_ratio"] * travelled_src, rel=0.05)


def test_rotation_steps_in_the_report_are_the_motion_s(long_legs):
    from usdmotion.ops.retarget.quality import rotation_steps, step_limits

    source, _, result = long_legs
    q = result.report["quality"]
    steps = rotation_steps(result.motion.rotations)
    limits = step_limits(source, result_setup(source, result))
    live = ~result.motion.end_sites
    flagged = {n for n, s_, lim, ok in zip(result.motion.joint_names, steps, limits, live) if ok and s_ > lim}
    assert set(q["flips"]) == flagged
    named = {n: s for n, s in zip(result.motion.joint_names, steps)}
    assert all(named[n] == pytest.approx(v["step_deg"], abs=1e-3) for n, v in q["rotation_steps"].items())


def test_no_flip_rule_on_the_solved_walk(long_legs):
    from usdmotion.ops.retarget.quality import rotation_steps, step_limits

    source, _, result = long_legs
    q = result.report["quality"]
    steps = rotation_steps(result.motion.rotations)
    assert q["flips"] == {}
    named = {n: s for n, s in zip(result.motion.joint_names, steps)}
    assert all(named[n] == pytest.approx(v["step_deg"], abs=1e-3) for n, v in q["rotation_steps"].items())
    limits = step_limits(source, result_setup(source, result))
    assert np.all(steps[~result.motion.end_sites] <= limits[~result.motion.end_sites])


def result_setup(source, result):
    """The step limits' view of a same-names retarget: every target joint follows its namesake."""
    from usdmotion.ops.retarget.hierarchy import rig_from_motion

    rig = rig_from_motion(result.motion)
    source_of = np.array([source.joint_names.index(n) for n in rig.joint_names])
    return type("Setup", (), {"rig": rig, "source_of": source_of, "weights": np.ones(rig.n_joints)})()


# ------------------------------------------------------------ rules, hand-built


def test_flip_rule_flags_a_half_turn_and_hemisphere_is_continuous():
    from usdmotion.ops.retarget.quality import rotation_steps
    from usdmotion.ops.retarget.unmapped import continuous_hemisphere

    angles = np.radians(np.r_[np.linspace(0, 20, 10), np.linspace(200, 210, 5)])  # a 180° jump at frame 10
    q = axis_angle_quat("X", angles)[:, None]
    q[::3] *= -1  # sign noise: the same rotations
    steps = rotation_steps(q)
    assert steps[0] == pytest.approx(180.0, abs=1e-6)  # from 20° to 200° in one frame
    smooth = continuous_hemisphere(q)
    assert np.all(np.sum(smooth[1:] * smooth[:-1], -1) >= 0)
    np.testing.assert_allclose(np.abs(np.sum(smooth * q, -1)), 1.0, atol=1e-12)  # same rotations


def test_twist_bones_take_their_share_of_the_driver_twist():
    from usdmotion.ops.retarget.unmapped import distribute_twist, twist_about, twist_bones

    names = ("Forearm", "ForearmTwist01", "ForearmTwist02", "Hand")
    parents = np.array([-1, 0, 0, 0])
    offsets = np.array([[0, 0, 0], [8, 0, 0], [16, 0, 0], [24, 0, 0.0]])
    driven = np.array([True, False, False, True])
    rows = twist_bones(names, parents, offsets, driven, np.zeros(4, bool))
    assert [(r[0], r[1]) for r in rows] == [(1, 3), (2, 3)]
    assert [r[2] for r in rows] == pytest.approx([1 / 3, 2 / 3])
    twist = np.radians(np.linspace(-120, 120, 9))
    swing = axis_angle_quat("Z", np.radians(30.0))
    q = np.zeros((9, 4, 4))
    q[..., 0] = 1
    q[:, 3] = quat_mul(np.broadcast_to(swing, (9, 4)), axis_angle_quat("X", twist))  # hand: swing · twist
    out = distribute_twist(q, rows)
    for j, share in ((1, 1 / 3), (2, 2 / 3)):
        np.testing.assert_allclose(twist_about(out[:, j], np.array([1.0, 0, 0])),
                                   share * twist_about(q[:, 3], np.array([1.0, 0, 0])), atol=1e-12)
        # a pure twist about the bone: the bone axis does not move
        np.testing.assert_allclose(quat_rotate(out[:, j], np.array([1.0, 0, 0])), [[1, 0, 0]] * 9, atol=1e-12)


def test_floor_root_follows_the_hips_ground_projection_and_heading():
    from usdmotion.ops.retarget.unmapped import floor_root

    parents = np.array([-1, 0, 1, 1])  # root bone, hips, spine, leg
    n = 6
    rng = np.random.default_rng(2)
    q = np.zeros((n, 4, 4))
    q[..., 0] = 1
    yaw = np.radians(np.linspace(0, 150, n))
    tilt = axis_angle_quat("X", np.radians(rng.uniform(-10, 10, n)))
    q[:, 1] = quat_mul(axis_angle_quat("Y", yaw), tilt)  # hips: heading · tilt
    q[:, 2] = euler_to_quat(rng.uniform(-0.5, 0.5, (n, 3)), "ZXY")
    t = np.zeros((n, 4, 3))
    t[:, 0] = 0.0  # the root bone stays at the origin (as solved)
    t[:, 1] = np.c_[rng.uniform(-50, 50, n), rng.uniform(80, 95, n), rng.uniform(-50, 50, n)]
    t[:, 2] = (0, 10, 0)
    t[:, 3] = (10, -40, 0)
    before_q, before_p = fk_arrays(q, t, parents)
    q2, t2 = floor_root(q, t, parents, top=1, floor=0.0, up=1, top_translates=True)
    after_q, after_p = fk_arrays(q2, t2, parents)
    np.testing.assert_allclose(after_p[:, 1:], before_p[:, 1:], atol=1e-9)  # the body does not move
    np.testing.assert_allclose(np.abs(np.sum(after_q[:, 1:] * before_q[:, 1:], -1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(after_p[:, 0], before_p[:, 1] * [1, 0, 1], atol=1e-9)  # under the hips, on the floor
    fwd = quat_rotate(q2[:, 0], np.array([0, 0, 1.0]))
    np.testing.assert_allclose(np.arctan2(fwd[:, 0], fwd[:, 2]), yaw, atol=1e-9)  # the hips' heading


# ------------------------------------------------------- contact weights and fixed points


def test_toe_fixed_point_lies_a_foot_length_from_the_ankle_s():
    from usdmotion.ops.retarget.contact_terms import foot_length_apart

    parents = np.array([-1, 0, 1, 2])  # hips, knee, ankle, toe
    offsets = np.array([[0, 0, 0], [0, -40.0, 0], [0, -40.0, 0], [0, -6.0, 12.0]])
    rig = type("Rig", (), {"parents": parents, "n_joints": 4})()
    setup = type("Setup", (), {"rig": rig, "offsets": offsets})()
    contact = np.zeros((30, 2), bool)
    contact[0:20, 0] = True  # ankle
    contact[5:28, 1] = True  # toe: later on and off (its mean lies elsewhere)
    planted = np.zeros((30, 2, 3))
    planted[:, 0] = (1.0, 8.0, 2.0)
    planted[:, 1] = (1.5, 3.0, 15.0)  # 13.01 units from the ankle's point horizontally
    out = foot_length_apart(setup, np.array([2, 3]), contact, planted, up=1)
    np.testing.assert_array_equal(out[:, 0], planted[:, 0])  # the ankle's point is kept
    toe = out[5, 1]
    length = np.linalg.norm(offsets[3])
    assert np.linalg.norm(toe - out[5, 0]) == pytest.approx(length, rel=1e-12)  # a foot's length apart
    assert toe[1] == 3.0  # at its own planted level
    heading = lambda v: np.arctan2(v[0], v[2])  # noqa: E731
    assert heading(toe - out[5, 0]) == pytest.approx(heading(planted[5, 1] - planted[5, 0]))  # same direction
    np.testing.assert_array_equal(out[5:28, 1], np.broadcast_to(toe, (23, 3)))  # one point per contact


# ------------------------------------------------------------- legs meet the contacts (leg_ik)


def test_leg_ik_puts_ankle_and_toe_on_their_points_and_keeps_the_bones():
    from usdmotion.ops.retarget.leg_ik import legs_of, place_legs

    parents = np.array([-1, 0, 1, 2, 3, 0])  # hips, thigh, knee, ankle, toe; spine
    offsets = np.array([[0, 0, 0], [10, -5, 0], [0, -40, 0], [0, -40, 0], [0, -6, 12], [0, 30, 0.0]])
    n = 40
    rng = np.random.default_rng(3)
    q = euler_to_quat(np.c_[rng.uniform(-0.3, 0.3, (n, 6, 3))].reshape(n, 6, 3) * [1, 0.3, 0.3], "ZXY")
    q[:, 2] = axis_angle_quat("X", np.radians(rng.uniform(20, 40, n)))  # a bent knee
    t = np.broadcast_to(offsets, (n, 6, 3)).copy()
    t[:, 0] = (0, 82, 0)  # the hip 77 above the floor: every point within reach
    world_p = fk_arrays(q, t, parents)[1]
    # fixed points a few cm from the solved ankle and toe, a foot's length apart, on the floor
    contact = np.ones((n, 2), bool)
    ankle = world_p[:, 3].mean(axis=0) + (2.0, 0, -1.5)
    ankle[1] = 9.0
    toe = ankle + (0, -6, 12)
    planted = np.broadcast_to(np.stack([ankle, toe]), (n, 2, 3)).copy()
    legs = legs_of(parents, np.array([3, 4]), ("left_ankle", "left_toe"), offsets, 0)
    assert [(leg.hip, leg.knee, leg.ankle, leg.toe) for leg in legs] == [(1, 2, 3, 4)]
    q2, t2, drop = place_legs(q, t, parents, 0, legs, planted, contact, np.array([9.0, 3.0]), 1, 120.0, 0.0)
    after = fk_arrays(q2, t2, parents)[1]
    assert not drop.any()
    np.testing.assert_allclose(after[:, 3], planted[:, 0], atol=1e-9)
    np.testing.assert_allclose(after[:, 4], planted[:, 1], atol=1e-9)
    np.testing.assert_array_equal(q2[:, [0, 4, 5]], q[:, [0, 4, 5]])  # only hip, knee and ankle turn
    np.testing.assert_allclose(after[:, 5], world_p[:, 5], atol=1e-12)  # the body above the legs stays
    # the knee bends the same way as solved: same side of the hip → ankle line
    def bend(p):
        along = p[:, 3] - p[:, 1]
        return np.cross(along, p[:, 2] - p[:, 1])
    assert np.all(np.sum(bend(after) * bend(world_p), axis=-1) > 0)


def test_the_snap_puts_the_legs_back_on_the_ik_points_and_leaves_the_rest_of_the_phase():
    """After the contact phase the legs go back onto where the leg IK held their contact joints:
    exactly on contact frames (the root coming down only where a raised hip cannot reach), the
    ankle a foot's length from its toe on toe-only frames and never below its level, the knee
    bending the way the phase bent it, and nothing moved on frames far from any contact."""
    from usdmotion.ops.retarget.leg_ik import legs_of, nearness
    from usdmotion.ops.retarget.leg_reach import DROP_WINDOW_S
    from usdmotion.ops.retarget.leg_snap import snap_legs

    parents = np.array([-1, 0, 1, 2, 3, 0])  # hips, thigh, knee, ankle, toe; spine
    offsets = np.array([[0, 0, 0], [10, -5, 0], [0, -40, 0], [0, -40, 0], [0, -6, 12], [0, 30, 0.0]])
    n, fps, fade_s = 120, 60.0, 0.2
    rng = np.random.default_rng(5)
    q = euler_to_quat(rng.uniform(-0.2, 0.2, (n, 6, 3)), "ZXY")
    q[:, 2] = axis_angle_quat("X", np.radians(rng.uniform(40, 50, n)))  # a bent knee: the points within reach
    t = np.broadcast_to(offsets, (n, 6, 3)).copy()
    t[:, 0] = (0, 80, 0)
    t[40:44, 0, 1] = 92.0  # the phase raised the hips for four frames: the held ankle is out of reach there
    world = fk_arrays(q, t, parents)[1]
    contact = np.zeros((n, 2), bool)
    contact[30:60, 0] = True  # ankle
    contact[30:75, 1] = True  # toe, on alone after heel-off
    low = world[:, 3, 1].min() - 0.5  # the ankle's planted level: below the phase's ankle everywhere
    ankle = np.median(world[30:60, 3], axis=0) + (0.5, 0.0, -0.5)
    toe = ankle + (0, -6, 12)
    held = world[:, [3, 4]].copy()
    held[30:60, 0] = ankle
    held[30:75, 1] = toe
    level = np.array([low, world[:, 4, 1].min() - 0.5])  # the toe's too
    legs = legs_of(parents, np.array([3, 4]), ("left_ankle", "left_toe"), offsets, 0)
    near = np.stack([nearness(contact[:, c], fade_s * fps) for c in range(2)], axis=1)  # the phase's weights
    q2, t2 = snap_legs(q, t, parents, 0, legs, held, contact, near, level, 1, fps, low - 20.0)
    after = fk_arrays(q2, t2, parents)[1]  # independent FK of the result
    np.testing.assert_allclose(after[30:60, 3], held[30:60, 0], atol=1e-9)
    np.testing.assert_allclose(after[30:75, 4], held[30:75, 1], atol=1e-9)
    foot = np.linalg.norm(offsets[4])
    np.testing.assert_allclose(np.linalg.norm(after[60:75, 3] - after[60:75, 4], axis=-1), foot, rtol=1e-9)
    assert after[:, 3, 1].min() >= low - 1e-9  # no ankle below its level
    drop = t[:, 0, 1] - t2[:, 0, 1]
    assert drop[40:44].min() > 0 and drop.min() >= 0  # the root came down where it had to, never up
    window = int(DROP_WINDOW_S * fps) + 1
    assert not drop[: 40 - window].any() and not drop[44 + window:].any()
    along = lambda p: np.cross(p[:, 3] - p[:, 1], p[:, 2] - p[:, 1])  # noqa: E731 - the knee's bend side
    assert np.all(np.sum(along(after) * along(world), axis=-1) > 0)
    far = np.r_[0:30 - int(fade_s * fps) - 1, 75 + int(fade_s * fps) + 1:n]
    np.testing.assert_allclose(after[far], world[far], atol=1e-9)
    np.testing.assert_array_equal(q2[:, [0, 5]], q[:, [0, 5]])  # only the leg turns


def test_a_toe_only_contact_turns_the_foot_about_the_toe_never_the_heel_below_its_level():
    """Where the solve's foot, pivoted about its planted toe, would put the ankle below the
    ankle's planted level (the heel through the floor), the foot turns up about the toe onto
    that level: the toe stays exactly on its point (lifted straight up, the foot missed it)."""
    from usdmotion.ops.retarget.leg_ik import legs_of, place_legs

    parents = np.array([-1, 0, 1, 2, 3, 0])  # hips, thigh, knee, ankle, toe; spine
    offsets = np.array([[0, 0, 0], [10, -5, 0], [0, -40, 0], [0, -40, 0], [0, -6, 12], [0, 30, 0.0]])
    n = 20
    q = np.zeros((n, 6, 4))
    q[..., 0] = 1.0
    q[:, 2] = axis_angle_quat("X", np.radians(np.linspace(20, 35, n)))  # a bent knee
    q[:, 3] = axis_angle_quat("X", np.radians(-50.0))  # the foot pitched toe up
    t = np.broadcast_to(offsets, (n, 6, 3)).copy()
    t[:, 0] = (0, 82, 0)
    world_p = fk_arrays(q, t, parents)[1]
    toe = world_p[:, 4].mean(axis=0) + (1.0, 0, 0)
    toe[1] = 3.0
    planted = np.broadcast_to(np.stack([world_p[:, 3].mean(axis=0), toe]), (n, 2, 3)).copy()
    contact = np.zeros((n, 2), bool)
    contact[:, 1] = True  # the toe alone is down, on every frame
    level = np.array([9.0, 3.0])
    assert (toe + world_p[:, 3] - world_p[:, 4])[:, 1].max() < level[0] - 1.0  # the solve's foot: heel below
    legs = legs_of(parents, np.array([3, 4]), ("left_ankle", "left_toe"), offsets, 0)
    q2, t2, _ = place_legs(q, t, parents, 0, legs, planted, contact, level, 1, 120.0, 0.0)
    after = fk_arrays(q2, t2, parents)[1]
    np.testing.assert_allclose(after[:, 4], planted[:, 1], atol=1e-9)
    assert after[:, 3, 1].min() >= level[0] - 1e-9
    np.testing.assert_allclose(np.linalg.norm(after[:, 4] - after[:, 3], axis=-1), np.linalg.norm(offsets[4]))


def test_an_ankle_is_planted_where_the_plain_solve_stands_it_over_its_toe():
    """The ankle's planted level is the plain solve's median height over its contact frames
    (how high an ankle stands over its toe is the target foot's), the toe's stays the source's,
    and the toe's fixed point is a foot's length from the ankle's again."""
    from types import SimpleNamespace

    from usdmotion.ops.contacts.detect import FootContacts
    from usdmotion.ops.retarget.contact_terms import ContactTerms, solved_ankle_levels

    parents = np.array([-1, 0, 1])  # hips, ankle, toe
    offsets = np.array([[0, 0, 0], [0, -80, 0], [0, -6, 12.0]])
    n = 30
    contact = np.zeros((n, 2), bool)
    contact[5:20] = True
    planted = np.zeros((n, 2, 3))
    planted[5:20] = [[0, 7.0, 0], [0, 3.0, 12.0]]
    found = FootContacts(("ankle", "toe"), np.array([1, 2]), ("left_ankle", "left_toe"), contact, 0.0,
                         np.array([0.07, 0.03]), "Y", 120.0)
    terms = ContactTerms(np.array([1, 2]), planted, np.array([7.0, 3.0]), 0.0, 1, 1.0, np.zeros((n, 3, 3)),
                         np.zeros((n, 3)), found, ())
    setup = SimpleNamespace(rig=SimpleNamespace(parents=parents, meters_per_unit=0.01, n_joints=3), offsets=offsets)
    world = np.zeros((n, 3, 3))
    world[:, 1, 1] = np.linspace(8.0, 10.0, n)  # the plain solve's ankle: median 9 over frames 5-19
    out = solved_ankle_levels(setup, terms, world)
    median = np.median(world[5:20, 1, 1])
    np.testing.assert_allclose(out.level, [median, 3.0])
    np.testing.assert_allclose(out.planted[5:20, :, 1], np.broadcast_to([median, 3.0], (15, 2)))
    np.testing.assert_allclose(np.linalg.norm(out.planted[5:20, 1] - out.planted[5:20, 0], axis=-1),
                               np.linalg.norm(offsets[2]))
    np.testing.assert_allclose(out.target_contacts.clearance, [median * 0.01, 0.03])
    np.testing.assert_array_equal(out.planted[:5], terms.planted[:5])  # off contact: as it was


def test_the_fixed_points_search_finds_the_full_grids_least_cost(monkeypatch):
    """``within_reach`` searches its 41 × 41 grid of shifts coarse to fine: on contacts whose
    points lie out of the leg's reach by various amounts it moves them exactly where the
    search of every grid point does (and does move some)."""
    from usdmotion.ops.retarget import leg_ik

    parents = np.array([-1, 0, 1, 2, 3, 0])
    offsets = np.array([[0, 0, 0], [10, -5, 0], [0, -40, 0], [0, -40, 0], [0, -6, 12], [0, 30, 0.0]])
    legs = leg_ik.legs_of(parents, np.array([3, 4]), ("left_ankle", "left_toe"), offsets, 0)
    n = 400
    rng = np.random.default_rng(7)
    contact = np.zeros((n, 2), bool)
    planted = np.zeros((n, 2, 3))
    for k, a in enumerate(range(10, n - 40, 40)):  # ten contacts of 30 frames, each at its own point
        contact[a:a + 30] = True
        ankle = np.array([rng.uniform(-20, 20), 9.0, rng.uniform(-20, 20)])
        planted[a:a + 30] = [ankle, ankle + (0, -6, 12)]
    hips = np.zeros((n, 1, 3))
    hips[:, 0] = (0, 85, 0) + rng.normal(0, 2, (n, 3))  # the ankle points 73-80 away: some out of reach
    reach = np.array([80.0])

    def full_grid(cost, steps, coarse=5):
        points = np.stack(np.meshgrid(steps, steps, indexing="ij"), -1).reshape(-1, 2)
        return points[int(np.argmin(cost(points)))]

    fast = leg_ik.within_reach(planted, contact, legs, hips, reach, 1, 50.0)
    monkeypatch.setattr(leg_ik, "_grid_minimum", full_grid)
    every = leg_ik.within_reach(planted, contact, legs, hips, reach, 1, 50.0)
    np.testing.assert_array_equal(fast, every)
    assert np.abs(fast - planted).max() > 0.5  # points did move


def test_the_leg_ik_reads_the_legs_forward_kinematics_alone_and_gets_the_same_numbers(monkeypatch):
    """The leg IK computes world transforms of the legs and what carries them only (not the
    spine, arms, head: ~1/5 of a 70-joint rig); its result is the same to the bit as with the
    whole skeleton's forward kinematics."""
    from usdmotion.ops.retarget import leg_ik

    # hips, a spine with two arms of three joints, two legs (thigh, knee, ankle, toe, toe tip)
    parents = np.array([-1, 0, 1, 2, 3, 1, 5, 0, 7, 8, 9, 10, 0, 12, 13, 14, 15])
    rng = np.random.default_rng(11)
    n, joints = 50, len(parents)
    offsets = rng.normal(0, 10, (joints, 3))
    offsets[[8, 9, 13, 14]] = (0, -40, 0)
    q = euler_to_quat(rng.uniform(-0.4, 0.4, (n, joints, 3)), "ZXY")
    t = np.broadcast_to(offsets, (n, joints, 3)).copy()
    t[:, 0] = (0, 85, 0)
    legs = leg_ik.legs_of(parents, np.array([10, 11, 15, 16]), ("left_ankle", "left_toe", "right_ankle", "right_toe"),
                          offsets, 0)
    chain = leg_ik.chain_joints(parents, legs, 0)
    np.testing.assert_array_equal(chain, [0, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16])  # no spine, no arms
    world_q, world_p = leg_ik.fk_of(q, t, parents, chain)
    full_q, full_p = fk_arrays(q, t, parents)
    np.testing.assert_array_equal(world_q[:, chain], full_q[:, chain])
    np.testing.assert_array_equal(world_p[:, chain], full_p[:, chain])
    world = full_p
    contact = np.zeros((n, 4), bool)
    contact[10:40] = True
    planted = np.zeros((n, 4, 3))
    planted[10:40] = world[25, [10, 11, 15, 16]] + (1.0, -3.0, 0.5)
    args = (q, t, parents, 0, legs, planted, contact, planted[25, :, 1] - 0.5, 1, 120.0,
            float(world[..., 1].min() - 5.0))
    chained = leg_ik.place_legs(*args)
    monkeypatch.setattr(leg_ik, "fk_of", lambda q, t, parents, joints: fk_arrays(q, t, parents))
    for a, b in zip(chained, leg_ik.place_legs(*args)):
        np.testing.assert_array_equal(a, b)


def test_root_drop_covers_the_need_and_never_steps():
    from usdmotion.ops.retarget.leg_reach import DROP_WINDOW_S, REACH, root_drop

    n, fps = 300, 120.0
    rng = np.random.default_rng(4)
    hips = np.zeros((n, 1, 3))
    hips[:, 0, 1] = 90.0
    feet = np.zeros((n, 1, 3))
    feet[:, 0, 2] = rng.uniform(-30, 30, n) * (rng.uniform(size=n) < 0.2)  # some frames far out
    drop = root_drop(hips, np.array([88.0]), feet, 1, fps)
    # brute force: per frame the lowest hip within reach
    need = np.maximum(90.0 - np.sqrt((REACH * 88.0) ** 2 - feet[:, 0, 2] ** 2), 0.0)
    assert need.max() > 1.0
    assert np.all(drop >= need - 1e-9)
    half = int(round(DROP_WINDOW_S * fps / 2))
    assert np.abs(np.diff(drop)).max() <= need.max() / (2 * half + 1) + 1e-9  # a ramp, never a step
    assert not root_drop(hips, np.array([88.0]), np.zeros((n, 1, 3)) + (0, 10, 0), 1, fps).any()  # all reachable


def test_floor_includes_the_toe_tips_that_go_below_it():
    from usdmotion.ops.retarget.contact_terms import tips_floor

    parents = np.array([-1, 0, 1, 2, 3])  # hips, knee, ankle, toe, toe tip
    n = 200
    targets = np.zeros((n, 5, 3))
    targets[:, 4, 1] = np.linspace(-3.0, 5.0, n)  # the tip's heights; its 2nd percentile ≈ -2.84
    rig = type("Rig", (), {"parents": parents})()
    setup = type("Setup", (), {"rig": rig, "targets": targets, "mapped": np.arange(5)})()
    expected = np.percentile(targets[:, 4, 1], 2.0)
    assert tips_floor(setup, np.array([2, 3]), 0.0, 1.0, 1) == pytest.approx(expected)
    assert tips_floor(setup, np.array([2, 3]), 1.0, 2.0, 1) == pytest.approx(1.0 + 2.0 * (expected - 1.0))
    setup.mapped = np.arange(4)  # the tip not mapped: the contacts' floor
    assert tips_floor(setup, np.array([3]), 0.5, 1.0, 1) == 0.5


def test_an_ankle_without_a_toe_is_planted_no_lower_than_its_foot_hangs_below_it():
    """A foot whose End Site hangs straight under the ankle (the Biovision example rig's sole
    point) plants its ankle at least as far above the floor as the End Site reaches beyond it
    along the shin in the rest pose: lower, the sole point lay under the floor and the foot was
    turned to lift it (100°/frame steps)."""
    from types import SimpleNamespace

    from usdmotion.ops.contacts.detect import FootContacts
    from usdmotion.ops.retarget.contact_terms import ContactTerms, solved_ankle_levels

    parents = np.array([-1, 0, 1])  # hips, ankle, its End Site 8 units below
    offsets = np.array([[0, 0, 0], [0, -80, 0], [0, -8.0, 0]])
    n = 30
    contact = np.zeros((n, 1), bool)
    contact[5:20] = True
    planted = np.zeros((n, 1, 3))
    planted[5:20] = [0, 3.5, 0]
    found = FootContacts(("ankle",), np.array([1]), ("left_ankle",), contact, 0.0, np.array([0.035]), "Y", 120.0)
    terms = ContactTerms(np.array([1]), planted, np.array([3.5]), 0.0, 1, 1.0, np.zeros((n, 3, 3)),
                         np.zeros((n, 3)), found, ())
    setup = SimpleNamespace(rig=SimpleNamespace(parents=parents, meters_per_unit=0.01, n_joints=3), offsets=offsets)
    out = solved_ankle_levels(setup, terms, np.zeros((n, 3, 3)))
    floor_min = 0.1  # ABOVE_FLOOR_M in target units
    np.testing.assert_allclose(out.level, [8.0 + floor_min])
    np.testing.assert_allclose(out.planted[5:20, 0, 1], 8.0 + floor_min)
    np.testing.assert_array_equal(out.planted[:5], terms.planted[:5])
    higher = dataclasses.replace(terms, level=np.array([12.0]))  # already higher than the foot hangs: kept
    assert solved_ankle_levels(setup, higher, np.zeros((n, 3, 3))).level[0] == 12.0
    # a Z-up take whose rig's rest pose lies along -Y (pybvh's 60-joint test rig: its forefoot
    # 1.44 in past the ankle along the shin, the foot turned 45.6°/frame): the reach is along the shin
    lying = dataclasses.replace(terms, up=2, planted=planted[..., [0, 2, 1]])
    np.testing.assert_allclose(solved_ankle_levels(setup, lying, np.zeros((n, 3, 3))).level, [8.0 + floor_min])


def test_a_cmu_walk_onto_the_biovision_example_rig_plants_its_toeless_feet_without_flips():
    """The Biovision example rig (``LeftUpArm``, ``LeftLowArm``, ``LeftLowLeg``, a foot with no
    toe whose End Site hangs under the ankle) was mapped by normalised names (10 joints, no
    elbows or knees), and the contact solve turned its feet by 100°/frame: the source's ankle
    height put the sole point under the floor. Now it maps through the ``biovision`` profile and
    no joint steps above its limit. Independent check: float64 forward kinematics of the written
    motion, End Sites included, against the reported floor."""
    from conftest import shared_path

    from usdmotion.io import read_motion
    from usdmotion.ops.retarget.pipeline import retarget

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        walk = read_motion(shared_path(WALK), units="asf")
        rig = read_motion(shared_path("edge_cases/bvhio_example.bvh"))
    source = walk.with_frames(walk.rotations[1:241], walk.root_translation[1:241], None)  # 2 s, both feet planted
    result = retarget(source, rig, contacts="auto")
    rep = result.report
    assert rep["map"]["how"] == "rig profiles cmu_cgspeed -> biovision"
    pairs = rep["map"]["pairs"]
    assert pairs["LeftLowLeg"] == "LeftLeg" and pairs["RightLowArm"] == "RightForeArm"
    assert sum(v is not None for v in pairs.values()) >= 16
    assert rep["contacts"]["parts"] == ["left_ankle", "right_ankle"]
    assert rep["quality"]["flips"] == {}
    motion = result.motion
    world = joint_positions(motion) * motion.meters_per_unit
    ends = [motion.joint_index(n) for n in ("LeftFoot_End", "RightFoot_End")]
    assert world[:, ends, 1].min() >= rep["contacts"]["floor_m"] - 1e-4  # the sole points on or above the floor
    assert rep["quality"]["feet"]["skate_mean_cm_s"] <= 1.0

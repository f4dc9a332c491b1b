"""Blending, its alignment helpers, and the path machinery it relies on."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from edit_support import angle_between, frame_steps, walker
from scipy.spatial.transform import Rotation, Slerp

from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions
from usdmotion.ops.edit import EditError, blend
from usdmotion.ops.edit import align as A
from usdmotion.ops.edit import trajectory as T


def test_dtw_rows_match_a_plain_dynamic_programme():
    rng = np.random.default_rng(1)
    cost = rng.uniform(size=(7, 15))
    path = A.subsequence_dtw(cost)
    # brute force: D[i, j] with free start/end along the columns, steps (1,1), (1,0), (0,1)
    d = np.full((7, 15), np.inf)
    d[0] = cost[0]
    for i in range(1, 7):
        for j in range(15):
            best = min(d[i - 1, j], d[i - 1, j - 1] if j else np.inf, d[i, j - 1] if j else np.inf)
            d[i, j] = cost[i, j] + best
    assert np.isclose(cost[path[:, 0], path[:, 1]].sum(), d[-1].min())
    assert path[0, 0] == 0 and path[-1, 0] == 6 and np.all(np.diff(path, axis=0) >= 0)


def test_dtw_finds_a_shifted_copy():
    x = np.sin(np.linspace(0, 6 * np.pi, 200))
    query = x[60:90, None]
    cost = (query - x[None, :]) ** 2
    warp = A.warp_from_path(A.subsequence_dtw(cost), 30)
    np.testing.assert_allclose(warp[3:-3], np.arange(60, 90)[3:-3], atol=0.5)


def test_peak_offset_puts_the_last_peak_on_the_first():
    t = np.arange(300.0)
    s0 = np.sin(2 * np.pi * t / 50)             # peaks at 12.5 + 50k
    s1 = np.sin(2 * np.pi * (t[:200] - 20) / 40)  # peaks at 30 + 40k
    offset = A.peak_offset(s0, s1, at=260, transition=30)
    last0 = A.peaks(s0)[A.peaks(s0) <= 275][-1]
    assert last0 in (262, 263) and offset == last0 - 30
    with pytest.raises(EditError, match="no clear peak"):
        A.peak_offset(s0, np.zeros(100), 260, 30)


def test_path_split_and_join_round_trip():
    m = walker(turn_deg_per_frame=0.4)
    local, yaw, ground = T.split_path(m)
    assert np.max(np.abs(local.root_translation[:, [0, 2]])) < 1e-9
    rot, pos = T.join_path(local, yaw, ground)
    assert np.max(angle_between(rot, m.rotations[:, 0])) < 1e-9
    np.testing.assert_allclose(pos, m.root_translation, atol=1e-9)
    y2, g2 = T.integrate(*T.steps(yaw, ground), yaw[0], ground[0])
    np.testing.assert_allclose(y2, yaw, atol=1e-12)
    np.testing.assert_allclose(g2, ground, atol=1e-9)


def test_blending_a_motion_with_itself_changes_nothing():
    m = walker(n_frames=200, turn_deg_per_frame=0.3, noise_deg=0.5)
    out = blend(m, m, transition=40, at=100, offset=0)  # same frame of both at every output frame
    assert out.n_frames == 200
    assert np.max(angle_between(out.rotations, m.rotations)) < 1e-9
    np.testing.assert_allclose(out.root_translation, m.root_translation, atol=1e-8)


def test_constant_weight_is_slerp_of_the_local_rotations():
    m0 = walker(n_frames=80, noise_deg=3, seed=1)
    m1 = walker(n_frames=80, period=45, noise_deg=3, seed=2)
    out = blend(m0, m1, keys=[(0, 0.3)])
    assert out.n_frames == 80
    for j in (3, 4, 7):
        for f in (0, 33, 79):
            key = Rotation.from_quat(np.stack([m0.rotations[f, j], m1.rotations[f, j]]), scalar_first=True)
            ref = Slerp([0, 1], key)([0.3]).as_quat(scalar_first=True)[0]
            assert angle_between(out.rotations[f, j], ref) < 1e-9
    nl = blend(m0, m1, keys=[(0, 0.3)], method="nlerp")
    assert np.degrees(np.max(angle_between(nl.rotations, out.rotations))) < 0.5  # close, not identical


def test_walk_to_run_on_real_files_is_continuous(shared_file):
    walk = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    run = read_motion(shared_file("bandai1/dataset-1_run_normal_001.bvh"))
    out = blend(walk, run, transition=10, align="peaks", align_joint="UpperLeg_L")
    p = joint_positions(out)
    step, jerk = frame_steps(p)
    step_w, jerk_w = frame_steps(joint_positions(walk))
    step_r, jerk_r = frame_steps(joint_positions(run))
    assert step.max() <= 1.1 * max(step_w.max(), step_r.max())
    assert jerk.max() <= 1.1 * max(jerk_w.max(), jerk_r.max())
    hips = out.joint_names.index("Hips")
    np.testing.assert_allclose(p[:170], joint_positions(walk)[:170], atol=1e-6)  # before the transition
    # after it: the run's poses and its own path, moved rigidly to where the walk left off
    tail = out.n_frames - 5
    pr = joint_positions(run)
    joints = ~out.end_sites  # (end-site offsets differ between the two files; the output keeps the walk's)
    rel_out = p[tail:, joints, 1] - p[tail:, hips:hips + 1, 1]
    rel_run = pr[-5:, joints, 1] - pr[-5:, hips:hips + 1, 1]
    np.testing.assert_allclose(rel_out, rel_run, atol=0.05)  # cm; the files' leg bones differ by < 0.02 cm
    travel = np.linalg.norm(np.diff(p[:, hips, [0, 2]], axis=0), axis=1)
    assert travel[-5:].mean() == pytest.approx(np.linalg.norm(np.diff(pr[:, hips, [0, 2]], axis=0), axis=1)[-5:].mean(),
                                               rel=1e-6)


def test_dtw_alignment_runs_and_stays_continuous(shared_file):
    walk = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    run = read_motion(shared_file("bandai1/dataset-1_run_normal_001.bvh"))
    out = blend(walk, run, transition=12, align="dtw")
    step, _ = frame_steps(joint_positions(out))
    assert step.max() <= 1.1 * max(frame_steps(joint_positions(walk))[0].max(),
                                   frame_steps(joint_positions(run))[0].max())


def test_subtree_blend_touches_only_the_subtree():
    m0, m1 = walker(n_frames=100), walker(n_frames=100, period=40)
    out = blend(m0, m1, transition=20, at=30, offset=0, joint="LeftUpLeg", subtree=True)
    assert out.n_frames == 100
    changed = np.any(angle_between(out.rotations, m0.rotations) > 1e-12, axis=0)
    assert [n for n, c in zip(m0.joint_names, changed) if c] == ["LeftUpLeg", "LeftLeg"]  # the foot never turns
    np.testing.assert_array_equal(out.root_translation, m0.root_translation)


def test_incompatible_inputs_are_one_line_errors():
    m0 = walker(n_frames=60)
    renamed = dataclasses.replace(m0, joint_names=tuple(n.replace("Left", "L_") for n in m0.joint_names))
    with pytest.raises(EditError, match="no joint for LeftUpLeg, LeftLeg, LeftFoot"):
        blend(m0, renamed)
    mapping = {n: n.replace("Left", "L_") for n in m0.joint_names}
    assert blend(m0, renamed, joint_map=mapping).n_frames == 90  # 0.5 s = 30 frames of overlap
    swapped = dataclasses.replace(m0, parents=np.array([-1, 0, 1, 0, 3, 4, 0, 6, 3]))
    with pytest.raises(EditError, match="RightFoot's parent is RightLeg.*LeftUpLeg"):
        blend(m0, swapped)
    with pytest.raises(EditError, match="Y-up motion with a Z-up"):
        blend(m0, dataclasses.replace(m0, up_axis="Z"))
    with pytest.raises(EditError, match="does not fit"):
        blend(m0, m0, transition=50, at=30)
    with pytest.raises(EditError, match="speed1 must be a positive number"):
        blend(m0, m0, speed1=0)
    with pytest.raises(EditError, match="peak alignment needs align_joint"):
        blend(m0, m0, align="peaks")

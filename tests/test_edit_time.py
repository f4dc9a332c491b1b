"""Speed curves, resampling, trimming and cycling."""

from __future__ import annotations

import numpy as np
import pytest
from edit_support import angle_between, frame_steps, walker
from scipy.interpolate import PchipInterpolator
from scipy.spatial.transform import Rotation, Slerp

from usdmotion.io import read_motion
from usdmotion.io.bvh_write import bvh_text
from usdmotion.kinematics import joint_positions
from usdmotion.ops.edit import EditError, cycle, resample, speed, trim
from usdmotion.ops.edit.cycle import loop_end
from usdmotion.ops.edit.timewarp import sample_rotations, speed_times


def test_constant_speed_keeps_every_other_frame():
    m = walker(n_frames=101)
    out = speed(m, 2.0)
    assert out.n_frames == 51 and out.fps == m.fps
    assert np.max(angle_between(out.rotations, m.rotations[::2])) < 1e-12
    np.testing.assert_allclose(out.root_translation, m.root_translation[::2], atol=1e-12)


def test_half_speed_slerp_matches_scipy():
    m = walker(n_frames=40)
    out = speed(m, 0.5, interp="linear")
    assert out.n_frames == 79
    for j in (0, 3, 4):
        key = Rotation.from_quat(m.rotations[:, j], scalar_first=True)
        ref = Slerp(np.arange(40.0), key)(np.arange(79) * 0.5).as_quat(scalar_first=True)
        assert np.max(angle_between(out.rotations[:, j], ref)) < 1e-9
    np.testing.assert_allclose(out.root_translation[1::2], 0.5 * (m.root_translation[:-1] + m.root_translation[1:]))


def test_cubic_beats_linear_on_a_smooth_rotation():
    t = np.arange(30.0)
    def truth(s):
        return Rotation.from_rotvec(np.stack([0.6 * np.sin(s / 4), 0.3 * np.cos(s / 5), 0.2 * s / 30], 1))

    keys = truth(t).as_quat(scalar_first=True)[:, None]
    fine = np.linspace(0, 29, 300)
    exact = truth(fine).as_quat(scalar_first=True)
    err_cubic = angle_between(sample_rotations(keys, fine, "cubic")[:, 0], exact)
    err_linear = angle_between(sample_rotations(keys, fine, "linear")[:, 0], exact)
    assert err_cubic.max() < 1e-4 and err_cubic.max() < 0.2 * err_linear.max()


def test_keyed_speed_curve_obeys_dtau_dk_equals_s():
    keys = [(0, 1.0), (50, 0.5), (100, 2.0)]
    tau = speed_times(121, keys=keys)
    s = PchipInterpolator([0, 50, 100], [1.0, 0.5, 2.0])(np.clip(tau, 0, 100))
    mid = 0.5 * (s[1:] + s[:-1])
    np.testing.assert_allclose(np.diff(tau), mid, rtol=5e-3)  # trapezoid rule on the ODE
    assert tau[0] == 0 and tau[-1] <= 120 and 120 - tau[-1] < s[-1]
    m = walker(n_frames=121)
    out = speed(m, keys=keys)
    assert out.n_frames == len(tau)


def test_speed_on_a_subtree_keeps_length_and_rest():
    m = walker(n_frames=100)
    out = speed(m, 2.0, joint="LeftUpLeg", subtree=True)
    assert out.n_frames == 100
    np.testing.assert_array_equal(out.rotations[:, 0], m.rotations[:, 0])
    assert np.max(angle_between(out.rotations[:50, 3], m.rotations[::2, 3])) < 1e-12
    assert np.max(angle_between(out.rotations[50:, 3], m.rotations[99, 3])) < 1e-12  # holds the last pose


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), "fast"])
def test_bad_speeds_are_rejected(bad):
    with pytest.raises(EditError, match="must be a (positive )?number"):
        speed(walker(n_frames=20), bad)
    with pytest.raises(EditError):
        speed(walker(n_frames=20), keys=[(0, 1.0), (10, bad)])


def test_resample_120_to_30_matches_the_decimated_file(shared_file):
    full = read_motion(shared_file("cmu14/max_14_14_exercise_routine.bvh"))
    thirty = read_motion(shared_file("cmu/max_jumping_jacks_30fps.bvh"))  # frames 0, 4, ..., 496 of it
    out = resample(trim(full, 0, 497), 30.0)
    assert out.n_frames == thirty.n_frames == 125
    assert np.degrees(np.max(angle_between(out.rotations, thirty.rotations))) < 1e-3
    np.testing.assert_allclose(out.root_translation, thirty.root_translation, atol=1e-4)
    up = resample(out, 120.0)
    assert up.n_frames == 497 and abs(up.duration - out.duration) < 1e-9


def test_trim_keeps_the_euler_values_as_read(shared_file):
    m = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    out = trim(m, 10, -10)
    assert out.n_frames == m.n_frames - 20
    rows = bvh_text(out).splitlines()[-out.n_frames:]
    original = bvh_text(m).splitlines()[-m.n_frames:]
    assert rows == original[10:-10]
    for start, stop in ((0, 0), (5, 3), (0, 10_000), (-10_000, 5)):
        with pytest.raises(EditError, match="outside|needs at least"):
            trim(m, start, stop)


# ----------------------------------------------------------------------------- cycle
def test_cycle_of_a_periodic_motion_is_its_analytic_continuation():
    period, n = 60, 12
    m = walker(n_frames=period + n + 5)  # the range [0, period + n) loops exactly
    out = cycle(m, 0, period + n, transition=n, loops=3)
    truth = walker(n_frames=3 * period + n)
    assert out.n_frames == 3 * period
    # the output starts at loop frame n: original frame n
    assert np.max(angle_between(out.rotations, truth.rotations[n:n + 3 * period])) < 1e-9
    np.testing.assert_allclose(joint_positions(out), joint_positions(truth)[n:n + 3 * period], atol=1e-9)


def test_cycle_with_turning_walk_keeps_curving_and_translation_mode_goes_straight():
    m = walker(n_frames=140, turn_deg_per_frame=0.5)  # 30° per 60-frame period
    rigid = cycle(m, 0, 72, transition=12, loops=4)
    truth = walker(n_frames=12 + 240, turn_deg_per_frame=0.5)
    np.testing.assert_allclose(joint_positions(rigid)[:, 0], joint_positions(truth)[12:252, 0], atol=0.05)
    straight = cycle(m, 0, 72, transition=12, loops=4, offset="translation")
    path = joint_positions(straight)[:, 0, [0, 2]]
    per_loop = path[60::60] - path[:-60:60]
    np.testing.assert_allclose(per_loop - per_loop[0], 0.0, atol=1e-6)  # the same world step every loop
    in_place = cycle(m, 0, 72, transition=12, loops=4, offset="none")
    assert np.ptp(in_place.root_translation[:, 2]) < np.ptp(m.root_translation[:72, 2]) + 1e-9


def test_cycle_seams_are_continuous_and_the_walk_travels(shared_file):
    m = trim(read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh")), 1)
    start, transition = 50, 30
    stop = loop_end(m, start, transition)
    assert 220 <= stop <= 240  # one gait cycle (~151 frames) + the transition
    out = cycle(m, start, stop, transition=transition, loops=4)
    period = stop - start - transition
    step, jerk = frame_steps(joint_positions(out))
    step0, jerk0 = frame_steps(joint_positions(trim(m, start, stop)))
    fade = np.concatenate([np.arange(period - transition - 1, period + 1) + k * period for k in range(3)])
    assert step[fade].max() <= 1.05 * step0.max()  # position change per frame at the seams
    assert jerk[fade[:-1]].max() <= 1.05 * jerk0.max()  # velocity change per frame at the seams
    root = out.root_translation
    per_loop = np.linalg.norm(root[period::period, [0, 2]] - root[:-period:period, [0, 2]], axis=1)
    original = np.linalg.norm(m.root_translation[start + period, [0, 2]] - m.root_translation[start, [0, 2]])
    np.testing.assert_allclose(per_loop, original, rtol=0.05)  # keeps travelling, loop after loop


def test_cycle_rejects_bad_options():
    m = walker(n_frames=100)
    with pytest.raises(EditError, match="transition must be 1..29"):
        cycle(m, 0, 60, transition=30)
    with pytest.raises(EditError, match="loops must be"):
        cycle(m, loops=0)
    with pytest.raises(EditError, match="outside"):
        cycle(m, 50, 200)
    with pytest.raises(EditError, match="offset must be"):
        cycle(m, offset="spiral")

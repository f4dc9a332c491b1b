"""Equaliser (à-trous band pyramid) and the quaternion kernels it runs on."""

from __future__ import annotations

import numpy as np
import pytest
from edit_support import angle_between, euler_wxyz, position_spectrum, walker
from scipy.ndimage import correlate1d
from scipy.spatial.transform import Rotation, Slerp

from usdmotion import quat_planes as Q
from usdmotion import rotations as R
from usdmotion.io import read_motion
from usdmotion.ops.edit import EditError, equalize, trim
from usdmotion.ops.edit.equalize import KERNEL, atrous_bands, equalize_signal, max_bands, preset_gains

RNG = np.random.default_rng(7)


def random_quats(*shape):
    q = RNG.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ----------------------------------------------------------------------------- quaternion kernels
def test_kernels_match_core_rotations_and_scipy():
    a, b = random_quats(50, 3), random_quats(50, 3)
    ac, bc = Q.to_c(a), Q.to_c(b)
    np.testing.assert_allclose(Q.from_c(Q.mul(ac, bc)), R.quat_mul(a, b), atol=1e-14)
    v = R.quat_log(a)
    np.testing.assert_allclose(Q.from_c(Q.exp(Q.to_c(v))), R.quat_exp(v), atol=1e-14)
    assert np.max(angle_between(Q.from_c(Q.exp(Q.log(ac))), a)) < 1e-7
    t = RNG.uniform(size=(50, 3))
    ours = Q.from_c(Q.slerp(ac, bc, t))
    for j in range(3):  # SciPy's Slerp between each pair (independent implementation)
        for i in range(0, 50, 7):
            key = Rotation.from_quat(np.stack([a[i, j], b[i, j]]), scalar_first=True)
            ref = Slerp([0.0, 1.0], key)([t[i, j]]).as_quat(scalar_first=True)[0]
            assert angle_between(ours[i, j], ref) < 1e-9
    v3 = RNG.normal(size=(20, 3))
    np.testing.assert_allclose(Q.rotate(Q.to_c(a[:20, 0]), v3.T).T, R.quat_rotate(a[:20, 0], v3), atol=1e-12)


def test_unwrapped_log_is_continuous_through_180_degrees():
    angle = np.radians(np.linspace(0, 340, 69))  # a full-ish turn about a fixed axis
    axis = np.array([0.36, 0.48, 0.8])
    q = np.concatenate([np.cos(angle / 2)[:, None], np.sin(angle / 2)[:, None] * axis], axis=1)
    q[1::2] *= -1  # random-looking sign flips, same rotations
    d = Q.log(Q.align_signs(Q.to_c(q)[:, :, None], axis=1))[:, :, 0].T
    np.testing.assert_allclose(d, angle[:, None] * axis, atol=1e-12)  # no wrap at 180°


# ----------------------------------------------------------------------------- pyramid
def test_atrous_levels_match_dilated_kernel_and_reconstruct():
    x = RNG.normal(size=(300, 4)).cumsum(axis=0)
    bands, low = atrous_bands(x, 5)
    np.testing.assert_allclose(low + sum(bands), x, atol=1e-12)
    g = x
    for k in range(5):  # SciPy correlate1d with the zero-inserted kernel, point-reflected borders
        kernel = np.zeros(4 * 2**k + 1)
        kernel[:: 2**k] = KERNEL
        pad = 2 * 2**k
        ext = np.concatenate([2 * g[:1] - g[pad:0:-1], g, 2 * g[-1:] - g[-2:-pad - 2:-1]])
        smooth = correlate1d(ext, kernel, axis=0, mode="nearest")[pad:-pad]
        np.testing.assert_allclose(g - smooth, bands[k], atol=1e-10)
        g = smooth


def test_gain_scales_exactly_one_band_and_borders_keep_trends():
    x = RNG.normal(size=(200, 2)).cumsum(axis=0)
    bands, _ = atrous_bands(x, 3)
    np.testing.assert_allclose(equalize_signal(x, [1, 2.5, 1]) - x, 1.5 * bands[1], atol=1e-12)
    ramp = 3.0 + 0.7 * np.arange(100.0)  # a root walking at constant speed: zero padding would bend it
    np.testing.assert_allclose(equalize_signal(ramp, [0, 0, 0, 0]), ramp, atol=1e-12)
    np.testing.assert_allclose(equalize_signal(np.full(50, 4.2), [0, 0, 0]), 4.2, atol=1e-14)


def test_band_count_and_presets_follow_length_and_fps():
    assert max_bands(24) == 4 and max_bands(10_000) == 13
    with pytest.raises(EditError, match="need at least"):
        equalize_signal(np.zeros(10), [1, 1, 1, 1])
    # band centres fps/2^(k+1.5): 120 fps → 42, 21, 10.6, 5.3 Hz; 30 fps → 10.6, 5.3 Hz
    assert preset_gains("denoise", 120, 1000)[:4] == [0.0, 0.0, 0.5, 1.0]
    assert preset_gains("denoise", 30, 1000)[:2] == [0.5, 1.0]
    assert preset_gains("jitter", 120, 1000)[:5] == [4.0, 4.0, 4.0, 2.0, 1.0]


# ----------------------------------------------------------------------------- on motions
def test_unit_gains_reproduce_a_real_motion(shared_file):
    m = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    out = equalize(m, gains=[1.0] * 6)
    assert np.max(angle_between(out.rotations, m.rotations)) < 1e-9
    assert np.max(np.abs(out.root_translation - m.root_translation)) < 1e-9


def test_zeroing_high_bands_removes_high_frequencies_but_keeps_the_low_band(shared_file):
    m = trim(read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh")), 1)  # frame 0 is a T-pose
    X0, f = position_spectrum(m)
    X1, _ = position_spectrum(equalize(m, gains=[0, 0]))  # bands above ~15 Hz at 120 fps
    high = f >= 15.0
    ratio = np.sum(np.abs(X1[high]) ** 2) / np.sum(np.abs(X0[high]) ** 2)
    assert ratio < 0.15  # measured 0.074 (−92.6 %)
    low_change = np.fft.irfft(np.where((f < 2.0)[:, None], X1 - X0, 0), n=m.n_frames, axis=0)
    assert np.max(np.abs(low_change)) < 0.05  # ASF units (≈2.8 mm); measured 0.009 units (0.5 mm)


def test_no_jump_where_an_euler_angle_wraps():
    # the root turns through ±180° (BVH Y angle wraps from +179 to -179) with capture noise
    m = walker(n_frames=240, heading_deg=150, turn_deg_per_frame=0.25, noise_deg=0.8, seed=3)
    euler = R.quat_to_euler(m.rotations[:, 0], "ZXY")
    wrapped = (np.degrees(euler[:, 2]) + 180) % 360 - 180
    assert np.max(np.abs(np.diff(wrapped))) > 300  # the file's Euler channel really jumps
    out = equalize(m, gains=[0, 0, 0])
    step = np.degrees(angle_between(out.rotations[1:, 0], out.rotations[:-1, 0]))
    step_in = np.degrees(angle_between(m.rotations[1:, 0], m.rotations[:-1, 0]))
    assert step.max() < 0.5 * step_in.max()  # smoother than the input, and no 360° jump anywhere
    # the noise is removed: the result is close to the noise-free motion under the same filter
    reference = equalize(walker(n_frames=240, heading_deg=150, turn_deg_per_frame=0.25), gains=[0, 0, 0])
    err = np.degrees(angle_between(out.rotations[:, 0], reference.rotations[:, 0]))
    noise = np.degrees(angle_between(m.rotations[:, 0], walker(240, heading_deg=150,
                                                               turn_deg_per_frame=0.25).rotations[:, 0]))
    assert err.mean() < 0.5 * noise.mean()


def test_subtree_and_joint_selection(shared_file):
    m = walker(noise_deg=1.0)
    out = equalize(m, gains=[0, 0], joint="LeftUpLeg", subtree=True)
    touched = np.any(angle_between(out.rotations, m.rotations) > 1e-9, axis=0)
    assert list(np.array(m.joint_names)[touched]) == ["LeftUpLeg", "LeftLeg", "LeftFoot"]
    np.testing.assert_array_equal(out.root_translation, m.root_translation)
    with pytest.raises(EditError, match="no joint named 'LeftUpLg'.*LeftUpLeg"):
        equalize(m, gains=[0], joint="LeftUpLg")
    with pytest.raises(EditError, match="exactly one of gains or preset"):
        equalize(m)
    with pytest.raises(EditError, match="unknown equaliser preset"):
        equalize(m, preset="loud")


def test_presets_change_amplitude_in_the_documented_direction():
    m = walker(n_frames=480, noise_deg=0.5)
    thigh = m.joint_names.index("LeftUpLeg")

    def swing(motion):
        return np.ptp(np.degrees(R.quat_log(motion.rotations[:, thigh])[:, 0]))

    assert swing(equalize(m, preset="exaggerate")) > 1.2 * swing(m)
    assert swing(equalize(m, preset="damp")) < 0.8 * swing(m)
    jitter = equalize(m, preset="jitter")
    rough = lambda mm: np.abs(np.diff(mm.rotations[:, thigh], 2, axis=0)).mean()  # noqa: E731
    assert rough(jitter) > 2 * rough(m) and rough(equalize(m, preset="denoise")) < rough(m)
    np.testing.assert_allclose(euler_wxyz(np.zeros(3)), [1, 0, 0, 0])


def test_joints_that_never_rotate_come_back_unchanged(shared_file):
    motion = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    constant = np.all(motion.rotations == motion.rotations[:1], axis=(0, 2)) & ~motion.end_sites
    assert constant.sum() >= 2  # LHipJoint, RHipJoint never rotate in cgspeed files
    edited = equalize(motion, gains=[0.0, 0.0, 2.0])
    assert np.array_equal(edited.rotations[:, constant], motion.rotations[:, constant])
    moving = ~constant & ~motion.end_sites
    assert np.abs(edited.rotations[:, moving] - motion.rotations[:, moving]).max() > 1e-3  # the rest did change

"""The per-joint summary, computed over all joints at once (``joint_summaries``), gives exactly
the numbers of the former per-joint loop: that loop is kept here, as it was, as the reference,
and the two are compared value for value (the same JSON text: exact floats, keys in the same order) on real takes of every
rig family, on takes with end sites and undefined bends, and on series with NaN and one frame."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from usdmotion.io import read_motion
from usdmotion.io.bvh import motion_from_bvh, parse_bvh
from usdmotion.ops.analyse import analyse
from usdmotion.ops.analyse.report import angle_range, joint_summaries, joint_summary, summary, write_summary

AXES = ("x", "y", "z")


# --- the per-joint loop, as report.py had it before joint_summaries -----------------------------
def _peak_ref(values, kin):
    if values.size == 0 or not np.any(np.isfinite(values)):
        return {"value": None, "frame": None, "time": None}
    i = int(np.nanargmax(values))
    return {"value": round(float(values[i]), 6), "frame": int(kin.frames[i]), "time": round(float(kin.time[i]), 6)}


def _range_ref(values):
    return {"min": round(float(np.min(values)), 4), "max": round(float(np.max(values)), 4),
            "range": round(float(np.ptp(values)), 4)}


def _angle_range_ref(degrees):
    unwrapped = np.unwrap(np.asarray(degrees, np.float64), period=360.0)
    return _range_ref(unwrapped - 360.0 * np.round(np.median(unwrapped) / 360.0))


def _joint_summary_ref(kin, j):
    speed = np.linalg.norm(kin.velocities[:, j], axis=1)
    step = np.linalg.norm(np.diff(kin.positions[:, j], axis=0), axis=1)
    out = {
        "peak_speed": _peak_ref(speed, kin),
        "mean_speed": round(float(speed.mean()), 6),
        "path_length": round(float(step.sum()), 6),
        "peak_acceleration": _peak_ref(np.linalg.norm(kin.accelerations[:, j], axis=1), kin),
        "peak_angular_speed": _peak_ref(np.linalg.norm(kin.omega[:, j], axis=1), kin),
    }
    if not kin.end_sites[j]:
        order = kin.euler_orders[j]
        out["peak_relative_angular_speed"] = _peak_ref(np.linalg.norm(kin.omega_rel[:, j], axis=1), kin)
        out["range_of_motion"] = {"euler_order": order, **{axis: _angle_range_ref(kin.euler[:, j, "xyz".index(axis)])
                                                           for axis in AXES}}
    bend = kin.bend[:, j]
    if np.all(np.isfinite(bend)):
        out["bend"] = _range_ref(bend)
    return out
# -------------------------------------------------------------------------------------------------


def _assert_same(kin, joints=None):
    idx = list(range(len(kin.joint_names))) if joints is None else joints
    expected = [_joint_summary_ref(kin, j) for j in idx]
    got = joint_summaries(kin, idx)
    for j, a, b in zip(idx, got, expected):
        # exact floats (repr round-trips), NaN equal to NaN, keys in the same order: the JSON file is unchanged
        assert json.dumps(a) == json.dumps(b), kin.joint_names[j]
    return got


TAKES = ["cmu/cgspeed_12_01_walk.bvh", "other_rigs/ad_mixamo_Boxing.bvh", "other_rigs/ad_fair1_zombie.bvh",
         "edge_cases/pybvh_bvh_test3_60joints_mixed_orders.bvh", "edge_cases/fairmotion_sinusoidal_no_end_site.bvh",
         "bandai1/dataset-1_kick_normal_001.bvh"]


@pytest.mark.parametrize("relative", TAKES)
def test_summary_of_every_joint_equals_the_per_joint_loop(shared_file, relative):
    kin = analyse(read_motion(shared_file(relative)))
    got = _assert_same(kin)
    assert any("range_of_motion" in entry for entry in got)
    # the summary's joints and the single-joint helper are the same numbers
    assert summary(kin)["joints"] == dict(zip(kin.joint_names, got))
    assert joint_summary(kin, len(kin.joint_names) - 1) == got[-1]


def test_a_subset_of_joints_in_any_order(shared_file):
    kin = analyse(read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh")))
    n = len(kin.joint_names)
    _assert_same(kin, [n - 1, 0, 5, 3, 5])  # end site first, a repeated joint


def _tiny_motion(frames: int):
    rows = "".join(f"{i} 90 {i % 3} {10 * i} {-170 + 40 * i} 0 {200 * (i % 2)} 0 {5 * i}\n" for i in range(frames))
    text = ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation "
            "Yrotation\nJOINT LeftUpLeg\n{\nOFFSET 10 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\nEnd Site\n{\n"
            f"OFFSET 0 -40 0\n}}\n}}\n}}\nMOTION\nFrames: {frames}\nFrame Time: 0.01\n{rows}")
    return motion_from_bvh(parse_bvh(text))


@pytest.mark.parametrize("frames", [2, 3, 9])
def test_short_takes_with_wrapping_angles(frames):
    kin = analyse(_tiny_motion(frames))
    got = _assert_same(kin)
    assert "range_of_motion" not in got[-1]  # the end site
    if frames == 9:  # the Z rotation swings -170 → 150 through ±180: unwrapped, not 340° wide
        assert got[0]["range_of_motion"]["z"] == angle_range(kin.euler[:, 0, 2])


def test_nan_and_infinite_values():
    """NaN frames are skipped by the peaks; a series without a finite value has no peak; a
    bend undefined at one frame has no range."""
    kin = analyse(_tiny_motion(12))
    velocities = np.array(kin.velocities)
    velocities[3, 0] = np.nan       # one NaN frame of the root
    velocities[:, 1] = np.nan       # a joint without any finite speed
    omega = np.array(kin.omega)
    omega[:, 0] = -np.inf           # no finite value: no peak
    omega[5, 1] = np.inf            # the largest value is infinite
    bend = np.array(kin.bend)
    bend[:, 0] = 12.0
    bend[4, 0] = np.nan
    changed = dataclasses.replace(kin, velocities=velocities, omega=omega, bend=bend)
    got = _assert_same(changed)
    assert got[1]["peak_speed"] == {"value": None, "frame": None, "time": None}
    assert got[0]["peak_angular_speed"]["value"] is None
    assert got[1]["peak_angular_speed"]["frame"] == 5
    assert "bend" not in got[0]


def test_summary_file_is_unchanged(shared_file, tmp_path):
    """The JSON file the analyze command writes, with the reference's joints put in, is the same bytes."""
    path = shared_file("other_rigs/ad_mixamo_Boxing.bvh")
    kin = analyse(read_motion(path))
    data = summary(kin, None, str(path))
    reference = {**data, "joints": {name: _joint_summary_ref(kin, j) for j, name in enumerate(kin.joint_names)}}
    write_summary(data, tmp_path / "new.json")
    write_summary(reference, tmp_path / "old.json")
    assert (tmp_path / "new.json").read_bytes() == (tmp_path / "old.json").read_bytes()

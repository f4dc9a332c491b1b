"""``--units auto`` / ``--up-axis auto`` and the implausible-height warning (issue 15 item 8).

The expectations are independent of the guesser: units the data README states, and
copies of a real take rescaled or turned Z-up here by exact transforms."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from usdmotion.constants import METERS_PER_UNIT
from usdmotion.io import read_motion
from usdmotion.io.bvh import read_bvh
from usdmotion.kinematics import joint_positions
from usdmotion.rotations import axis_angle_quat, quat_mul, quat_rotate
from usdmotion.units_guess import guess_body, implausible_height

WALK = "cmu/cgspeed_12_01_walk.bvh"          # README: CMU ASF units, Y-up
ZUP = "edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh"  # README: inch-scale, Z-up
CM = "other_rigs/wspr_louise_optitrack_arena.bvh"          # README: cm, Y-up


def _scaled(motion, factor):
    jt = None if motion.joint_translations is None else motion.joint_translations * factor
    return dataclasses.replace(motion, offsets=motion.offsets * factor, root_translation=motion.root_translation * factor,
                               joint_translations=jt, source_channels=None)


def _z_up(motion):
    """The same take turned Y-up → Z-up: +90° about X applied to the root (exact)."""
    turn = axis_angle_quat("X", np.pi / 2)
    rotations = np.array(motion.rotations)
    rotations[:, 0] = quat_mul(turn, rotations[:, 0])
    return dataclasses.replace(motion, rotations=rotations, root_translation=quat_rotate(turn, motion.root_translation),
                               source_channels=None)


def test_guesses_match_the_data_readme(shared_file):
    for name, units, up in ((WALK, "asf", "Y"), (ZUP, "in", "Z"), (CM, "cm", "Y")):
        guess = guess_body(read_bvh(shared_file(name)))
        assert (guess.units, guess.up_axis) == (units, up), (name, guess)


@pytest.mark.parametrize(("factor", "units"), [(METERS_PER_UNIT["asf"], "m"), (METERS_PER_UNIT["asf"] / 0.01, "cm"),
                                               (METERS_PER_UNIT["asf"] / 0.001, "mm")])
def test_a_rescaled_take_is_guessed_in_its_new_unit(shared_file, factor, units):
    guess = guess_body(_scaled(read_bvh(shared_file(WALK)), factor))
    assert guess.units == units, guess.units_reason


def test_a_take_turned_z_up_is_guessed_z_up(shared_file):
    motion = _z_up(read_bvh(shared_file(CM)))
    heads = joint_positions(motion)[:, motion.joint_index("Head")]
    assert np.median(heads[:, 2]) > np.median(np.abs(heads[:, 1]))  # really stands along Z now
    assert guess_body(motion).up_axis == "Z"


def test_read_motion_auto_states_the_guess_and_its_reason(shared_file):
    with pytest.warns(UserWarning) as record:
        motion = read_motion(shared_file(ZUP), units="auto", up_axis="auto")
    text = "\n".join(str(w.message) for w in record)
    assert motion.meters_per_unit == METERS_PER_UNIT["in"] and motion.up_axis == "Z"
    assert "--units auto: in (the ankle-to-head chain is" in text and "--up-axis auto: Z (the head" in text
    assert "IMPLAUSIBLE" not in text


def test_implausible_units_warn_loudly(shared_file):
    with pytest.warns(UserWarning, match=r"IMPLAUSIBLE UNITS: at 0.01 m per unit this person is 0.2\d m tall.*"
                                         r"--units asf"):
        read_motion(shared_file(WALK), units="cm")  # CMU units read as cm: a 26 cm person
    assert implausible_height(read_bvh(shared_file(CM))) is None


def test_no_guess_for_a_non_human_skeleton_keeps_the_defaults(shared_file):
    with pytest.warns(UserWarning, match="no guess, keeping 0.01 m per unit"):
        motion = read_motion(shared_file("edge_cases/fairmotion_sinusoidal_no_end_site.bvh"), units="auto")
    assert motion.meters_per_unit == 0.01


@pytest.mark.parametrize(("name", "units", "up", "warned"), [
    (WALK, "asf", "Y", ["units guessed from the body: asf (the ankle-to-head chain is"]),
    (ZUP, "in", "Z", ["units guessed from the body: in", "up axis guessed from the body: Z (the head"]),
    (CM, "cm", "Y", []),
    ("edge_cases/fairmotion_sinusoidal_no_end_site.bvh", "cm", "Y", [])])
def test_auto_is_the_default_for_bvh_and_warns_only_where_it_changes_cm_y_up(shared_file, name, units, up, warned):
    """Without --units/--up-axis a BVH reads in the units and up axis the data README states
    (a non-human skeleton keeps cm, Y-up); a warning states the guess and its reason only where
    it is not the nominal cm / Y-up, and nothing is implausible."""
    import warnings

    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        motion = read_motion(shared_file(name))
    texts = [str(w.message) for w in record]
    assert motion.meters_per_unit == METERS_PER_UNIT[units] and motion.up_axis == up
    assert len(texts) == len(warned) and all(any(w in t for t in texts) for w in warned), texts
    explicit = read_motion(shared_file(name), units=units, up_axis=up)
    assert np.array_equal(joint_positions(explicit), joint_positions(motion))


def test_info_shows_the_guess_and_its_reason(shared_file, capsys):
    from usdmotion.cli import main

    assert main(["info", str(shared_file(ZUP)), "--json"]) == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    assert doc["units"] == "in" and doc["up_axis"] == "Z"
    assert doc["guessed"]["units"]["value"] == "in" and "ankle-to-head chain" in doc["guessed"]["units"]["reason"]
    assert doc["guessed"]["up_axis"]["value"] == "Z" and "+Z from the ankles" in doc["guessed"]["up_axis"]["reason"]
    assert main(["info", str(shared_file(ZUP)), "--units", "in", "--up-axis", "Z", "--json"]) == 0
    assert "guessed" not in json.loads(capsys.readouterr().out)


def test_a_bvh_without_frames_reads_with_the_default_guess(tmp_path):
    """The up-axis guess uses the rest pose when there is no frame (default reading)."""
    from usdmotion.io.bvh_write import write_bvh

    walk = read_bvh(Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh")
    path = write_bvh(walk.sliced(0, 0), tmp_path / "empty.bvh")
    motion = read_motion(path)
    assert motion.n_frames == 0 and motion.up_axis == "Y" and motion.meters_per_unit == METERS_PER_UNIT["asf"]


def test_the_median_of_the_up_guess_is_numpys_median():
    """``_median_rows`` (no numpy.ma import) gives ``np.median(a, axis=0)``'s numbers, NaN included."""
    from usdmotion.units_guess import _median_rows

    rng = np.random.default_rng(11)
    for n in (1, 2, 3, 4, 100, 101):
        for _ in range(50):
            a = rng.normal(size=(n, 3)) * rng.choice([1e-3, 1.0, 1e5])
            if rng.random() < 0.2:
                a[rng.integers(n), rng.integers(3)] = np.nan
            assert np.array_equal(_median_rows(a), np.median(a, axis=0), equal_nan=True)


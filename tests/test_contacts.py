"""Foot contacts: the detector against a walk with contacts known by construction, its
hysteresis and minimum durations against a plain state machine, the metrics against
hand-built trajectories, the JSON form against its schema, and the ``contacts`` command."""

from __future__ import annotations

import dataclasses
import json

import jsonschema
import numpy as np
import pytest
from contacts_support import ANKLE_HEIGHT, TOE_HEIGHT, synthetic_walk

from usdmotion.cli import main
from usdmotion.errors import InputError
from usdmotion.io import write_motion
from usdmotion.kinematics import joint_positions
from usdmotion.ops.contacts import ContactThresholds, detect_contacts, foot_metrics
from usdmotion.ops.contacts.detect import clean_runs, heel_off, hysteresis, runs
from usdmotion.ops.contacts.files import read_contacts_json, write_contacts_json
from usdmotion.schemas import schema


def reference_hysteresis(enter: np.ndarray, stay: np.ndarray) -> np.ndarray:
    """A forward-backward state machine, one frame at a time (the independent reference)."""
    out = np.zeros_like(enter)
    for order in (range(len(enter)), range(len(enter) - 1, -1, -1)):
        on = False
        for f in order:
            on = enter[f] or (on and stay[f])
            out[f] |= on
    return out


def reference_clean(mask: np.ndarray, min_frames: int, min_gap: int) -> np.ndarray:
    out = mask.copy()
    spans = [(a, b) for a, b in runs(mask)]
    for (a0, b0), (a1, b1) in zip(spans, spans[1:]):
        if a1 - b0 < min_gap:
            out[b0:a1] = True
    for a, b in runs(out):
        if b - a < min_frames:
            out[a:b] = False
    return out


@pytest.mark.parametrize("fps", [120.0, 30.0])
def test_synthetic_walk_contacts_found_within_two_frames(fps):
    motion, truth = synthetic_walk(fps)
    found = detect_contacts(motion)
    assert found.parts == ("left_ankle", "left_toe", "right_ankle", "right_toe")
    assert found.joints == ("LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase")
    assert found.floor == pytest.approx(TOE_HEIGHT, abs=1e-6)  # the floor is where the toes stand
    assert found.clearance == pytest.approx([ANKLE_HEIGHT - TOE_HEIGHT, 0, ANKLE_HEIGHT - TOE_HEIGHT, 0], abs=1e-6)
    for c, joint in enumerate(found.joints):
        expected, got = runs(truth[joint]), found.intervals(c)
        assert len(got) == len(expected) >= 4, joint
        assert np.abs(got - expected).max() <= 2, (joint, expected.tolist(), got.tolist())


def test_given_floor_gives_the_same_contacts_on_a_raised_walk():
    motion, truth = synthetic_walk(120.0, floor=0.5)
    estimated, given = detect_contacts(motion), detect_contacts(motion, floor=0.5)
    assert estimated.floor == pytest.approx(0.5 + TOE_HEIGHT, abs=1e-6)
    assert given.clearance == pytest.approx([ANKLE_HEIGHT, TOE_HEIGHT] * 2, abs=1e-6)
    assert np.array_equal(estimated.contact, given.contact)
    assert np.array_equal(estimated.contact, detect_contacts(synthetic_walk(120.0)[0]).contact)


def test_hysteresis_matches_a_state_machine():
    rng = np.random.default_rng(7)
    for _ in range(200):
        f = int(rng.integers(1, 40))
        stay = rng.random((f, 3)) < 0.6
        enter = stay & (rng.random((f, 3)) < 0.2)
        got = hysteresis(enter, stay)
        want = np.stack([reference_hysteresis(enter[:, c], stay[:, c]) for c in range(3)], axis=1)
        assert np.array_equal(got, want)


@pytest.mark.parametrize("min_frames, min_gap", [(1, 0), (3, 0), (1, 3), (4, 2), (6, 6)])
def test_minimum_duration_and_gap_match_a_loop(min_frames, min_gap):
    rng = np.random.default_rng(min_frames * 10 + min_gap)
    for _ in range(100):
        mask = rng.random((int(rng.integers(1, 50)), 2)) < 0.55
        got = clean_runs(mask, min_frames, min_gap)
        want = np.stack([reference_clean(mask[:, c], min_frames, min_gap) for c in range(2)], axis=1)
        assert np.array_equal(got, want)


def test_edge_cases_of_the_rule():
    enter = np.array([[0, 0, 1, 0, 0, 0, 0, 0]], bool).T
    stay = np.array([[0, 1, 1, 1, 0, 1, 1, 0]], bool).T
    assert hysteresis(enter, stay)[:, 0].tolist() == [0, 1, 1, 1, 0, 0, 0, 0]  # the run without an entry stays off
    # a contact of exactly the minimum length survives, one frame shorter does not
    mask = np.array([[1, 1, 1, 0, 0, 1, 1, 0]], bool).T
    assert clean_runs(mask, 3, 0)[:, 0].tolist() == [1, 1, 1, 0, 0, 0, 0, 0]
    # a gap at the start or end of the take is never "between two contacts"
    mask = np.array([[0, 1, 1, 0, 1, 1, 0]], bool).T
    assert clean_runs(mask, 1, 2)[:, 0].tolist() == [0, 1, 1, 1, 1, 1, 0]
    assert clean_runs(np.zeros((0, 2), bool), 3, 3).shape == (0, 2)


def test_heel_off_drops_a_contact_it_trims_below_the_minimum():
    # a 9-frame ankle contact whose heel is 1 cm up (toe planted) in its last 4 frames
    contact = np.zeros((12, 2), bool)
    contact[2:11] = True
    heights = np.zeros((12, 2))
    heights[7:11, 0] = 0.01
    parts = ("left_ankle", "left_toe")
    assert runs(heel_off(contact, heights, parts, min_frames=5)[:, 0]).tolist() == [[2, 7]]
    assert not heel_off(contact, heights, parts, min_frames=6)[:, 0].any()  # 5 frames left < 6: dropped
    assert np.array_equal(heel_off(contact, heights, parts, min_frames=6)[:, 1], contact[:, 1])  # the toe's stays


def test_no_contact_is_shorter_than_the_minimum_duration():
    # ankles with 4 mm of height noise: heel-off trims some contacts (seed 5: left ankle 186-191,
    # 5 frames at 120 fps, before the minimum was applied after heel-off too)
    motion, _ = synthetic_walk(120.0)
    for seed in range(8):
        rng = np.random.default_rng(seed)
        translations = motion.joint_translations.copy()
        for ankle in (12, 16):
            translations[:, ankle, 1] += rng.normal(0.0, 0.004, motion.n_frames)
        found = detect_contacts(dataclasses.replace(motion, joint_translations=translations))
        shortest = int(np.ceil(found.thresholds.min_duration * motion.fps - 1e-9))
        for c, part in enumerate(found.parts):
            lengths = np.diff(found.intervals(c), axis=1)
            assert lengths.size and lengths.min() >= shortest, (seed, part, found.intervals(c).tolist())


def test_thresholds_are_checked():
    with pytest.raises(ValueError, match="exit thresholds must be at least"):
        ContactThresholds(height_enter=0.1)
    with pytest.raises(ValueError, match="speed_enter must be a finite number"):
        ContactThresholds(speed_enter=float("nan"))


def _one_joint_contacts(contact, floor=0.0, clearance=0.0):
    motion, _ = synthetic_walk(120.0, seconds=0.5)
    found = detect_contacts(motion, joints=("LeftFoot",))
    contact = np.asarray(contact, bool)[:, None]
    return dataclasses.replace(found, contact=contact, floor=floor, clearance=np.array([clearance]),
                               indices=np.array([0]))


def test_foot_skate_of_a_known_slide():
    fps, n = 100.0, 50
    positions = np.zeros((n, 1, 3))
    positions[:, 0, 0] = np.arange(n) * 0.03 / fps  # 3 cm/s along x
    positions[:, 0, 1] = np.arange(n) * 0.5 / fps  # rising 50 cm/s: the up axis does not count
    positions[25:, 0, 2] = 0.001 * np.arange(25)  # 10 cm/s along z in the second half
    contact = np.zeros(n, bool)
    contact[5:20] = True
    contact[30:40] = True
    metrics = foot_metrics(positions, fps, _one_joint_contacts(contact))
    slow, fast = 14, 9  # steps with both frames in contact
    assert metrics.contact_steps == slow + fast
    assert metrics.skate_mean_cm_s == pytest.approx((slow * 3 + fast * np.hypot(3, 10)) / (slow + fast))
    assert metrics.skate_max_cm_s == pytest.approx(np.hypot(3, 10))
    assert metrics.skate_share == 1.0
    positions[:, 0, :] = 0.005 * np.sin(np.arange(n))[:, None] * [1, 0, 0] * 0  # still: no skate
    assert foot_metrics(positions, fps, _one_joint_contacts(contact)).skate_share == 0.0


def test_penetration_and_floating_of_known_heights():
    n = 40
    heights = np.full(n, 0.10)  # floor 0.02 + clearance 0.08: exactly planted
    heights[10:13] = [0.095, 0.088, 0.0995]  # 0.5 cm, 1.2 cm and 0.05 cm (within tolerance) below
    heights[20:30] = 0.13  # 3 cm above during contact frames 20..29
    positions = np.zeros((n, 1, 3))
    positions[:, 0, 1] = heights
    contact = np.zeros(n, bool)
    contact[15:35] = True
    metrics = foot_metrics(positions, 120.0, _one_joint_contacts(contact, floor=0.02, clearance=0.08))
    assert metrics.penetration_max_cm == pytest.approx(1.2)
    assert metrics.penetration_frames == 2
    assert metrics.floating_frames == 10 and metrics.contact_frames == 20
    assert metrics.floating_share == pytest.approx(0.5)


def test_json_round_trip_validates_against_the_schema(tmp_path):
    motion, _ = synthetic_walk(120.0)
    found = detect_contacts(motion)
    path = tmp_path / "c.json"
    write_contacts_json(found, path, "walk.bvh")
    jsonschema.validate(json.loads(path.read_text()), schema("contacts"))
    back = read_contacts_json(path, motion)
    for name in ("joints", "parts", "up", "fps", "floor", "thresholds"):
        assert getattr(back, name) == getattr(found, name), name
    for name in ("indices", "contact", "clearance"):
        assert np.array_equal(getattr(back, name), getattr(found, name)), name
    assert back.thresholds == found.thresholds


@pytest.mark.parametrize("change, message", [
    (lambda d: d["joints"][0].update(intervals=[[10, 5]]), r"/joints/0/intervals/0: \[10, 5\] is not a sorted"),
    (lambda d: d["joints"][0].update(intervals=[[0, 9999]]), r"is not a sorted, non-overlapping frame range"),
    (lambda d: d["joints"][0].update(name="Nope"), r"/joints: the motion has no joint named 'Nope'"),
    (lambda d: d.update(frames=7), r"/frames: the contacts are for 7 frames, the motion has 480"),
    (lambda d: d.update(up_axis="X"), r"/up_axis: 'X' is not one of"),
    (lambda d: d.update(frames=480.0, joints=[dict(d["joints"][0], intervals=[[3.0, 1.0]])]), r"\[3, 1\] is not"),
    (lambda d: d.update(thresholds=dict(d["thresholds"], speed_exit=0.01)), r"/thresholds: the exit thresholds"),
    # a retarget planted the feet 1e20 m up with these (exit 0, a warning)
    (lambda d: d.update(floor_m=1e20), r"/floor_m: 1e\+20 m is above the feet in every frame"),
    (lambda d: d["joints"][1].update(clearance_m=1e6), r"/joints/1/clearance_m: planted at 1e\+06 m, above everywhere"),
])
def test_bad_contacts_files_are_refused_with_the_path(tmp_path, change, message):
    motion, _ = synthetic_walk(120.0)
    path = tmp_path / "c.json"
    write_contacts_json(detect_contacts(motion), path)
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=message):
        read_contacts_json(path, motion)


def test_cli_table_json_and_plot(tmp_path, capsys):
    motion, truth = synthetic_walk(120.0)
    source = tmp_path / "walk.bvh"
    write_motion(motion, source)
    out, plot = tmp_path / "c.json", tmp_path / "c.png"
    assert main(["contacts", str(source), "--units", "m", "--json", str(out), "--plot", str(plot)]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[-1].startswith("foot skate 0.00 cm/s mean (max 0.0; 0 % of planted steps > 2 cm/s), "
                                "penetration 0.00 cm max (0 frames), floating 0 %")  # the walk is clean
    rows = {line.split()[0]: line.split() for line in table[2:-1]}
    assert set(rows) == {"LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase"}
    for joint, row in rows.items():
        true_spans = runs(truth[joint])
        assert int(row[2]) == len(true_spans)
        assert float(row[3]) == pytest.approx(truth[joint].sum() / 120.0, abs=2 * len(true_spans) / 120.0)
    document = json.loads(out.read_text())
    jsonschema.validate(document, schema("contacts"))
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and plot.stat().st_size > 20_000
    assert main(["contacts", str(source), "--units", "m", "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["joints"] == document["joints"]


@pytest.mark.parametrize("args, message", [
    (["missing.bvh"], r"missing\.bvh: cannot read"),
    (["{walk}", "--height-enter", "0.2"], r"the exit thresholds must be at least the enter thresholds"),
    (["{walk}", "--plot", "{tmp}/c.gif"], r"unknown image format '\.gif'"),
    (["{walk}", "--floor", "nan"], r"floor height must be a finite number"),
    # every frame counted as penetrating the floor, exit 0, before
    (["{walk}", "--floor", "1e20"], r"floor height 1e\+20 m is above the feet in every frame \(their lowest point "
                                    r"reaches at most 0\.\d+ m, up axis Y\)"),
    (["{walk}", "--plot", "{tmp}/walk.bvh.png", "--json", "{walk}"], r"walk\.bvh: output would overwrite the input"),
])
def test_cli_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, args, message):
    motion, _ = synthetic_walk(120.0)
    write_motion(motion, tmp_path / "walk.bvh")
    args = [a.format(walk=tmp_path / "walk.bvh", tmp=tmp_path) for a in args]
    before = set(tmp_path.iterdir())
    json_out = [] if "--json" in args else ["--json", str(tmp_path / "c.json")]
    assert main(["contacts", *args, "--units", "m", *json_out]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("usdmotion: error: ")
    assert __import__("re").search(message, err[0]), err[0]
    assert set(tmp_path.iterdir()) == before


def test_cmu_walk_contacts_alternate(shared_file):
    from usdmotion.io import read_motion

    walk = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"), units="asf")
    found = detect_contacts(walk)
    assert found.joints == ("LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase")
    ankles = found.contact[:, [0, 2]]
    assert 0.35 < ankles.mean() < 0.65  # a walk: each foot planted about half the time
    assert np.all(found.contact.any(axis=1)[30:-30])  # walking: never both feet in the air
    heights = joint_positions(walk)[:, found.indices, 1] * walk.meters_per_unit
    assert np.all(heights[found.contact] - found.floor - found.clearance[np.nonzero(found.contact)[1]] < 0.05)


def test_contacts_move_to_another_rig_by_part():
    from conftest import TEST_DATA

    from usdmotion.io import read_motion
    from usdmotion.ops.contacts import contacts_on_rig

    motion, _ = synthetic_walk(120.0)
    found = detect_contacts(motion)
    rig = read_motion(TEST_DATA / "rigs" / "unreal.bvh")  # ankle 9 cm, ball 2 cm above the floor at rest
    moved = contacts_on_rig(found, rig, floor=0.0)
    assert moved.joints == ("foot_l", "ball_l", "foot_r", "ball_r") and moved.parts == found.parts
    assert moved.clearance == pytest.approx([0.07, 0.0, 0.07, 0.0], abs=1e-9)
    assert np.array_equal(moved.contact, found.contact) and moved.floor == 0.0
    assert [rig.joint_names[i] for i in moved.indices] == list(moved.joints)
    only_ankles = dataclasses.replace(found, joints=found.joints[::2], indices=found.indices[::2],
                                      parts=found.parts[::2], contact=found.contact[:, ::2],
                                      clearance=found.clearance[::2])
    assert contacts_on_rig(only_ankles, rig).joints == ("foot_l", "foot_r")
    with pytest.raises(InputError, match="2 contact joints in common but 3 clearances"):
        contacts_on_rig(only_ankles, rig, clearance=np.zeros(3))


def test_contacts_on_a_rig_with_clearances_from_its_motion():
    from usdmotion.ops.contacts import contacts_on_rig

    motion, _ = synthetic_walk(120.0, floor=0.5)
    found = detect_contacts(motion, floor=0.5)
    same = contacts_on_rig(found, motion, clearance="motion")
    assert same.clearance == pytest.approx(found.clearance, abs=1e-12)
    assert same.clearance == pytest.approx([ANKLE_HEIGHT, TOE_HEIGHT] * 2, abs=1e-6)
    with pytest.raises(ValueError, match="clearance must be 'rest', 'motion' or an array"):
        contacts_on_rig(found, motion, clearance="floor")


def test_below_floor_of_any_joint():
    from usdmotion.ops.contacts import below_floor

    positions = np.zeros((5, 3, 3))
    positions[..., 2] = 0.5  # Z up, everything 50 cm above a floor at 0.1 m
    positions[1, 2, 2] = 0.08  # 2 cm under
    positions[3, 0, 2] = 0.0995  # 0.05 cm under: within the 1 mm tolerance
    depth, frames = below_floor(positions, 0.1, "Z")
    assert depth == pytest.approx(2.0) and frames == 1
    assert below_floor(positions, 0.1, "Y") == (pytest.approx(10.0), 5)  # Y holds 0: all 10 cm under


def test_z_up_walk_gives_the_same_contacts():
    motion, truth = synthetic_walk(120.0)
    turn = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)  # +90° about X: Y-up -> Z-up
    zup = dataclasses.replace(motion, offsets=motion.offsets @ turn.T,
                              root_translation=motion.root_translation @ turn.T,
                              joint_translations=motion.joint_translations @ turn.T, up_axis="Z")
    assert np.allclose(joint_positions(zup)[..., 2], joint_positions(motion)[..., 1])
    a, b = detect_contacts(motion), detect_contacts(zup)
    assert np.array_equal(a.contact, b.contact) and b.up == "Z" and b.floor == pytest.approx(a.floor)


def test_contacts_files_never_crash_the_reader(tmp_path):
    """Random edits of a valid contacts file: read back, or refused with one InputError."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    motion, _ = synthetic_walk(30.0, seconds=1.0)
    path = tmp_path / "c.json"
    write_contacts_json(detect_contacts(motion), path)
    valid = json.loads(path.read_text())
    values = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=False),
                       st.text(max_size=5), st.lists(st.integers(-5, 40), max_size=3))
    keys = st.sampled_from(["frames", "fps", "floor_m", "up_axis", "version", "thresholds", "joints", "junk"])
    joint_keys = st.sampled_from(["name", "part", "clearance_m", "intervals", "contacts"])

    @settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(top=st.dictionaries(keys, values, max_size=2), joint=st.dictionaries(joint_keys, values, max_size=2),
           speed=st.floats(allow_nan=False, allow_infinity=False))
    def check(top, joint, speed):
        doc = json.loads(json.dumps(valid))
        doc.update(top)
        if isinstance(doc.get("joints"), list) and doc["joints"] and isinstance(doc["joints"][0], dict):
            doc["joints"][0].update(joint)
        if isinstance(doc.get("thresholds"), dict):
            doc["thresholds"]["speed_enter"] = speed
        path.write_text(json.dumps(doc))
        try:
            read_contacts_json(path, motion)
        except InputError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(str(path))

    check()


def test_feet_of_a_rig_no_profile_knows_come_from_the_roles():
    from usdmotion.skeleton_names import detect_profile

    motion, _ = synthetic_walk(120.0)
    renamed = dataclasses.replace(motion, joint_names=tuple(
        n[4:] + ".L" if n.startswith("Left") else n[5:] + ".R" if n.startswith("Right") else n
        for n in motion.joint_names))
    assert detect_profile(motion.joint_names) == "humanik" and detect_profile(renamed.joint_names) is None
    a, b = detect_contacts(motion), detect_contacts(renamed)
    assert b.joints == ("Foot.L", "ToeBase.L", "Foot.R", "ToeBase.R")
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.contact, b.contact)
    with pytest.raises(InputError, match="cannot find the feet for contacts: cannot find the joints for role"):
        detect_contacts(dataclasses.replace(motion, joint_names=tuple(f"j{k}" for k in range(motion.n_joints))),
                        source="x.bvh")


def test_a_rig_with_heels_gets_heel_contacts(monkeypatch):
    import copy

    from usdmotion import skeleton_names
    from usdmotion.motion import Motion

    motion, truth = synthetic_walk(120.0)
    n, j = motion.n_frames, motion.n_joints
    feet = [motion.joint_index("LeftFoot"), motion.joint_index("RightFoot")]
    heel = np.array([0.0, -0.06, -0.05])  # 6 cm below and 5 cm behind the ankle: on the floor with it
    translations = np.concatenate([motion.joint_translations, np.broadcast_to(heel, (n, 2, 3))], axis=1)
    rotations = np.concatenate([motion.rotations, motion.rotations[:, :2]], axis=1)
    with_heels = Motion(motion.joint_names + ("LeftHeel", "RightHeel"), np.concatenate([motion.parents, feet]),
                        np.concatenate([motion.offsets, [heel, heel]]), rotations, motion.root_translation, motion.fps,
                        joint_translations=translations, meters_per_unit=1.0)
    profiles = copy.deepcopy(skeleton_names.rig_profiles())
    profiles["humanik"]["joints"].update(l_heel="LeftHeel", r_heel="RightHeel")
    monkeypatch.setattr(skeleton_names, "rig_profiles", lambda: profiles)
    found = detect_contacts(with_heels)
    assert found.parts == ("left_heel", "left_ankle", "left_toe", "right_heel", "right_ankle", "right_toe")
    assert found.joints[0] == "LeftHeel" and found.indices[0] == j
    for heel_c, ankle in ((0, "LeftFoot"), (3, "RightFoot")):
        assert np.abs(found.intervals(heel_c) - runs(truth[ankle])).max() <= 2

"""Segmentation: role map, bone-angle feature, the paper's heuristic, kernel change points,
synthetic takes with known cuts, and the one-to-one scoring rule."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.errors import InputError
from usdmotion.kinematics import joint_positions
from usdmotion.motion import Motion
from usdmotion.ops.segment import roles as R
from usdmotion.ops.segment import detect as S
from usdmotion.ops.segment.evaluate import Labels, activity_ranges, load_labels, reordered_take, score_cuts, synthetic_take
from usdmotion.rotations import axis_angle_quat

# A tiny humanoid: limbs hang along -Y, the spine points +Y, so every bone angle is π at rest.
NAMES = ("Hips", "Chest", "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand",
         "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")
PARENTS = np.array([-1, 0, 1, 2, 3, 1, 5, 6, 0, 8, 9, 0, 11, 12])
OFFSETS = np.array([[0, 0, 0], [0, 10, 0], [5, 0, 0], [0, -5, 0], [0, -5, 0], [-5, 0, 0], [0, -5, 0], [0, -5, 0],
                    [3, 0, 0], [0, -8, 0], [0, -8, 0], [-3, 0, 0], [0, -8, 0], [0, -8, 0]], float)


def tiny_motion(rotations: np.ndarray, root=None, fps: float = 30.0) -> Motion:
    n = rotations.shape[0]
    root = np.zeros((n, 3)) if root is None else root
    return Motion(joint_names=NAMES, parents=PARENTS, offsets=OFFSETS, rotations=rotations, root_translation=root,
                  fps=fps)


def identity(n: int) -> np.ndarray:
    q = np.zeros((n, len(NAMES), 4))
    q[..., 0] = 1.0
    return q


# ----------------------------------------------------------------------------- roles


@pytest.mark.parametrize("name, expected", [
    ("LeftForeArm", ("left", "forearm")), ("mixamorig:RightLeg", ("right", "leg")), ("lForeArm", ("left", "forearm")),
    ("rtibia", ("right", "tibia")), ("LowerArm_L", ("left", "lowerarm")), ("forearm.R", ("right", "forearm")),
    ("lowerback", (None, "lowerback")), ("Hips", (None, "hips")), ("LeftHip", ("left", "hip")),
])
def test_parse_side(name, expected):
    assert R.parse_side(name) == expected


@pytest.mark.parametrize("relative, preset, expected", [
    ("cmu86/86_01_from_amc_cgspeed_layout.bvh", "cgspeed-mb",
     {"root": "Hips", "chest": "Spine1", "left_elbow": "LeftForeArm", "right_knee": "RightLeg"}),
    ("cmu14/max_14_14_exercise_routine.bvh", "cgspeed-max",
     {"root": "Hips", "chest": "Chest2", "left_shoulder": "LeftShoulder", "right_ankle": "RightAnkle"}),
    ("cmu/daz_10_01_soccer_kick.bvh", "daz", {"root": "hip", "chest": "chest", "left_knee": "lShin"}),
    ("bandai1/dataset-1_kick_normal_001.bvh", "bandai", {"root": "Hips", "left_elbow": "LowerArm_L"}),
    ("other_rigs/20tab_test_freebvh_mixamorig.bvh", "mixamo", {"chest": "mixamorig:Spine2"}),
    ("other_rigs/ad_karate_mawashigeri.bvh", "asf", {"root": "pelvis", "left_knee": "ltibia"}),
])
def test_presets_fit_the_shared_rigs(shared_file, relative, preset, expected):
    from usdmotion.io import read_motion

    m = read_motion(shared_file(relative))
    assert R.match_preset(m) == preset
    roles = R.find_roles(m)
    assert {r: m.joint_names[roles[r]] for r in expected} == expected
    # Name-based guessing (hierarchy + names, no preset table) agrees on the limbs.
    guessed, missing = R._guess_roles(m)
    assert not missing
    limb = [r for r in R.ROLES if r not in ("root", "chest")]
    assert {r: guessed[r] for r in limb} == {r: roles[r] for r in limb}


@pytest.mark.parametrize("relative, chest", [
    ("other_rigs/ad_rokoko_jesse_dance.bvh", "Spine2"), ("other_rigs/wspr_louise_optitrack_arena.bvh", "Chest"),
    ("other_rigs/ad_cartwheel_clean.bvh", "upperback"), ("edge_cases/bvhio_example.bvh", "Chest"),
])
def test_guessing_on_rigs_without_preset(shared_file, relative, chest):
    from usdmotion.io import read_motion

    m = read_motion(shared_file(relative))
    assert R.match_preset(m) is None
    roles = R.find_roles(m)
    assert m.joint_names[roles["chest"]] == chest
    # Every limb bone joins a parent and its child.
    for _, upper, lower in R.LIMB_BONES:
        assert m.parents[roles[lower]] == roles[upper]


def test_missing_roles_are_listed_and_overrides_win():
    names = ("base", "a", "b", "c")
    m = Motion(joint_names=names, parents=np.array([-1, 0, 1, 2]), offsets=np.ones((4, 3)),
               rotations=np.tile([1.0, 0, 0, 0], (5, 4, 1)), root_translation=np.zeros((5, 3)), fps=30)
    with pytest.raises(InputError, match=r"^rig\.bvh: cannot find the joints for role\(s\) left_elbow, left_knee"):
        R.find_roles(m, source="rig.bvh")
    tiny = tiny_motion(identity(2))
    roles = R.find_roles(tiny, overrides={"chest": "LeftArm"})
    assert tiny.joint_names[roles["chest"]] == "LeftArm"
    with pytest.raises(InputError, match="unknown role 'neck'"):
        R.find_roles(tiny, overrides={"neck": "Chest"})
    with pytest.raises(InputError, match="no such joint"):
        R.find_roles(tiny, overrides={"chest": "Spine9"})
    with pytest.raises(InputError, match="two different joints"):
        R.find_roles(tiny, overrides={"chest": "Hips"})


# ----------------------------------------------------------------------------- feature


def test_bone_angles_match_hand_computed_values():
    """Arm and knee bends of known size; a random root rotation must not change anything."""
    n = 7
    rng = np.random.default_rng(0)
    a = np.linspace(0.0, 1.5, n)      # left shoulder about Z
    b = np.linspace(0.0, 1.0, n)      # left elbow about Z (adds to a)
    c = np.linspace(0.0, 1.2, n)      # right knee about X
    q = identity(n)
    q[:, 2] = axis_angle_quat("Z", a)
    q[:, 3] = axis_angle_quat("Z", b)
    q[:, 12] = axis_angle_quat("X", c)
    axes = rng.normal(size=(n, 3))
    root_q = np.concatenate([np.cos(rng.uniform(0, 1.5, (n, 1))), axes / np.linalg.norm(axes, axis=1)[:, None]
                             * np.sin(rng.uniform(0, 1.5, (n, 1)))], axis=1)
    q[:, 0] = root_q / np.linalg.norm(root_q, axis=1)[:, None]
    m = tiny_motion(q, root=rng.normal(size=(n, 3)) * 50)
    theta = S.bone_angles(m)
    expected = np.full((n, 8), np.pi)
    expected[:, 0] = np.pi - a          # left upper arm
    expected[:, 1] = np.pi - a - b      # left forearm
    expected[:, 7] = np.pi - c          # right shank
    np.testing.assert_allclose(theta, expected, atol=1e-9)
    np.testing.assert_allclose(S.norm_signal(theta), np.linalg.norm(expected, axis=1), atol=1e-9)


def test_feature_equals_full_fk_with_atan2(shared_file):
    """Restricted FK + arccos vs full FK (kinematics.joint_positions) + atan2(|a×b|, a·b)."""
    from usdmotion.io import read_motion

    m = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    roles = R.find_roles(m)
    p = joint_positions(m)
    centre = p[:, roles["chest"]] - p[:, roles["root"]]
    expected = []
    for _, upper, lower in R.LIMB_BONES:
        bone = p[:, roles[lower]] - p[:, roles[upper]]
        expected.append(np.arctan2(np.linalg.norm(np.cross(bone, centre), axis=1), np.sum(bone * centre, axis=1)))
    np.testing.assert_allclose(S.bone_angles(m, roles), np.stack(expected, 1), atol=1e-9)


# ----------------------------------------------------------------------------- paper heuristic


def test_local_extrema_match_scipy():
    from scipy.signal import argrelextrema

    t = np.linspace(0, 20, 3000)
    y = np.sin(t) + 0.5 * np.sin(3.1 * t + 0.3) + 0.2 * np.cos(7.3 * t)
    idx, is_max = S.local_extrema(y)
    maxima, minima = argrelextrema(y, np.greater)[0], argrelextrema(y, np.less)[0]
    np.testing.assert_array_equal(np.sort(np.concatenate([maxima, minima])), idx)
    np.testing.assert_array_equal(idx[is_max], maxima)
    assert np.all(is_max[1:] != is_max[:-1])  # alternate
    # A plateau is one extremum, and maxima/minima still alternate.
    idx, is_max = S.local_extrema(np.array([0, 1, 2, 2, 2, 1, 0, 0, 1, 0.0]))
    np.testing.assert_array_equal(idx, [2, 6, 8])
    np.testing.assert_array_equal(is_max, [True, False, True])


def test_swing_candidates_by_hand():
    # Piecewise-linear signal through extrema values at known frames.
    knots_x = np.array([0, 10, 20, 30, 40, 50, 60, 70])
    knots_y = np.array([0.0, 10, 0, 10, 0, 3, 0, 3])
    y = np.interp(np.arange(71), knots_x, knots_y)
    # Extrema at 10..60 (interior); swings: 10:(10,10) 20:(10,10) 30:(10,10) 40:(10,3) 50:(3,3) 60:(3,3)
    # the first (10) and last (60) have one neighbour only; 40 has min/max = 0.3 <= 0.5.
    np.testing.assert_array_equal(S.swing_candidates(y, 0.5), [40])
    np.testing.assert_array_equal(S.swing_candidates(y, 0.2), [])
    np.testing.assert_array_equal(S.swing_candidates(y, 1.0), [20, 30, 40, 50])
    with pytest.raises(ValueError):
        S.swing_candidates(y, 1.5)


def test_lowpass_is_zero_phase():
    fps = 120.0
    t = np.arange(2400) / fps
    slow, fast = np.sin(2 * np.pi * 0.4 * t), np.sin(2 * np.pi * 20 * t)
    y = S.lowpass(slow + fast, fps, 2.0)
    inner = slice(240, -240)
    np.testing.assert_allclose(y[inner], slow[inner], atol=0.02)  # passed, no lag
    assert np.abs(S.lowpass(fast, fps, 2.0)[inner]).max() < 0.01  # 20 Hz removed


# ----------------------------------------------------------------------------- kernel change points


def test_kernel_change_points_on_piecewise_stationary_signal():
    """Three regimes of an 8-D signal: different mean pose, then a different oscillation."""
    rng = np.random.default_rng(1)
    fps, n = 120.0, 1200
    t = np.arange(3 * n) / fps
    theta = np.full((3 * n, 8), 2.8) + 0.05 * rng.normal(size=(3 * n, 8))
    theta[:, :2] += 0.4 * np.sin(2 * np.pi * 1.0 * t)[:, None]         # steady cyclic action
    theta[n:2 * n, 4:6] -= 1.0                                           # new mean pose
    theta[2 * n:, 2:4] += 0.6 * np.sin(2 * np.pi * 0.7 * t[2 * n:])[:, None]  # new oscillation
    x, pool = S.pooled_features(theta, fps)
    cuts = S.kernel_change_points(x, None, 10) * pool
    assert len(cuts) == 2
    np.testing.assert_allclose(cuts, [n, 2 * n], atol=0.25 * fps)


def test_bone_energy_is_mean_squared_speed_then_moving_average():
    rng = np.random.default_rng(7)
    speed = np.abs(rng.normal(size=(50, 8)))
    raw = S.bone_energy(speed, fps=10.0, smooth_s=0.1)                 # window of one frame: no smoothing
    np.testing.assert_allclose(raw, (speed**2).sum(axis=1) / 8, rtol=1e-12)
    smooth = S.bone_energy(speed, fps=10.0, smooth_s=0.3)              # three frames, centred
    np.testing.assert_allclose(smooth[10], raw[9:12].mean(), rtol=1e-12)


def test_refine_moves_a_cut_downhill_to_the_nearest_local_minimum():
    f = np.arange(200, dtype=float)
    # A deep rest at frame 20, a shallower one at 60, rising to frame 100 and beyond.
    energy = 1.0 + np.minimum(np.minimum((f - 20) ** 2 / 400, 0.5 + (f - 60) ** 2 / 400), 10.0)
    assert S.refine_to_rest(energy, np.array([75]), fps=10.0, reach_s=10.0).tolist() == [60]
    # Reach caps the move; a cut already at a minimum stays; a cut left of 60 on the far slope goes to 20.
    assert S.refine_to_rest(energy, np.array([75]), fps=10.0, reach_s=0.5).tolist() == [70]
    assert S.refine_to_rest(energy, np.array([60]), fps=10.0, reach_s=10.0).tolist() == [60]
    assert S.refine_to_rest(energy, np.array([35]), fps=10.0, reach_s=10.0).tolist() == [20]
    # Flat energy: nothing moves.
    assert S.refine_to_rest(np.ones(200), np.array([30, 90]), fps=10.0, reach_s=10.0).tolist() == [30, 90]


def test_refine_never_passes_the_midpoint_to_a_neighbouring_cut():
    f = np.arange(200, dtype=float)
    energy = 1.0 + (f - 100) ** 2 / 100                                # one rest at 100
    out = S.refine_to_rest(energy, np.array([80, 140]), fps=10.0, reach_s=100.0)
    assert out.tolist() == [100, 111]                                  # the second stops past the midpoint 110
    out = S.refine_to_rest(energy, np.array([1, 199]), fps=10.0, reach_s=100.0)
    assert 1 <= out.min() and out.max() <= 199 and np.all(np.diff(out) > 0)


def test_refined_cut_lands_in_the_pause_between_two_actions():
    """Action A (a fast swing), a 0.6 s stand still, action B (new pose, slow swing): kernel change
    points place the cut somewhere around the pause; refinement moves it into the pause."""
    rng = np.random.default_rng(2)
    fps = 120.0
    a, pause, b = 360, 72, 480
    t = np.arange(a + pause + b) / fps
    theta = np.full((t.size, 8), 2.8) + 0.002 * rng.normal(size=(t.size, 8))
    theta[:a, :4] += 0.5 * np.sin(2 * np.pi * 1.5 * t[:a])[:, None]
    theta[a + pause:, 4:] -= 0.8
    theta[a + pause:, 4:6] += 0.4 * np.sin(2 * np.pi * 0.8 * (t[a + pause:] - t[a + pause]))[:, None]
    x, pool = S.pooled_features(theta, fps, speed_weight=0.25)
    raw = S.kernel_change_points(x, 6.0, 10) * pool
    assert raw.size == 1 and abs(raw[0] - (a + pause // 2)) <= 0.5 * fps
    assert not a <= raw[0] < a + pause                                 # the detector alone misses the pause
    refined = S.refine_to_rest(S.bone_energy(S.angular_speed(theta, fps), fps), raw, fps)
    assert refined.size == 1 and a <= refined[0] < a + pause


# ----------------------------------------------------------------------------- scoring


def test_score_is_one_to_one_with_bands_and_tolerance():
    labels = Labels(cuts=np.array([100, 200]), bands=np.array([[80, 130], [200, 200]]))
    # 75 is outside [80, 130] widened to ±10 → [80, 130]; 128 and 90 both fall in cut 100's region.
    s = score_cuts([90, 128, 211, 75], labels, tolerance_frames=10)
    assert (s.true_positives, s.detected, s.labelled, s.in_region) == (1, 4, 2, 2)
    assert s.recall == 0.5 and s.precision == 0.25
    s = score_cuts([90, 210], labels, tolerance_frames=10)  # 210 is exactly at the tolerance
    assert s.precision == 1.0 and s.recall == 1.0
    # Overlapping regions: a greedy nearest match would pair 150 with 140 and lose 140's partner.
    overlap = Labels(cuts=np.array([140, 160]), bands=np.array([[140, 140], [160, 160]]))
    s = score_cuts([150, 130], overlap, tolerance_frames=20)
    assert s.true_positives == 2
    assert score_cuts([], labels, 10).precision == 1.0 and score_cuts([], labels, 10).recall == 0.0


def test_label_files_agree(shared_file):
    import csv

    js = load_labels(shared_file("cmu86/groundtruth86.json"))
    cs = load_labels(shared_file("cmu86/86_01_segments.csv"))
    np.testing.assert_array_equal(js.cuts, [549, 1149, 1979, 2499, 3199, 4064])  # AMC frame − 1
    np.testing.assert_array_equal(js.bands[:, 0], js.cuts - 50)
    np.testing.assert_array_equal(js.cuts, cs.cuts)
    np.testing.assert_array_equal(js.bands, cs.bands)
    # 14_14: cuts at the first frame of each activity, recomputed from the 12-frame window labels.
    windows = np.array(shared_file("cmu14/mocap6_14_14_truelabels.txt").read_text().split(), int)
    changes = np.flatnonzero(windows[1:] != windows[:-1]) + 1   # 0-based window index of a new label
    with open(shared_file("cmu14/14_14_segments.csv"), newline="") as fh:
        assert len(list(csv.DictReader(fh))) == len(changes) + 1
    np.testing.assert_array_equal(load_labels(shared_file("cmu14/14_14_segments.csv")).cuts, 12 * changes)


# ----------------------------------------------------------------------------- synthetic takes


def test_synthetic_take_keeps_clips_and_blends(shared_file):
    from usdmotion.io import read_motion

    walk = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    slash = read_motion(shared_file("bandai1/dataset-1_slash_normal_001.bvh"))
    take, labels = synthetic_take([walk, slash], blend_s=0.5)
    nb = 15
    assert take.n_frames == walk.n_frames + nb + slash.n_frames
    np.testing.assert_array_equal(labels.bands, [[walk.n_frames, walk.n_frames + nb - 1]])
    np.testing.assert_allclose(take.rotations[: walk.n_frames], walk.rotations)
    np.testing.assert_allclose(take.rotations[-slash.n_frames:], slash.rotations)
    np.testing.assert_allclose(take.joint_translations[-slash.n_frames:], slash.joint_translations)
    # The second clip continues where the first stopped (horizontally), heights unchanged.
    start = take.root_translation[-slash.n_frames]
    np.testing.assert_allclose(start[[0, 2]], walk.root_translation[-1][[0, 2]])
    np.testing.assert_allclose(start[1], slash.root_translation[0][1])
    # Blend frames move monotonically from one pose to the other (angle to the end pose shrinks).
    blend = take.rotations[walk.n_frames: walk.n_frames + nb, 2]
    dots = np.abs(np.sum(blend * slash.rotations[0, 2], axis=-1))
    assert np.all(np.diff(dots) >= -1e-12)


def test_known_cuts_are_found_on_a_synthetic_take(shared_file):
    """Walk (CMU 12_01) → punches → kicks (CMU 86_01 pieces): kcpd finds both junctions, nothing else."""
    from usdmotion.io import read_motion

    walk = read_motion(shared_file("cmu/cgspeed_12_01_walk.bvh"))
    take86 = read_motion(shared_file("cmu86/86_01_from_amc_cgspeed_layout.bvh"))
    parts = [S.clip(walk, 1, walk.n_frames - 1), S.clip(take86, 2050, 2430), S.clip(take86, 3300, 3990)]
    take, labels = synthetic_take(parts, blend_s=0.5)
    seg = S.segment(take)
    score = score_cuts(seg.cuts, labels, int(0.5 * take.fps))
    assert (score.precision, score.recall) == (1.0, 1.0), (seg.cuts, labels.cuts)
    heuristic = S.segment(take, method="heuristic")
    np.testing.assert_array_equal(heuristic.cuts, heuristic.candidates)
    assert heuristic.cuts.size > seg.cuts.size  # the paper's candidates over-segment


def test_bandai_take_at_30_fps(shared_file):
    from usdmotion.io import read_motion

    names = ("walk_normal", "slash_normal", "walk_tired")
    parts = [read_motion(shared_file(f"bandai1/dataset-1_{n}_001.bvh")) for n in names]
    take, labels = synthetic_take(parts, blend_s=0.5)
    seg = S.segment(take)
    score = score_cuts(seg.cuts, labels, int(0.5 * take.fps))
    assert (score.precision, score.recall) == (1.0, 1.0), (seg.cuts, labels.cuts)
    bounds = seg.bounds()
    assert bounds[0, 0] == 0 and bounds[-1, 1] == take.n_frames - 1
    np.testing.assert_array_equal(bounds[1:, 0], bounds[:-1, 1] + 1)
    assert [seg.segment_at(int(f)) for f in bounds[:, 0]] == list(range(len(bounds)))


def test_activity_ranges_match_the_csv_action_columns(shared_file):
    """Ranges from the JSON bands vs the CSV's own action columns (1-based, inclusive, sharing the
    band's edge frames, which the ranges leave out)."""
    import csv

    labels = load_labels(shared_file("cmu86/groundtruth86.json"))
    with open(shared_file("cmu86/86_01_segments.csv"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    first = np.array([int(r["action_start_frame"]) for r in rows]) - 1
    last = np.array([int(r["action_end_frame"]) for r in rows]) - 1
    first[1:] += 1
    last[:-1] -= 1
    ranges = activity_ranges(labels, 4579)
    np.testing.assert_array_equal(ranges, np.stack([first, last], 1))
    widened = activity_ranges(labels, 4579, 60)
    np.testing.assert_array_equal(widened[1:, 0], ranges[1:, 0] + 60)
    np.testing.assert_array_equal(widened[:-1, 1], ranges[:-1, 1] - 60)
    assert widened[0, 0] == 0 and widened[-1, 1] == 4578
    with pytest.raises(ValueError, match="empty"):
        activity_ranges(labels, 4579, 300)


def test_reordered_take_keeps_each_activity():
    """Frame f of the source has its left shoulder turned by f·0.001 rad about Z, so every frame of the
    new take says which source frame it came from."""
    n = 400
    q = identity(n)
    q[:, 2] = axis_angle_quat("Z", 0.001 * np.arange(n))
    m = tiny_motion(q)
    labels = Labels(cuts=np.array([100, 250]), bands=np.array([[90, 110], [240, 260]]))
    take, new = reordered_take(m, labels, [2, 0, 1], margin_frames=5, blend_s=0.5)
    source = np.rint(2 * np.arctan2(take.rotations[:, 2, 3], take.rotations[:, 2, 0]) / 0.001).astype(int)
    nb = 15  # 0.5 s at 30 fps
    expected_frames = np.concatenate([np.arange(266, 400), np.arange(0, 85), np.arange(116, 235)])
    real = np.ones(take.n_frames, bool)
    for a, _ in new.bands:
        real[a:a + nb] = False
    np.testing.assert_array_equal(source[real], expected_frames)
    np.testing.assert_array_equal(new.bands[:, 0], [134, 134 + nb + 85])
    np.testing.assert_array_equal(new.cuts, new.bands[:, 0] + nb // 2)
    with pytest.raises(ValueError, match="order"):
        reordered_take(m, labels, [0, 3])


def test_too_short_motion_is_refused():
    with pytest.raises(InputError, match=r"^short\.bvh: motion too short to segment: 20 frames"):
        S.segment(tiny_motion(identity(20)), source="short.bvh")


def test_heuristic_on_a_constructed_motion():
    """Shoulder swings of constant then halved amplitude: the candidate sits at the change."""
    fps, n = 60.0, 600
    t = np.arange(n) / fps
    amp = np.where(t < 5, 1.2, 0.4)
    q = identity(n)
    q[:, 2] = axis_angle_quat("Z", 0.2 + amp * (1 - np.cos(2 * np.pi * 0.5 * t)) / 2)
    seg = S.segment(tiny_motion(q, fps=fps), method="heuristic", param=0.5, cutoff_hz=2.0)
    assert seg.cuts.size >= 1
    assert np.min(np.abs(seg.cuts / fps - 5.0)) <= 1.0  # the first small swing follows 5 s
    assert np.all(np.abs(seg.cuts / fps - 5.0) <= 1.0)  # no candidate inside the steady parts


@pytest.mark.parametrize("bvh, labels", [("cmu86/86_01_from_amc_cgspeed_layout.bvh", "cmu86/groundtruth86.json"),
                                         ("cmu14/max_14_14_exercise_routine.bvh", "cmu14/14_14_segments.csv")])
def test_refined_cuts_on_the_labelled_takes(shared_file, bvh, labels):
    """Each shipped cut is the raw kcpd cut moved to the quietest frame of the raw cut's change
    region, and every labelled transition is found."""
    from usdmotion.io import read_motion

    motion = read_motion(shared_file(bvh))
    raw = S.segment(motion, refine=False)
    seg = S.segment(motion)
    assert seg.params["refine"] and not raw.params["refine"]
    assert raw.cuts.size == seg.cuts.size and np.all(raw.cuts % 12 == 0)    # 10 Hz grid at 120 Hz
    assert np.array_equal(seg.regions, raw.regions)
    assert np.all((raw.regions[:, 0] <= seg.cuts) & (seg.cuts <= raw.regions[:, 1]))
    energy = S.bone_energy(S.angular_speed(seg.angles, motion.fps), motion.fps)
    quietest = [lo + int(np.argmin(energy[lo:hi + 1])) for lo, hi in raw.regions]
    assert seg.cuts.tolist() == quietest
    score = score_cuts(seg.cuts, load_labels(shared_file(labels)), int(0.5 * motion.fps))
    assert (score.precision, score.recall) == (1.0, 1.0), (seg.cuts.tolist(), score)

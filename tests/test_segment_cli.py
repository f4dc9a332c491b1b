"""``usdmotion segment`` / ``segment-eval``: outputs re-read and checked, bad input → one line, exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import without_warnings

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions
from usdmotion.ops.segment.evaluate import synthetic_take

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def take_bvh(tmp_path_factory):
    """A 30 fps synthetic take (Bandai walk → slash → tired walk) written as BVH, with its true cuts."""
    from conftest import shared_path
    from usdmotion.io import write_motion

    parts = [read_motion(shared_path(f"bandai1/dataset-1_{n}_001.bvh"))
             for n in ("walk_normal", "slash_normal", "walk_tired")]
    take, labels = synthetic_take(parts, blend_s=0.5)
    path = tmp_path_factory.mktemp("take") / "take.bvh"
    write_motion(take, path)
    return path, labels


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_segment_outputs(take_bvh, tmp_path, capsys):
    import jsonschema
    import matplotlib.image

    path, labels = take_bvh
    out, plot, clips = tmp_path / "seg.json", tmp_path / "seg.png", tmp_path / "clips"
    code, stdout, err = run(capsys, "segment", path, "--out", out, "--plot", plot, "--export-clips", clips)
    assert code == 0, err
    doc = json.loads(out.read_text())
    schema = json.loads((REPO / "schemas" / "segments.schema.json").read_text())
    jsonschema.validate(doc, schema)
    original = read_motion(path)
    # Segments partition the frames; times are frame / fps; cuts near the known junctions.
    segs = doc["segments"]
    assert segs[0]["start_frame"] == 0 and segs[-1]["end_frame"] == original.n_frames - 1
    assert [s["start_frame"] for s in segs[1:]] == doc["cuts"] == [s["end_frame"] + 1 for s in segs[:-1]]
    assert all(abs(s["end_time"] - s["end_frame"] / original.fps) < 1e-6 for s in segs)
    assert np.allclose(doc["cuts"], labels.cuts, atol=15)
    # Clips: valid BVH, frames and poses identical to the take's slices.
    files = sorted(clips.glob("*.bvh"))
    assert len(files) == len(segs)
    full = joint_positions(original)
    for f, s in zip(files, segs):
        m = read_motion(f)
        assert m.n_frames == s["frames"] and m.joint_names == original.joint_names
        np.testing.assert_allclose(joint_positions(m), full[s["start_frame"]: s["end_frame"] + 1], atol=1e-5)
        np.testing.assert_allclose(m.source_channels, original.source_channels[s["start_frame"]: s["end_frame"] + 1],
                                   atol=1e-6)
    # The plot is a real image with content.
    image = matplotlib.image.imread(plot)
    assert image.shape[0] > 400 and image.shape[1] > 1000 and image[..., :3].std() > 0.05
    assert f"{len(segs)} segments" in stdout


def test_at_exports_one_usd_clip(take_bvh, tmp_path, capsys):
    path, labels = take_bvh
    frame = int(labels.cuts[0]) + 60  # inside the slash
    code, stdout, err = run(capsys, "segment", path, "--at", frame, "--export-clips", tmp_path, "--format", "usdc",
                            "--json")
    assert code == 0, err
    doc = json.loads(stdout)
    (seg,) = doc["segments"]
    assert seg["start_frame"] <= frame <= seg["end_frame"]
    (clip_path,) = map(Path, doc["clips"])
    assert clip_path.suffix == ".usdc" and sorted(tmp_path.iterdir()) == [clip_path]
    clip = read_motion(clip_path)
    original = read_motion(path)
    assert clip.n_frames == seg["frames"]
    expected = joint_positions(original)[seg["start_frame"]: seg["end_frame"] + 1]
    np.testing.assert_allclose(joint_positions(clip), expected, atol=1e-3 * np.ptp(expected))


def test_heuristic_method_and_json(shared_file, capsys):
    path = shared_file("cmu/cgspeed_12_01_walk.bvh")
    code, stdout, err = run(capsys, "segment", path, "--method", "heuristic", "--param", "0.3", "--json")
    assert code == 0, err
    doc = json.loads(stdout)
    from usdmotion.ops.segment import detect as S

    seg = S.segment(read_motion(path), method="heuristic", param=0.3)
    assert doc["cuts"] == seg.cuts.tolist() and doc["params"] == {"param": 0.3, "cutoff_hz": 2.0}


def test_no_refine_keeps_the_detector_cuts(shared_file, capsys):
    from usdmotion.ops.segment import detect as S

    path = shared_file("cmu14/max_14_14_exercise_routine.bvh")
    docs = {}
    for flag in ("--refine", "--no-refine"):
        code, stdout, err = run(capsys, "segment", path, flag, "--json")
        assert code == 0, err
        docs[flag] = json.loads(stdout)
    motion = read_motion(path)
    unrefined = S.segment(motion, refine=False)
    raw = unrefined.cuts
    assert docs["--no-refine"]["cuts"] == raw.tolist() and docs["--no-refine"]["params"]["refine"] is False
    energy = S.bone_energy(S.angular_speed(S.bone_angles(motion), motion.fps), motion.fps)
    assert docs["--refine"]["cuts"] == S.quietest_in_region(energy, raw, unrefined.regions).tolist()
    assert docs["--refine"]["cuts"] != docs["--no-refine"]["cuts"]


def test_segment_eval_matches_an_independent_count(shared_file, capsys):
    bvh, labels = shared_file("cmu14/max_14_14_exercise_routine.bvh"), shared_file("cmu14/14_14_segments.csv")
    code, stdout, err = run(capsys, "segment-eval", bvh, labels, "--json")
    assert code == 0, err
    doc = json.loads(stdout)
    truth = doc["labelled_cuts"]
    assert truth == [456, 1044, 1608, 2280, 3576]  # start_frame − 1
    for name, r in doc["methods"].items():
        from usdmotion.ops.segment import detect as S

        cuts = S.segment(read_motion(bvh), method=name).cuts
        # Independent count: walk the labelled cuts in order, take the nearest unused detection within ±60.
        used, hits = set(), 0
        for t in truth:
            near = [c for c in cuts if abs(c - t) <= 60 and c not in used]
            if near:
                used.add(min(near, key=lambda c: abs(c - t)))
                hits += 1
        assert r["true_positives"] == hits and r["detected"] == len(cuts)
        assert r["precision"] == pytest.approx(hits / len(cuts)) and r["recall"] == pytest.approx(hits / 5)


@pytest.mark.parametrize("relative, args, message", [
    ("edge_cases/fairmotion_sinusoidal_no_end_site.bvh", [], "cannot find the joints for role(s)"),
    ("bandai1/dataset-1_dash_normal_001.bvh", [], "motion too short to segment: 20 frames"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--at", "524"], "--at 524: frame is outside 0..523"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--role", "chest"], "expected ROLE=JOINT"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--role", "chest=Nope"], "role chest='Nope': no such joint"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--preset", "nope"], "unknown role preset 'nope'"),
    # scipy's "Singular matrix" was the line
    ("cmu/cgspeed_12_01_walk.bvh", ["--cutoff", "1e-12"], "--cutoff 1e-12 Hz must be at least 0.1 Hz"),
    # NaN and inf passed the range checks: ruptures' AssertionError, an OverflowError (exit 1)
    ("cmu/cgspeed_12_01_walk.bvh", ["--penalty", "nan"], "--penalty must be a positive number, got nan"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--min-length", "inf"], "--min-length must be a positive number, got inf"),
    ("cmu/cgspeed_12_01_walk.bvh", ["--param", "nan"], "--param must be a non-negative number, got nan"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(shared_file, tmp_path, capsys, relative, args, message):
    path = shared_file(relative)
    out, plot = tmp_path / "s.json", tmp_path / "s.png"
    code, stdout, err = run(capsys, "segment", path, *args, "--out", out, "--plot", plot, "--export-clips",
                            tmp_path / "clips")
    assert code == 2
    lines = without_warnings(err)
    assert len(lines) == 1 and lines[0].startswith("usdmotion: error: ") and message in lines[0]
    assert "Traceback" not in err
    assert not out.exists() and not plot.exists() and not (tmp_path / "clips").exists()
    if "ROLE=" not in message and not message.startswith("--"):
        assert lines[0].startswith(f"usdmotion: error: {path}: ")


def test_bad_labels(shared_file, tmp_path, capsys):
    bad = tmp_path / "labels.csv"
    bad.write_text("a,b\n1,2\n")
    code, _, err = run(capsys, "segment-eval", shared_file("cmu/cgspeed_12_01_walk.bvh"), bad)
    assert code == 2 and f"{bad}: CSV needs columns" in err and len(err.strip().splitlines()) == 1


def test_clip_export_reports_progress_after_each_clip(take_bvh, tmp_path):
    from usdmotion.ops.segment.detect import segment
    from usdmotion.ops.segment.files import export_clips

    path, _ = take_bvh
    motion = read_motion(path)
    seg = segment(motion)
    n = len(seg.bounds())
    seen = []

    def report(done, total, message):  # usdmotion.progress.Progress
        seen.append((done, total, len(list(tmp_path.iterdir()))))

    paths = export_clips(motion, seg, tmp_path, "bvh", "take", progress=report)
    assert n > 1 and len(paths) == n
    assert seen == [(k, n, k) for k in range(n + 1)]  # reported as each clip is about to be / has been written

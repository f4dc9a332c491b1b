"""``usdmotion analyze``, ``check`` and ``synth`` in-process: outputs checked against the library."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from usdmotion.cli import main
from usdmotion.kinematics import joint_positions
from usdmotion.synthesis import example_path, load_synthesis

LIMITS = str(example_path("giant_swing").with_name("giant_swing_limits.json"))


def test_analyze_csv_and_summary_of_the_giant_swing(tmp_path, capsys):
    out, summary = tmp_path / "kin.csv", tmp_path / "summary.json"
    assert main(["analyze", "giant_swing", "--out", str(out), "--summary", str(summary), "--filter", "none"]) == 0
    table = pd.read_csv(out, keep_default_na=False, na_values=[""])
    motion = load_synthesis(example_path("giant_swing"))
    feet = table[table.joint == "Legs_End"].sort_values("frame")
    assert np.allclose(feet[["pos_x", "pos_y", "pos_z"]].to_numpy(), joint_positions(motion)[:, 3] * 0.05)
    assert np.allclose(feet.speed, np.linalg.norm(feet[["vel_x", "vel_y", "vel_z"]].to_numpy(), axis=1))
    body = table[table.joint == "Body"].sort_values("frame")
    assert np.allclose(body.angle_z, [7.0, 6.2, 5.5, 4.7, 3.9, 3.2, 2.8, 2.7, 2.9, 3.9, 6.4, 11.8, 20.6, 31.0, 38.2,
                                      38.1, 31.3, 21.5, 12.7, 6.6, 3.5, 3.0, 4.1])
    assert set(body.euler_order) == {"ZXY"}
    data = json.loads(summary.read_text())
    peak = data["joints"]["Legs_End"]["peak_speed"]
    assert peak["value"] == pytest.approx(feet.speed.max(), rel=1e-6)
    assert peak["frame"] == int(feet.frame.iloc[int(np.argmax(feet.speed.to_numpy()))])
    assert data["joints"]["Legs"]["range_of_motion"]["z"] == {"min": -37.2, "max": 3.9, "range": 41.1}
    assert data["meta"]["units"]["speed"] == "m/s" and data["meta"]["filter"]["method"] == "none"
    assert data["com"] is None  # a 3-segment model has no de Leva landmarks
    lines = summary.read_text().splitlines()  # readable: a key per line to the joints, then a joint per line
    assert [line for line in lines if line.startswith('  "Legs_End": {')] == \
        ['  "Legs_End": ' + json.dumps(data["joints"]["Legs_End"])]
    assert ' "meta": {' in lines and '  "fps": 30.0,' in lines and len(lines) < 40
    printed = capsys.readouterr()
    assert "Legs_End" in printed.out and "no centre of mass" in printed.err


def test_analyze_cmu_walk_parquet_json_and_plot(shared_file, tmp_path, capsys):
    path = shared_file("cmu/cgspeed_12_01_walk.bvh")
    parquet, as_json, plot = tmp_path / "k.parquet", tmp_path / "k.json", tmp_path / "k.png"
    args = ["analyze", str(path), "--units", "asf", "--frames", "1:", "--mass", "70", "--joints", "LeftLeg,LeftFoot"]
    assert main(args + ["--out", str(parquet), "--plot", str(plot)]) == 0
    assert main(args + ["--out", str(as_json), "--json"]) == 0
    printed = capsys.readouterr().out
    assert json.loads(printed[printed.index("\n{") + 1:])["joints"]["LeftLeg"]["bend"]["max"] > 60  # knee flexion
    import pyarrow.parquet as pq

    table = pq.read_table(parquet)
    encodings = {column.path_in_schema: column.encodings for column in
                 (pq.ParquetFile(parquet).metadata.row_group(0).column(i) for i in range(table.num_columns))}
    assert "RLE_DICTIONARY" in encodings["joint"] and "RLE_DICTIONARY" not in encodings["pos_y"]  # labels only
    meta = json.loads(table.schema.metadata[b"usdmotion"])
    assert meta["first_frame"] == 1 and meta["units"]["momentum"] == "kg m/s"
    frame = table.to_pandas()
    assert set(frame.joint.astype(str)) >= {"LeftLeg", "LeftFoot", "COM", "COM:left_thigh"}
    com = frame[frame.joint == "COM"].sort_values("frame")
    assert com.frame.iloc[0] == 1 and len(com) == 523
    assert np.allclose(com[["momentum_x", "momentum_y", "momentum_z"]].to_numpy(),
                       70.0 * com[["vel_x", "vel_y", "vel_z"]].to_numpy())
    doc = json.loads(as_json.read_text())
    assert list(doc["joints"]) == ["LeftLeg", "LeftFoot"]
    assert doc["com"]["mass_kg"] == 70.0 and 0.7 < doc["com"]["mean_horizontal_speed"] < 1.1
    rows = np.array(doc["table"]["joint"]) == "LeftFoot"
    assert np.allclose(np.array(doc["table"]["pos_y"])[rows],
                       frame[frame.joint == "LeftFoot"].sort_values("frame").pos_y, atol=1e-6)
    import matplotlib.image as mpimg

    image = mpimg.imread(plot)
    assert image.shape[0] > 500 and image.shape[1] > 800 and image[..., :3].std() > 0.05


def test_rest_pose_frame_warning(shared_file, capsys):
    path = shared_file("cmu/cgspeed_12_01_walk.bvh")
    assert main(["analyze", str(path), "--units", "asf", "--joints", "Hips", "--no-com"]) == 0
    assert "jumps between frames 0 and 1" in capsys.readouterr().err
    assert main(["analyze", str(path), "--units", "asf", "--joints", "Hips", "--no-com", "--frames", "1:"]) == 0
    assert "jumps" not in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--joints", "Bodyy"], r"giant_swing: no joint named 'Bodyy' \(did you mean Body\?\)"),
    (["--cutoff", "20"], r"--cutoff 20 Hz must be at least 0.1 Hz and below the Nyquist frequency 15 Hz"),
    # numpy's "Unable to allocate 2.62 TiB" was the line (the filter's end padding grows as fps / cutoff)
    (["--cutoff", "1e-9"], r"--cutoff 1e-09 Hz must be at least 0.1 Hz"),
    (["--frames", "5"], r"--frames: '5' is not START:STOP"),
    (["--frames", "22:"], r"--frames 22: leaves 1 of 23 frames"),
    (["--euler-order", "XYX"], r"Euler order must be one of"),
    (["--mass", "-3"], r"--mass must be a body mass between 1 and 1000 kg, got -3"),
    (["--mass", "1e30"], r"--mass must be a body mass between 1 and 1000 kg, got 1e\+30"),  # exit 0 before
    (["--out", "{tmp}/k.txt"], r"k\.txt: unknown table format '\.txt'"),
    (["--plot", "{tmp}/k.gif"], r"k\.gif: unknown image format '\.gif'"),
])
def test_analyze_bad_options_are_one_line_errors(tmp_path, capsys, args, message):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(["analyze", "giant_swing", "--out", str(tmp_path / "ok.csv")] + args) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("usdmotion: warning: ")]
    assert len(err) == 1 and err[0].startswith("usdmotion: error: ")
    import re

    assert re.search(message, err[0]), err[0]
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_analyze_segment_map_errors_name_the_file(tmp_path, capsys, shared_file):
    path = shared_file("cmu/cgspeed_12_01_walk.bvh")
    seg = tmp_path / "seg.json"
    seg.write_text('{"landmarks": {"left_knee": "LKnee"}}')
    assert main(["analyze", str(path), "--units", "asf", "--segments", str(seg)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("usdmotion: warning: ")]
    assert err == [f"usdmotion: error: {seg}: /landmarks/left_knee: no joint named 'LKnee'"]
    seg.write_text('{"segments": [{"name": "all", "from": "Hips", "to": "Head", "mass_fraction": 1, '
                   '"com_fraction": 0.5}]}')
    out = tmp_path / "k.json"
    assert main(["analyze", str(path), "--units", "asf", "--frames", "1:", "--segments", str(seg), "--joints",
                 "Hips,Head", "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    rows = np.array(doc["table"]["joint"])
    mid = 0.5 * (np.array(doc["table"]["pos_y"])[rows == "Hips"] + np.array(doc["table"]["pos_y"])[rows == "Head"])
    assert np.allclose(np.array(doc["table"]["pos_y"])[rows == "COM"], mid, atol=1e-6)


def test_check_exit_codes_and_report(tmp_path, capsys):
    assert main(["check", "giant_swing", "--limits", LIMITS]) == 0
    assert "no limit violated" in capsys.readouterr().out
    strict = tmp_path / "strict.yaml"
    strict.write_text("joints:\n  Legs: {z: [-30, 30]}\n  Body: {max_angular_speed: 300}\n")
    assert main(["check", "giant_swing", "--limits", str(strict), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    hip = [v for v in report["violations"] if v["joint"] == "Legs"]
    # the paper's hip angle is below -30 deg in frames 6..9 (-28.2 is not), worst -37.2 at frame 8
    assert [(v["first_frame"], v["last_frame"], v["value"], v["worst_frame"]) for v in hip] == [(7, 9, -37.2, 8)]
    assert all(v["limit"] == -30 and v["bound"] == "min" for v in hip)
    assert any(v["joint"] == "Body" and v["quantity"] == "angular_speed" for v in report["violations"])
    bad = tmp_path / "bad.json"
    bad.write_text('{"joints": {"Legs": {"z": [30, -30]}}}')
    assert main(["check", "giant_swing", "--limits", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usdmotion: error: {bad}: /joints/Legs/z: minimum 30 is above maximum -30")


def test_synth_writes_bvh_usd_and_strip(tmp_path, capsys):
    bvh, usd, png = tmp_path / "s.bvh", tmp_path / "s.usda", tmp_path / "s.png"
    assert main(["synth", "giant_swing", str(bvh), str(usd), "--plot", str(png)]) == 0
    from usdmotion.io import read_motion

    expected = joint_positions(load_synthesis(example_path("giant_swing")))
    assert np.allclose(joint_positions(read_motion(bvh)), expected, atol=1e-9)
    assert np.allclose(joint_positions(read_motion(usd)), expected, atol=1e-4)
    assert "363.3" in bvh.read_text()
    capsys.readouterr()
    assert main(["synth", "giant_swing", "--print-spec"]) == 0
    assert json.loads(capsys.readouterr().out)["name"] == "giant_swing"
    assert main(["synth", "giant_swing"]) == 2
    assert "nothing to do" in capsys.readouterr().err
    assert main(["synth", "no_such_example", str(bvh)]) == 2
    assert "no_such_example" in capsys.readouterr().err

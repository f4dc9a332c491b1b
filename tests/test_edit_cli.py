"""The editing commands and pipeline files, run in-process through ``usdmotion.cli.main``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from edit_support import angle_between, walker

from usdmotion.cli import main
from usdmotion.io import read_motion, write_motion
from usdmotion.ops.edit import cycle, equalize, resample, speed, trim
from usdmotion.ops.edit.pipeline import load_pipeline


@pytest.fixture
def walk_file(tmp_path):
    path = tmp_path / "walk.bvh"
    write_motion(walker(n_frames=150, noise_deg=0.5), path)
    return path


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def same_motion(a, b, tol=1e-6):
    assert a.n_frames == b.n_frames and a.fps == pytest.approx(b.fps)
    assert np.max(angle_between(a.rotations, b.rotations)) < tol
    np.testing.assert_allclose(a.root_translation, b.root_translation, atol=1e-5)


def test_pipeline_equals_the_library_calls(tmp_path, walk_file, capsys):
    pipeline = tmp_path / "edits.json"
    pipeline.write_text(json.dumps([
        {"op": "trim", "start": 5, "stop": "2s"},
        {"op": "equalize", "preset": "denoise"},
        {"op": "speed", "factor": 1.5},
        {"op": "resample", "fps": 30},
        {"op": "cycle", "stop": "auto", "transition": 4, "loops": 3},
    ]))
    code, out, err = run(capsys, "edit", walk_file, tmp_path / "out.bvh", "--pipeline", pipeline)
    assert code == 0, err
    assert "5 operations from edits.json" in out
    m = read_motion(walk_file)
    expected = cycle(resample(speed(equalize(trim(m, 5, 120), preset="denoise"), 1.5), 30), stop="auto",
                     transition=4, loops=3)
    same_motion(read_motion(tmp_path / "out.bvh"), expected)


@pytest.mark.parametrize("document, message", [
    ("[", "not valid JSON"),
    ({"op": "trim"}, "is not of type 'array'"),
    ([{"op": "trim"}, {"op": "sped", "factor": 2}], "operation 1 (sped): op: 'sped' is not one of"),
    ([{"op": "speed"}], "operation 0 (speed): needs exactly one of 'factor' or 'keys'"),
    ([{"op": "speed", "factor": -2}], "operation 0 (speed): factor: -2 is less than or equal to the minimum of 0"),
    ([{"op": "equalize", "preset": "denoise", "gain": [1]}], "operation 0 (equalize): unknown option(s) ('gain'"),
    ([{"op": "cycle", "loops": 1.5}], "operation 0 (cycle): loops: 1.5 is not of type 'integer'"),
])
def test_malformed_pipelines_name_file_and_entry(tmp_path, walk_file, capsys, document, message):
    pipeline = tmp_path / "bad.json"
    pipeline.write_text(document if isinstance(document, str) else json.dumps(document))
    code, out, err = run(capsys, "edit", walk_file, tmp_path / "out.bvh", "--pipeline", pipeline)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and str(pipeline) in err and message in err, err
    assert not (tmp_path / "out.bvh").exists()


def test_pipeline_errors_at_run_time_name_the_entry(tmp_path, walk_file, capsys):
    pipeline = tmp_path / "edits.json"
    pipeline.write_text(json.dumps([{"op": "trim", "start": 0, "stop": 50},
                                    {"op": "equalize", "gains": [0], "joint": "Hipz"}]))
    code, _, err = run(capsys, "edit", walk_file, tmp_path / "o.bvh", "--pipeline", pipeline)
    assert code == 2 and "operation 1 (equalize): no joint named 'Hipz' (did you mean Hips?)" in err
    pipeline.write_text(json.dumps([{"op": "blend", "with": "missing.bvh"}]))
    code, _, err = run(capsys, "edit", walk_file, tmp_path / "o.bvh", "--pipeline", pipeline)
    assert code == 2 and "missing.bvh" in err and len(err.strip().splitlines()) == 1
    assert load_pipeline.__doc__ and not (tmp_path / "o.bvh").exists()


def test_blend_with_a_relative_path(tmp_path, walk_file, capsys):
    write_motion(walker(n_frames=120, period=40), tmp_path / "fast.bvh")
    pipeline = tmp_path / "edits.json"
    pipeline.write_text(json.dumps([{"op": "blend", "with": "fast.bvh", "transition": "0.25s"}]))
    code, out, err = run(capsys, "edit", walk_file, tmp_path / "o.usda", "--pipeline", pipeline)
    assert code == 0, err
    assert read_motion(tmp_path / "o.usda").n_frames == 150 - 15 + 120


def test_subcommands(tmp_path, walk_file, capsys):
    out_file = tmp_path / "o.bvh"
    m = read_motion(walk_file)
    code, out, err = run(capsys, "speed", walk_file, out_file, "--factor", 2)
    assert code == 0 and "75 frames" in out
    same_motion(read_motion(out_file), speed(m, 2.0))
    code, out, err = run(capsys, "equalize", walk_file, out_file, "--gains", "0,0", "--joint", "LeftUpLeg",
                         "--subtree")
    assert code == 0, err
    same_motion(read_motion(out_file), equalize(m, gains=[0, 0], joint="LeftUpLeg", subtree=True))
    assert run(capsys, "trim", walk_file, out_file, "--frames", "10:-10")[0] == 0
    assert read_motion(out_file).n_frames == 130
    assert run(capsys, "reorient", walk_file, out_file, "--heading", "90", "--position", "0,0")[0] == 0
    root = read_motion(out_file).root_translation
    assert abs(root[-1, 2] - root[0, 2]) < 1e-3 and root[-1, 0] > root[0, 0] + 100
    assert run(capsys, "cycle", walk_file, out_file, "--frames", "0:auto", "--loops", 2)[0] == 0
    assert run(capsys, "layer", walk_file, out_file, "--joint", "Head", "--channel", "rx", "--key", "0=0",
               "--key", "1s=30")[0] == 0
    assert run(capsys, "displace", walk_file, out_file, "--rotate", "LeftUpLeg@75=0,20,0", "--falloff", "0.5s")[0] == 0
    assert run(capsys, "resample", walk_file, out_file, "--fps", 24)[0] == 0
    assert read_motion(out_file).fps == pytest.approx(24)
    assert run(capsys, "blend", walk_file, walk_file, out_file, "--align", "peaks", "--align-joint",
               "LeftUpLeg")[0] == 0


@pytest.mark.parametrize("argv, message", [
    (["speed", "{in}", "{out}", "--factor", "0"], "speed must be a positive number"),
    (["speed", "{in}", "{out}", "--key", "0=1", "--key", "40=-1"], "speed key value must be a positive number"),
    (["equalize", "{in}", "{out}", "--preset", "denoise", "--joint", "Lefty"], "no joint named 'Lefty'"),
    (["trim", "{in}", "{out}", "--frames", "100:400"], "outside the motion's frames 0..149"),
    (["cycle", "{in}", "{out}", "--frames", "0:20", "--transition", "15"], "transition must be 1..9"),
    (["blend", "{in}", "{in}", "{out}", "--transition", "500"], "does not fit"),
    (["displace", "{in}", "{out}", "--rotate", "Head=1,2,3"], "expected JOINT@FRAME=A,B,C"),
    (["reorient", "{in}", "{out}", "--position", "1"], "needs 2 or 3 numbers"),
    # results too long to hold: numpy's "Unable to allocate 3.81 TiB ..." was the line (no FILE)
    (["speed", "{in}", "{out}", "--factor", "1e-9"], "speed 1e-09: the result would have 149,000,000,001 frames"),
    (["speed", "{in}", "{out}", "--key", "0=1e-9", "--key", "40=1e-9"], "the speed keys: the result would have"),
    (["resample", "{in}", "{out}", "--fps", "1e9"], "resampling to 1e+09 fps: the result would have"),
    (["cycle", "{in}", "{out}", "--loops", "100000000"], "100000000 loops of"),
])
def test_bad_options_are_one_line_errors_and_write_nothing(tmp_path, walk_file, capsys, argv, message):
    out_file = tmp_path / "o.bvh"
    argv = [a.format(**{"in": walk_file, "out": out_file}) for a in argv]
    code, out, err = run(capsys, *argv)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"usdmotion: error: {walk_file}") and message in lines[0], err
    assert not out_file.exists() and "Traceback" not in err


@pytest.mark.parametrize("ext", ["bvh", "usda", "glb"])
def test_a_result_no_reader_accepts_is_not_written(tmp_path, walk_file, capsys, ext):
    """``reorient --translate 1e16,0,0`` wrote a file (exit 0) that every reader, usdmotion's
    own included, refuses: values beyond ±1e15 (the readers' bound)."""
    out_file = tmp_path / f"o.{ext}"
    code, out, err = run(capsys, "reorient", walk_file, out_file, "--translate", "1e16,0,0")
    assert code == 2 and not out_file.exists() and not list(tmp_path.glob(".o*")), err
    assert err.strip() == (f"usdmotion: error: {out_file}: not written: the result's root translation at frame 0: "
                           f"{float(read_motion(walk_file).root_translation[0, 0] + 1e16)!r} is not a finite number within "
                           "±1e+15, which no reader accepts")
    code, out, err = run(capsys, "reorient", walk_file, out_file, "--translate", "1e14,0,0")  # within the bound
    assert code == 0 and read_motion(out_file).root_translation[0, 0] > 9e13

"""The command line, run in-process through usdmotion.cli.main (exit codes, output)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import without_warnings
from reference_fk import usd_world_positions

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions

WALK = "cmu/cgspeed_12_01_walk.bvh"


def run(capsys, *args):
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_convert_to_all_formats_and_back(shared_file, tmp_path, capsys):
    source = shared_file(WALK)
    reference = joint_positions(read_motion(source))
    for ext in (".usda", ".usdc", ".usdz"):
        code, out, err = run(capsys, "convert", source, tmp_path / f"walk{ext}", "--units", "asf")
        assert code == 0, err
        assert "31 joints (+7 end sites), 524 frames at 120 fps" in out
        assert np.allclose(usd_world_positions(tmp_path / f"walk{ext}"), reference, atol=1e-3)
    code, out, err = run(capsys, "convert", tmp_path / "walk.usdz", tmp_path / "back.bvh")
    assert code == 0, err
    assert np.allclose(joint_positions(read_motion(tmp_path / "back.bvh")), reference, atol=1e-3)


def test_info_json_describes_the_file(shared_file, capsys):
    code, out, _ = run(capsys, "info", shared_file("cmu/daz_10_01_soccer_kick.bvh"), "--json")
    assert code == 0
    info = json.loads(out)
    assert (info["joints"], info["end_sites"], info["frames"], info["channels"]) == (43, 14, 802, 132)
    assert info["rotation_orders"] == {"ZXY": 42, "ZYX": 1}
    assert info["fps"] == 120.0 and info["duration_s"] == pytest.approx(801 / 120)
    assert info["units"] == "cm" and info["up_axis"] == "Y" and info["root_offset"] == "add"
    hips = info["hierarchy"][0]
    assert hips["name"] == "hip" and hips["parent"] is None and len(hips["channels"]) == 6
    code, out, _ = run(capsys, "info", shared_file("cmu/daz_10_01_soccer_kick.bvh"))
    assert code == 0 and "43 (+14 end sites)" in out and "rShldr" in out


def test_positions_json_equals_library_fk(shared_file, capsys):
    source = shared_file("edge_cases/bvhtoolbox_walk01.bvh")
    code, out, _ = run(capsys, "positions", source, "--frames", "0,50,100", "--joints", "Hips,LeftFoot",
                       "--root-offset", "replace", "--json")
    assert code == 0
    result = json.loads(out)
    motion = read_motion(source, root_offset="replace")
    expected = joint_positions(motion)[[0, 50, 100]][:, [motion.joint_index("Hips"), motion.joint_index("LeftFoot")]]
    assert result["frames"] == [0, 50, 100] and result["joints"] == ["Hips", "LeftFoot"]
    assert np.allclose(result["positions"], expected, atol=1e-9)
    code, out, _ = run(capsys, "positions", source, "--frames", "0:101:50", "--root-offset", "add", "--json")
    added = np.array(json.loads(out)["positions"])
    assert np.allclose(added[:, 0, 1] - expected[:, 0, 1], motion.offsets[0][1])  # root OFFSET added


def test_units_and_up_axis_options_reach_the_stage(shared_file, tmp_path, capsys):
    from pxr import Usd, UsdGeom

    out = tmp_path / "zup.usda"
    code, _, err = run(capsys, "convert", shared_file("other_rigs/ad_cartwheel_clean.bvh"), out,
                       "--units", "in", "--up-axis", "Z")
    assert code == 0, err
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.0254)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetTimeCodesPerSecond() == pytest.approx(119.88)


@pytest.mark.parametrize(("args", "fragment"), [
    (["convert", "{walk}", "{tmp}/x.usda", "--units", "furlong"], "unknown units 'furlong'"),
    (["convert", "{walk}", "{tmp}/x.fbx"], "unknown output format '.fbx'"),
    (["convert", "{tmp}/missing.bvh", "{tmp}/x.usda"], "missing.bvh: cannot read"),
    (["convert", "{walk}", "{walk}"], "overwrite the input"),
    (["convert", "{walk}", "{tmp}/nofolder/x.usda"], "does not exist"),
    (["convert", "{walk}", "{tmp}/x.usda", "--root-offset", "sideways"], "--root-offset"),
    (["positions", "{walk}", "--frames", "9999"], "outside 0..523"),
    (["positions", "{walk}", "--joints", "Hipz"], "did you mean Hips"),
    (["info", "{tmp}/notes.txt"], "unknown input format '.txt'"),
])
def test_bad_options_one_line_exit_2(shared_file, tmp_path, capsys, args, fragment):
    walk = shared_file(WALK)
    (tmp_path / "notes.txt").write_text("hello")
    code, out, err = run(capsys, *[a.format(walk=walk, tmp=tmp_path) for a in args])
    assert code == 2
    lines = without_warnings(err)
    assert len(lines) == 1 and fragment in lines[0], err
    assert not (tmp_path / "x.usda").exists()

"""``--to-up-axis`` (issue 15 item 7): a rigid turn of the whole take, meshes included."""

from __future__ import annotations

import numpy as np
import pytest
from test_usd_dcc import _skinned_stage, usd_core_skinned_world

from usdmotion.io import read_motion, write_motion
from usdmotion.kinematics import joint_positions
from usdmotion.ops.up_axis import convert_up_axis

Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # Rx(+90°): +Y → +Z, +Z → -Y


def test_y_up_take_turned_z_up_and_back(shared_file):
    motion = read_motion(shared_file("other_rigs/wspr_louise_optitrack_arena.bvh"))
    z_up = convert_up_axis(motion, "Z")
    assert z_up.up_axis == "Z"
    assert np.allclose(joint_positions(z_up), joint_positions(motion) @ Y_TO_Z.T, atol=1e-9)
    back = convert_up_axis(z_up, "Y")
    assert back.up_axis == "Y" and np.allclose(joint_positions(back), joint_positions(motion), atol=1e-9)
    assert convert_up_axis(motion, "Y") is motion


def test_carried_mesh_turns_with_the_skeleton(tmp_path):
    source = _skinned_stage(tmp_path / "skinned.usda")  # Y-up
    expected = usd_core_skinned_world(source, range(10))["Body"] @ Y_TO_Z.T
    out = write_motion(convert_up_axis(read_motion(source), "Z"), tmp_path / "zup.usda")
    got = usd_core_skinned_world(out, range(10))["Body"]
    assert np.abs(got - expected).max() <= 1e-5 * float(np.ptp(expected.reshape(-1, 3), axis=0).max())


def test_convert_cli_to_up_axis(shared_file, tmp_path, capsys):
    from pxr import Usd, UsdGeom

    from usdmotion.cli import main

    out = tmp_path / "yup.usda"
    code = main(["convert", str(shared_file("other_rigs/ad_cartwheel_clean.bvh")), str(out), "--units", "in",
                 "--up-axis", "Z", "--to-up-axis", "Y"])
    assert code == 0, capsys.readouterr().err
    assert UsdGeom.GetStageUpAxis(Usd.Stage.Open(str(out))) == UsdGeom.Tokens.y
    source = read_motion(shared_file("other_rigs/ad_cartwheel_clean.bvh"), units="in", up_axis="Z")
    assert np.allclose(joint_positions(read_motion(out)), joint_positions(source) @ Y_TO_Z, atol=1e-4)


def test_a_mesh_usdz_of_a_z_up_source_turned_y_up_passes_the_ar_rules(shared_file, tmp_path, capsys):
    from pxr import Usd, UsdGeom, UsdShade

    from usdmotion.cli import main
    from usdmotion.io.usd import validate_stage
    from usdmotion.io.usd_ar import ar_quick_look_problems

    source = shared_file("edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh")
    zup = tmp_path / "zup.usdz"
    with pytest.warns(UserWarning, match="not AR Quick Look compliant: upAxis is Z"):
        write_motion(read_motion(source, units="in", up_axis="Z"), zup)
    assert any("upAxis is Z" in p for p in ar_quick_look_problems(zup))

    out = tmp_path / "ar.usdz"
    code = main(["convert", str(source), str(out), "--units", "in", "--up-axis", "Z", "--to-up-axis", "Y", "--mesh"])
    err = capsys.readouterr().err
    assert code == 0 and "AR Quick Look" not in err, err
    assert ar_quick_look_problems(out) == [] and validate_stage(out) == []
    stage = Usd.Stage.Open(str(out))
    root = stage.GetDefaultPrim()
    assert Usd.ModelAPI(root).GetKind() == "component"
    lo, hi = (np.array(v) for v in UsdGeom.Boundable(root).GetExtentAttr().Get())
    skinned = usd_core_skinned_world(out, range(0, 75, 5))["Body"].reshape(-1, 3)  # usd-core's skinned body
    assert np.all(lo <= skinned.min(axis=0) + 1e-4) and np.all(hi >= skinned.max(axis=0) - 1e-4)
    body = stage.GetPrimAtPath(root.GetPath().AppendChild("Body"))
    material, _ = UsdShade.MaterialBindingAPI(body).ComputeBoundMaterial()
    assert material and material.GetSurfaceOutput().HasConnectedSource()

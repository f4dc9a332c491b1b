"""The USD writer's structural check (every write) and ``--validate`` (pxr.UsdValidation, before
the file replaces the target): a defect raises, exit 2, and nothing is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from usdmotion.cli import main
from usdmotion.errors import OutputError
from usdmotion.io import read_motion
from usdmotion.io.usd import validate_stage, write_usd

pxr = pytest.importorskip("pxr")
from pxr import Sdf, Usd, UsdSkel  # noqa: E402

WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"


@pytest.fixture(scope="module")
def walk():
    return read_motion(WALK, units="asf").sliced(0, 30)


def _no_binding_api(stage, skeleton):
    skeleton.GetPrim().RemoveAppliedSchema("SkelBindingAPI")


def _no_default_prim(stage, skeleton):
    stage.ClearDefaultPrim()


def _short_joint_names(stage, skeleton):
    skeleton.GetJointNamesAttr().Set(skeleton.GetJointNamesAttr().Get()[:-1])


def _missing_sample(stage, skeleton):
    UsdSkel.Skeleton(skeleton).GetPrim().GetParent().GetChild("Animation").GetAttribute("rotations").ClearAtTime(7)


def _x_up(stage, skeleton):
    stage.SetMetadata("upAxis", "X")


# (defect, what the check says, the pxr.UsdValidation validator that finds it too, or None)
DEFECTS = [
    (_no_binding_api, "without SkelBindingAPI", "MissingSkelBindingAPI"),
    (_no_default_prim, "defaultPrim", "MissingDefaultPrim"),
    (_short_joint_names, "jointNames does not hold 38 values", None),
    (_missing_sample, "rotations has 29 time samples for 30 frames", None),
    (_x_up, "upAxis 'X'", None),
]


@pytest.mark.parametrize(("defect", "said", "validator"), DEFECTS, ids=[d[0].__name__.strip("_") for d in DEFECTS])
def test_a_defective_layer_is_refused_and_nothing_is_written(walk, tmp_path, defect, said, validator):
    found_by_usd_core = []

    def decorate(stage, skeleton):
        defect(stage, skeleton)
        found_by_usd_core.extend(validate_stage(stage))

    out = tmp_path / "walk.usdc"
    with pytest.raises(OutputError, match=f"not valid UsdSkel.*{said}.*nothing written"):
        write_usd(walk, out, decorate=decorate)
    assert list(tmp_path.iterdir()) == []  # neither the output nor a temporary file
    if validator is not None:  # usd-core's validators agree that the stage is invalid
        assert any(validator in problem for problem in found_by_usd_core), found_by_usd_core
    else:
        assert found_by_usd_core == []  # beyond what the validators check


def _unapplied_material_binding(stage, skeleton):
    prop = stage.DefinePrim(skeleton.GetPrim().GetParent().GetPath().AppendChild("Prop"), "Xform")
    prop.CreateRelationship("material:binding").SetTargets([Sdf.Path("/Nowhere")])


def test_validate_runs_usd_cores_validators_before_the_file_is_written(walk, tmp_path):
    # a defect the structural check does not look for (a material binding without MaterialBindingAPI)
    kept = write_usd(walk, tmp_path / "kept.usdc", decorate=_unapplied_material_binding)
    problems = validate_stage(str(kept))
    assert any("MissingMaterialBindingAPI" in p for p in problems), problems
    with pytest.raises(OutputError, match="fails pxr.UsdValidation: .*MissingMaterialBindingAPI.*nothing written"):
        write_usd(walk, tmp_path / "refused.usdc", decorate=_unapplied_material_binding, validate=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.usdc"]


@pytest.mark.parametrize("ext", [".usdc", ".usda", ".usdz"])
def test_convert_validate_option(tmp_path, capsys, ext):
    out = tmp_path / f"walk{ext}"
    assert main(["convert", str(WALK), str(out), "--units", "asf", "--validate"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert validate_stage(str(out)) == []
    stage = Usd.Stage.Open(str(out))
    assert UsdSkel.Root(stage.GetDefaultPrim()) and len(stage.GetPrimAtPath(
        stage.GetDefaultPrim().GetPath().AppendChild("Animation")).GetAttribute("rotations").GetTimeSamples()) == 524

"""Long takes through USD (issue 16, "Must show" 3): the writer frees a handed-over motion
before filling its layer, and the reader copies samples in bulk, naming a bad one exactly.

Figures (peak memory, time against the BVH) come from ``benchmarks/huge_inputs.py`` and
``benchmarks/usd_read.py``; these tests check what the figures rest on: the same file,
the same motion, the take's arrays really gone.
"""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from usdmotion.errors import UsdReadError
from usdmotion.io import read_motion
from usdmotion.io.usd import read_usd, write_usd

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdSkel, Vt  # noqa: E402

# Root motion only (CMU) and position channels on every joint (Bandai): both sample layouts.
TAKES = ["cmu/cgspeed_12_01_walk.bvh", "bandai1/dataset-1_walk_normal_001.bvh"]


@pytest.mark.parametrize("name", TAKES, ids=[t.split("/")[-1] for t in TAKES])
def test_handed_over_motion_is_freed_before_the_layer_fills_and_the_file_is_the_same(shared_file, tmp_path, name):
    path = shared_file(name)
    kept = write_usd(read_motion(path, units="cm"), tmp_path / "kept.usdc")
    take = [read_motion(path, units="cm")]
    rotations = weakref.ref(take[0].rotations)
    seen = {}

    def decorate(stage, skeleton):  # runs after every sample is in the layer
        seen["alive"] = rotations() is not None
        seen["frames"] = len(UsdSkel.Animation(stage.GetPrimAtPath(skeleton.GetPath().GetParentPath()
                                                                   .AppendChild("Animation")))
                             .GetRotationsAttr().GetTimeSamples())

    handed = write_usd(take, tmp_path / "handed.usdc", name="kept", decorate=decorate)
    assert take == [] and seen["alive"] is False
    assert seen["frames"] == read_motion(path, units="cm").n_frames
    assert handed.read_bytes() == kept.read_bytes()


def _stage_with_short_sample(path, bad_time: int, n_frames: int = 6):
    """A 3-joint SkelAnimation whose rotations at ``bad_time`` hold 2 values, not 3."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdSkel.Root.Define(stage, "/R")
    skel = UsdSkel.Skeleton.Define(stage, "/R/Skel")
    joints = Vt.TokenArray(["a", "a/b", "a/b/c"])
    skel.CreateJointsAttr(joints)
    rest = np.tile(np.eye(4), (3, 1, 1))
    rest[1:, 3, 1] = 1.0
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray.FromNumpy(rest))
    bind = rest.copy()
    bind[:, 3, 1] = [0.0, 1.0, 2.0]  # world rest: the chain of 1-unit bones
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray.FromNumpy(bind))
    anim = UsdSkel.Animation.Define(stage, "/R/Anim")
    anim.CreateJointsAttr(joints)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    rng = np.random.default_rng(0)
    for t in range(n_frames):
        q = rng.normal(size=(2 if t == bad_time else 3, 4)).astype(np.float32)
        anim.GetRotationsAttr().Set(Vt.QuatfArray.FromNumpy(q / np.linalg.norm(q, axis=1, keepdims=True)), t)
        anim.GetTranslationsAttr().Set(Vt.Vec3fArray.FromNumpy(rest[:, 3, :3].astype(np.float32)), t)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("bad_time", [0, 3, 5])
def test_bulk_sample_copy_names_the_first_bad_sample(tmp_path, bad_time):
    path = _stage_with_short_sample(tmp_path / "short.usda", bad_time)
    with pytest.raises(UsdReadError, match=rf"rotations at time {bad_time} has 2 values for 3 joints"):
        read_usd(path)


def test_bulk_sample_copy_reads_what_usd_core_reads(tmp_path):
    path = _stage_with_short_sample(tmp_path / "ok.usda", bad_time=-1)
    motion = read_usd(path)
    stage = Usd.Stage.Open(str(path))
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/R/Anim"))
    expected = np.array([np.array(anim.GetRotationsAttr().Get(t)) for t in range(6)], np.float64)  # xyzw
    wxyz = np.concatenate([expected[..., 3:], expected[..., :3]], axis=-1)
    assert motion.n_frames == 6
    assert np.allclose(motion.rotations, wxyz / np.linalg.norm(wxyz, axis=-1, keepdims=True), atol=1e-7)
    assert motion.root_translation.dtype == np.float64 and motion.joint_translations is None

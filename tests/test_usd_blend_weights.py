"""Animated blend-shape weights (a SkelAnimation's ``blendShapes`` / ``blendShapeWeights``
time samples) carried through convert, trim and retime (issue 15 item 3).

The reference is usd-core itself: its ``UsdSkel.BakeSkinning`` of the output (which applies
the blend shapes with the animated weights, then the skinning) equals its bake of the input,
and the weights read back by usd-core equal the input's, sliced or linearly interpolated
(``numpy.interp``, the interpolation USD applies between samples) at the output's frames.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_usd_dcc import POSITION_TOL, _skinned_stage, usd_core_baked_world

from usdmotion.cli import main
from usdmotion.io import read_motion, write_motion

pxr = pytest.importorskip("pxr")
from pxr import Gf, Usd, UsdSkel, Vt  # noqa: E402

FRAMES = 10
SHAPES = ("smile", "blink")


def source_weights() -> np.ndarray:
    """``(FRAMES, 2)`` weights, exact in float32: smile ramps up, blink pulses."""
    t = np.arange(FRAMES, dtype=np.float64)
    return np.stack([t / (FRAMES - 1), np.where(t % 3 == 0, 1.0, 0.25)], axis=1).astype(np.float32)


def _animated_stage(path):
    """The skinned test character of test_usd_dcc with a second blend shape and both shapes'
    weights animated on its SkelAnimation (one sample per time code, 24 per second)."""
    _skinned_stage(path)
    stage = Usd.Stage.Open(str(path))
    blink = UsdSkel.BlendShape.Define(stage, "/Char/Body/blink")
    blink.CreateOffsetsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0.03)] * 3))
    blink.CreatePointIndicesAttr(Vt.IntArray([1, 2, 30]))
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/Char/Body"))
    binding.GetBlendShapesAttr().Set(Vt.TokenArray(list(SHAPES)))
    binding.GetBlendShapeTargetsRel().SetTargets(["/Char/Body/smile", "/Char/Body/blink"])
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/Char/Arm/Skel_Anim"))
    anim.CreateBlendShapesAttr(Vt.TokenArray(list(reversed(SHAPES))))  # the animation's own order
    weights = anim.CreateBlendShapeWeightsAttr()
    for k, row in enumerate(source_weights()):
        weights.Set(Vt.FloatArray.FromNumpy(row[::-1].copy()), float(k))
    stage.GetRootLayer().Save()
    return path


def usd_core_weights(path) -> tuple[list[str], np.ndarray]:
    """``(names, weights (T, S))`` of the stage's one SkelAnimation, read by usd-core."""
    stage = Usd.Stage.Open(str(path))
    anim = next(UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    attr = anim.GetBlendShapeWeightsAttr()
    return ([str(n) for n in anim.GetBlendShapesAttr().Get()],
            np.array([np.array(attr.Get(t)) for t in attr.GetTimeSamples()]))


def _by_name(names, weights) -> np.ndarray:
    return weights[:, [names.index(s) for s in SHAPES]]


@pytest.fixture()
def source(tmp_path):
    return _animated_stage(tmp_path / "face.usda")


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_convert_carries_the_weights_and_usd_core_bakes_the_same_deformation(source, tmp_path, ext, recwarn):
    motion = read_motion(source)
    assert motion.blend_shape_names == ("blink", "smile")
    out = write_motion(motion, tmp_path / f"out{ext}")
    assert not [w for w in recwarn if "blend" in str(w.message)]  # nothing said to be left out
    names, weights = usd_core_weights(out)
    assert np.array_equal(_by_name(names, weights), source_weights())
    expected = usd_core_baked_world(source, range(FRAMES))["Body"]
    got = usd_core_baked_world(out, range(FRAMES))["Body"]
    height = float(np.ptp(expected.reshape(-1, 3), axis=0).max())
    assert np.abs(got - expected).max() <= POSITION_TOL * height
    moved = np.abs(expected[FRAMES - 1] - usd_core_baked_world(_without_weights(source, tmp_path),
                                                               [FRAMES - 1])["Body"][0]).max()
    assert moved > 100 * POSITION_TOL * height  # the blend shapes visibly move points at the last frame


def _without_weights(source, tmp_path):
    stage = Usd.Stage.Open(str(source))
    path = tmp_path / "no_weights.usda"
    stage.GetRootLayer().Export(str(path))
    stage = Usd.Stage.Open(str(path))
    UsdSkel.Animation(stage.GetPrimAtPath("/Char/Arm/Skel_Anim")).GetBlendShapeWeightsAttr().Clear()
    stage.GetRootLayer().Save()
    return path


def test_trim_command_slices_the_weights(source, tmp_path, capsys):
    out = tmp_path / "trim.usdc"
    assert main(["trim", str(source), str(out), "--frames", "2:7"]) == 0, capsys.readouterr().err
    assert "blend" not in capsys.readouterr().err
    names, weights = usd_core_weights(out)
    assert np.array_equal(_by_name(names, weights), source_weights()[2:7])


def test_resample_command_interpolates_the_weights_as_usd_does(source, tmp_path, capsys):
    out = tmp_path / "slow.usda"
    assert main(["resample", str(source), str(out), "--fps", "60"]) == 0, capsys.readouterr().err
    names, weights = usd_core_weights(out)
    times = np.arange(weights.shape[0]) * 24.0 / 60.0  # the output's frames in source frames
    assert weights.shape[0] == 23 and times[-1] == pytest.approx(FRAMES - 1 - 0.2)
    expected = np.stack([np.interp(times, np.arange(FRAMES), source_weights()[:, s]) for s in range(2)], axis=1)
    assert np.abs(_by_name(names, weights) - expected).max() <= 1e-6


def test_an_operation_that_cannot_map_its_frames_says_the_weights_are_left_out(source):
    motion = read_motion(source)
    with pytest.warns(UserWarning, match=r"animated blend-shape weights \(blink, smile…\) are left out"):
        doubled = motion.with_frames(np.concatenate([motion.rotations] * 2), np.concatenate([motion.root_translation] * 2))
    assert doubled.blend_shape_weights is None
    with pytest.raises(ValueError, match="blend_shape_weights must have shape"):
        type(motion)(**{**{f: getattr(motion, f) for f in motion.__dataclass_fields__},
                        "blend_shape_weights": np.zeros((3, 2))})


def test_render_draws_the_stage_body_with_its_animated_blend_shapes_as_usd_core_bakes_it(source):
    """The rendered stage body's points (``usdmotion.render.views.Actor``, render space: metres, Y up)
    equal usd-core's bake, which applies the animated blend shapes before the skinning."""
    from usdmotion.render.space import to_render_space
    from usdmotion.render.views import Actor

    motion = read_motion(source)
    actor = Actor(motion, np.arange(FRAMES), "body", 96, ghost=False)
    got = actor.skin(np.arange(FRAMES)).positions
    expected = to_render_space(usd_core_baked_world(source, range(FRAMES))["Body"], motion.meters_per_unit,
                               motion.up_axis)
    height = float(np.ptp(expected.reshape(-1, 3), axis=0).max())
    assert np.abs(got - expected).max() <= POSITION_TOL * height
    unshaped = Actor(motion, np.arange(FRAMES), "body", 96, ghost=False)
    unshaped.shapes = None  # the same body drawn without its blend shapes: visibly off at the last frame
    assert np.abs(unshaped.skin(np.arange(FRAMES)).positions[-1] - expected[-1]).max() > 100 * POSITION_TOL * height


def test_render_says_when_the_blend_shape_weights_are_gone(source):
    from usdmotion.render.views import Actor

    motion = read_motion(source)
    with pytest.warns(UserWarning, match="left out"):
        doubled = motion.with_frames(np.concatenate([motion.rotations] * 2),
                                     np.concatenate([motion.root_translation] * 2))
    with pytest.warns(UserWarning, match="Body: the blend shape weights are not carried .* drawn without its "
                                         "blend shapes"):
        actor = Actor(doubled, np.arange(2 * FRAMES), "body", 96, ghost=False)
    assert actor.shapes is None

"""``usdmotion render`` and ``convert --mesh`` from the command line, and bad input:
one-line errors, exit code 2, nothing left behind."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.cli import main

WALK = "cmu/cgspeed_12_01_walk.bvh"
FAST = ["--units", "asf", "--size", "160x120", "--frames", "100:130", "--fps", "10"]


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir())


def test_render_cli_writes_a_video_and_reports_the_rate(shared_file, tmp_path, capsys):
    import av

    code = main(["render", str(shared_file(WALK)), str(tmp_path / "walk.mp4"), *FAST, "--camera", "orbit",
                 "--trace", "com", "--style", "stick"])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "3 frames 160x120" in out.out and "frames/s" in out.out
    with av.open(str(tmp_path / "walk.mp4")) as container:
        assert sum(1 for _ in container.decode(video=0)) == 3
    assert leftovers(tmp_path) == ["walk.mp4"]


@pytest.mark.parametrize("extra, message", [
    (["--camera", "sideways"], "unknown camera preset 'sideways'"),
    (["--frames", "200:200"], "no frames to render"),
    (["--style", "clay"], "unknown style 'clay'"),
    (["--trace", "LeftPinky"], "no joint named 'LeftPinky'"),
    (["--camera", "missing.usda"], "missing.usda: no such camera file"),
    (["--angle", "knee_middle"], "--angle 'knee_middle': unknown angle"),
    (["--angle", "Hips,LeftUpLeg,Nope"], "no joint named 'Nope'"),
    (["--angle", "Hips,LeftUpLeg"], "three joint names"),
    # numpy's "Unable to allocate 1.90 TiB" was the line, without the option
    (["--speed", "1e-9"], "the video would have"),
])
def test_bad_options_fail_in_one_line_without_output(shared_file, tmp_path, capsys, extra, message):
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "out.mp4"), *FAST, *extra])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().startswith("usdmotion: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert leftovers(tmp_path) == []


def test_unwritable_outputs(shared_file, tmp_path, capsys):
    (tmp_path / "afile").write_text("not a folder")
    for target in (tmp_path / "afile" / "out.mp4", tmp_path / "afile" / "frames" / "####.png",
                   tmp_path / "out.avi", tmp_path / "frames" / "no_pattern.png"):
        code = main(["render", str(shared_file(WALK)), str(target), *FAST])
        err = capsys.readouterr().err
        assert code == 2 and err.strip().startswith("usdmotion: error: ") and len(err.strip().splitlines()) == 1, err
    # an existing folder where the video should go: fails at the final rename, leaves nothing
    (tmp_path / "taken.mp4").mkdir()
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "taken.mp4"), *FAST])
    assert code == 2 and "taken.mp4" in capsys.readouterr().err
    assert leftovers(tmp_path) == ["afile", "taken.mp4"] and not any((tmp_path / "taken.mp4").iterdir())


def test_usd_without_skeleton_is_rejected(tmp_path, capsys):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(stage, "/World")
    stage.GetRootLayer().Save()
    code = main(["render", str(tmp_path / "empty.usda"), str(tmp_path / "out.mp4")])
    err = capsys.readouterr().err
    assert code == 2 and "no UsdSkel Skeleton" in err and len(err.strip().splitlines()) == 1
    assert leftovers(tmp_path) == ["empty.usda"]


def test_failure_mid_render_leaves_no_partial_output(shared_file, tmp_path):
    from usdmotion.io import read_motion
    from usdmotion.render import RenderOptions, render_motion

    motion = read_motion(shared_file(WALK), units="asf")
    calls = []

    def stop_after_three(current, total, message):  # a usdmotion.progress.Progress
        calls.append((current, total, message))
        if len(calls) == 3:
            raise KeyboardInterrupt

    for target in (tmp_path / "v.mp4", tmp_path / "seq" / "####.png"):
        with pytest.raises(KeyboardInterrupt):
            render_motion(motion, target, RenderOptions(width=96, height=64, start=0, end=120, fps=30,
                                                        body_resolution=32), progress=stop_after_three)
        calls.clear()
    assert leftovers(tmp_path) == []


def test_convert_mesh_writes_a_valid_skinned_stage(shared_file, tmp_path, capsys):
    from pxr import Usd, UsdSkel

    from usdmotion.io.usd import validate_stage

    out = tmp_path / "walk.usdc"
    assert main(["convert", str(shared_file(WALK)), str(out), "--units", "asf", "--mesh"]) == 0
    assert validate_stage(str(out)) == []
    stage = Usd.Stage.Open(str(out))
    body = stage.GetDefaultPrim().GetChild("Body")
    assert body.HasAPI(UsdSkel.BindingAPI)
    weights = np.array(UsdSkel.BindingAPI(body).GetJointWeightsPrimvar().Get()).reshape(-1, 4)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)
    assert main(["convert", str(shared_file(WALK)), str(tmp_path / "walk.bvh"), "--units", "asf", "--mesh"]) == 2
    assert "--mesh needs a USD or glTF output" in capsys.readouterr().err


def test_more_msaa_samples_than_the_renderer_offers_is_one_line(shared_file, tmp_path, capsys):
    """``--msaa`` above the driver's GL_MAX_SAMPLES (4 on llvmpipe) is refused in one line, not a GL error."""
    from OpenGL import GL

    from usdmotion.render import MSAA_SAMPLES
    from usdmotion.render.gl import offscreen_renderer

    probe = offscreen_renderer(16, 16)
    probe._platform.make_current()
    most = int(GL.glGetIntegerv(GL.GL_MAX_SAMPLES))
    probe.delete()
    above = [n for n in MSAA_SAMPLES if n > most]
    if not above:
        pytest.skip(f"this OpenGL offers {most} samples, as many as --msaa accepts")
    code = main(["render", str(shared_file(WALK)), str(tmp_path / "walk.mp4"), *FAST, "--msaa", str(above[0])])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("usdmotion: error: ") and err.count("\n") == 1, err
    assert f"at most {most} samples" in err
    assert leftovers(tmp_path) == []

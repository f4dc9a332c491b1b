"""Issue 16: bad input never gets past. One test (or a few) per numbered item of the issue
that this branch owns (1–4, 6–8; items 5 and 9, the USD reading internals, are tested
with the USD reader). Every CLI case asserts the contract: one line
``usdmotion: error: FILE[:LINE]: message``, exit 2, no traceback, no raw library
diagnostics, nothing left in the output folder.

Reproducers found by ``benchmarks/fuzz.py`` live in ``tests/data/malformed/fuzz/`` and
are replayed by :func:`test_fuzz_reproducers_stay_fixed`.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.constants import MAX_ABS_VALUE, MAX_JOINT_DEPTH, MAX_JOINTS
from usdmotion.errors import InputError, OutputError
from usdmotion.io import read_motion, write_motion
from usdmotion.io.bvh import read_bvh
from usdmotion.io.bvh_write import write_bvh

HERE = Path(__file__).parent
WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
MALFORMED = HERE / "data" / "malformed"
FUZZ = MALFORMED / "fuzz"


def cli(capfd, *args) -> tuple[int, str, str]:
    """Run the CLI in-process; stdout and stderr captured at the file-descriptor level, so
    USD's C++ diagnostics (written straight to fd 2) are seen too."""
    code = main([str(a) for a in args])
    out, err = capfd.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, path: Path | str, *fragments: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith(f"usdmotion: error: {path}"), line
    assert "Traceback" not in err and "pxrInternal" not in err and ".cpp" not in err
    for fragment in fragments:
        assert fragment in line, line
    return line


def chain_bvh(depth: int, frames: int = 2) -> str:
    lines = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0",
             "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in range(1, depth):
        lines += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["}"] * depth + ["MOTION", f"Frames: {frames}", "Frame Time: 0.04"]
    lines += [" ".join(["0"] * (3 * depth + 3))] * frames
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def walk():
    return read_motion(WALK)


@pytest.fixture
def walk_usda(walk, tmp_path):
    return write_motion(walk.sliced(0, 4), tmp_path / "walk.usda")


# ---------------------------------------------------------------- 1. deep hierarchies


def test_1_a_50000_deep_chain_is_refused_at_the_first_joint_too_deep(tmp_path, capfd):
    src = tmp_path / "chain.bvh"
    src.write_text(chain_bvh(50_000))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code, _, err = cli(capfd, "convert", src, out_dir / "chain.usdc")
    line_no = chain_bvh(MAX_JOINT_DEPTH + 2).splitlines().index(f"JOINT j{MAX_JOINT_DEPTH + 1}") + 1
    assert_one_line_error(code, err, f"{src}:{line_no}:", f"at most {MAX_JOINT_DEPTH}")
    assert list(out_dir.iterdir()) == []


def test_1_the_deepest_chain_allowed_converts_and_its_usd_paths_read_back(tmp_path, capfd):
    src = tmp_path / "chain.bvh"
    src.write_text(chain_bvh(MAX_JOINT_DEPTH + 1))
    code, _, err = cli(capfd, "convert", src, tmp_path / "chain.usdc", "--no-validate")
    assert code == 0, err
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(tmp_path / "chain.usdc"))
    joints = UsdSkel.Skeleton(stage.GetPrimAtPath("/chain/Skeleton")).GetJointsAttr().Get()
    assert len(joints) == MAX_JOINT_DEPTH + 1
    assert str(joints[-1]).count("/") == MAX_JOINT_DEPTH  # usd-core sees the full chain
    back = read_motion(tmp_path / "chain.usdc")
    assert back.n_joints == MAX_JOINT_DEPTH + 1 and np.all(back.parents[1:] == np.arange(MAX_JOINT_DEPTH))


def test_1_motion_topology_refuses_too_deep_and_too_many_joints():
    from usdmotion.motion import validate_topology

    ok, reason = validate_topology(np.arange(-1, MAX_JOINT_DEPTH + 1))  # a chain one level too deep
    assert not ok and f"at most {MAX_JOINT_DEPTH}" in reason
    assert validate_topology(np.arange(-1, MAX_JOINT_DEPTH))[0]
    ok, reason = validate_topology(np.r_[-1, np.zeros(MAX_JOINTS, int)])  # wide: one joint too many
    assert not ok and f"at most {MAX_JOINTS}" in reason


def test_1_a_too_deep_usd_skeleton_is_refused_naming_the_file(tmp_path, capfd):
    from pxr import Usd, UsdSkel, Vt

    path = tmp_path / "deep.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdSkel.Root.Define(stage, "/R")
    skel = UsdSkel.Skeleton.Define(stage, "/R/Skeleton")
    tokens = ["/".join(f"j{k}" for k in range(d + 1)) for d in range(MAX_JOINT_DEPTH + 2)]
    skel.CreateJointsAttr(Vt.TokenArray(tokens))
    eye = np.broadcast_to(np.eye(4), (len(tokens), 4, 4)).copy()
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray.FromNumpy(eye))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray.FromNumpy(eye))
    stage.GetRootLayer().Save()
    code, _, err = cli(capfd, "info", path)
    assert_one_line_error(code, err, path, f"at most {MAX_JOINT_DEPTH}")


# ------------------------------------------------------------ 2. beyond float32


@pytest.mark.parametrize("value", ["1e39", "1e308", "-3.5e38"])
def test_2_root_positions_beyond_float32_are_refused_with_their_line(tmp_path, capfd, value):
    text = WALK.read_text().splitlines()
    data_start = next(i for i, line in enumerate(text) if line.startswith("Frame Time")) + 1
    row = text[data_start + 3].split()
    row[0] = value
    text[data_start + 3] = " ".join(row)
    src = tmp_path / "huge.bvh"
    src.write_text("\n".join(text) + "\n")
    code, _, err = cli(capfd, "convert", src, tmp_path / "huge.usdc")
    assert_one_line_error(code, err, f"{src}:{data_start + 4}:", "beyond")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["huge.bvh"]


def test_2_the_usd_writer_refuses_values_float32_cannot_hold(walk, tmp_path):
    import dataclasses

    from usdmotion.io.usd import write_usd

    huge = dataclasses.replace(walk.sliced(0, 3), root_translation=np.full((3, 3), 1e39))
    with pytest.raises(OutputError, match="float32"):
        write_usd(huge, tmp_path / "huge.usdc")
    # write_motion refuses it before, as beyond what any reader accepts (±1e15)
    with pytest.raises(OutputError, match=r"huge.usdc: not written: the result's root translation at frame 0: 1e\+39 "):
        write_motion(huge, tmp_path / "huge.usdc")
    assert list(tmp_path.iterdir()) == []
    big = dataclasses.replace(walk.sliced(0, 3), root_translation=np.full((3, 3), MAX_ABS_VALUE))
    back = read_motion(write_motion(big, tmp_path / "big.usdc"))  # the largest accepted value survives
    assert np.all(np.isfinite(back.root_translation))
    assert np.allclose(back.root_translation, np.float32(MAX_ABS_VALUE), rtol=1e-7)


# ----------------------------------------- 3. NumPy warnings never leak; errors name the file


def _set_rotation_sample(path: Path, frame: int, value) -> None:
    from pxr import Gf, Usd, UsdSkel

    stage = Usd.Stage.Open(str(path))
    anim = next(UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    rotations = anim.GetRotationsAttr().Get(frame)
    rotations[1] = Gf.Quatf(*value)
    anim.GetRotationsAttr().Set(rotations, frame)
    stage.GetRootLayer().Save()


@pytest.mark.parametrize("value", [(math.nan, 0, 0, 0), (1e38, 1e38, 1e38, 1e38)])
def test_3_a_broken_quaternion_in_a_usd_gives_one_line_naming_the_file(walk_usda, tmp_path, capfd, value):
    _set_rotation_sample(walk_usda, 2, value)
    code, _, err = cli(capfd, "convert", walk_usda, tmp_path / "back.bvh")
    assert_one_line_error(code, err, walk_usda)
    assert "warning" not in err and "encountered" not in err.split(str(walk_usda), 1)[0]
    assert not (tmp_path / "back.bvh").exists()


@pytest.mark.parametrize("fps", [math.inf, 1e300])
def test_3_a_usd_with_an_absurd_frame_rate_is_refused_naming_the_file(walk_usda, capfd, fps):
    from pxr import Usd

    stage = Usd.Stage.Open(str(walk_usda))
    stage.SetTimeCodesPerSecond(fps)
    stage.GetRootLayer().Save()
    code, _, err = cli(capfd, "info", walk_usda)
    line = assert_one_line_error(code, err, walk_usda)
    assert "fps" in line or "frame rate" in line or "timeCodesPerSecond" in line


def test_3_a_usd_with_zero_meters_per_unit_is_refused_naming_the_file(walk_usda, capfd):
    text = walk_usda.read_text()
    walk_usda.write_text(re.sub(r"metersPerUnit = [0-9.e-]+", "metersPerUnit = 0", text))
    assert "metersPerUnit = 0\n" in walk_usda.read_text()
    code, _, err = cli(capfd, "info", walk_usda)
    assert_one_line_error(code, err, walk_usda, "metersPerUnit")


def test_3_library_errors_are_input_errors_with_the_path(walk_usda):
    text = walk_usda.read_text()
    walk_usda.write_text(re.sub(r"metersPerUnit = [0-9.e-]+", "metersPerUnit = -1", text))
    with pytest.raises(InputError) as info:
        read_motion(walk_usda)
    assert info.value.path == str(walk_usda)


# -------------------------------------------------------------- 4. USD C++ diagnostics


def test_4_a_usda_parse_error_names_the_file_and_line_without_cpp_noise(tmp_path, capfd):
    path = tmp_path / "bad.usda"
    path.write_text('#usda 1.0\n(\n  defaultPrim = "A"\n)\ndef Xform "A"\n{\n'
                    '  float3 xformOp:translate = (1, 2\n}\n')
    code, _, err = cli(capfd, "info", path)
    assert_one_line_error(code, err, f"{path}:8:", "parse error", "</A.xformOp:translate>")


SKELETON = ('#usda 1.0\n(\n  defaultPrim = "R"\n)\ndef SkelRoot "R"\n{\n  def Skeleton "Skeleton"\n  {\n'
            '    uniform token[] joints = ["A", "A/B"]\n'
            '    uniform matrix4d[] restTransforms = [( (1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1) ){rest}]\n'
            '    uniform matrix4d[] bindTransforms = [( (1,0,0,0),(0,1,0,0),(0,0,1,0),(0,0,0,1) )]\n  }\n}\n')


def test_4_a_usd_warning_on_a_readable_stage_becomes_one_usdmotion_warning(tmp_path, capfd):
    path = tmp_path / "skel.usda"
    path.write_text(SKELETON.replace("{rest}", ", ( (1,0,0,0),(0,1,0,0),(0,0,1,0),(0,1,0,1) )"))
    code, out, err = cli(capfd, "info", path)
    assert code == 0, err
    assert err.strip().splitlines() == [
        f"usdmotion: warning: {path}: USD: /R/Skeleton: size of 'bindTransforms' attr [1] does not match the "
        "number of joints in the 'joints' attr [2]."]
    assert "joints      2" in out


def test_4_usd_diagnostics_behind_a_refusal_are_folded_into_its_one_line(tmp_path, capfd):
    path = tmp_path / "skel.usda"
    path.write_text(SKELETON.replace("{rest}", ""))  # one rest transform for two joints: unusable
    code, _, err = cli(capfd, "info", path)
    line = assert_one_line_error(code, err, path, "USD: /R/Skeleton: size of '", "does not match the number of joints")
    assert "Warning: in" not in line


def test_4_usd_error_message_prefers_the_parse_record():
    from usdmotion.usd_diagnostics import usd_error_message

    text = ("\n\tError in 'pxrInternal_v0_26_11__pxrReserved__::Sdf_TextFileFormatParser::_RaiseErrorPEGTL' at "
            "line 48 in file /opt/USD/pxr/usd/sdf/textParserHelpers.h : '/x/a.usda:12:3: parse error matching "
            "pxrInternal_v0_26_11__pxrReserved__::Sdf_TextFileFormatParser::TupleValueClose at '}'\n'\n\tError in "
            "'pxrInternal_v0_26_11__pxrReserved__::UsdStage::Open' at line 1287 in file /opt/USD/pxr/usd/usd/"
            "stage.cpp : 'Failed to open layer @/x/a.usda@'")
    assert usd_error_message(text) == (12, "parse error matching TupleValueClose at '}'")
    assert usd_error_message("Error in 'f' at line 1 in file x.cpp : 'boom'") == (None, "boom")


def test_4_a_corrupted_usdc_does_not_print_usds_own_posix_madvise_line(capfd, tmp_path):
    """usd-core's crate reader writes ``failed call to posix_madvise(…)`` straight to fd 2
    (C++, past the Tf diagnostic trap) for this fuzzed file; only our one line is seen."""
    path = FUZZ / "convert_usdc_003.usdc"
    for args in (("info", path), ("convert", path, tmp_path / "out.bvh")):
        code, _, err = cli(capfd, *args)
        assert_one_line_error(code, err, path, "cannot open as USD")
        assert "madvise" not in err
    assert not list(tmp_path.iterdir())


def test_4_what_is_printed_past_usdmotion_during_a_usd_read_becomes_its_warnings(tmp_path):
    """Lines written to fd 2 while a stage is read, by native code or by the Python bindings
    printing an error themselves, become ``usdmotion: warning: FILE: USD: …``; usdmotion's own
    warnings written meanwhile pass unchanged, in order; fd 2 is restored afterwards (checked
    in a subprocess, where sys.stderr is fd 2 as in the installed command)."""
    path = tmp_path / "walk.usda"
    write_motion(read_motion(WALK, units="asf").sliced(0, 3), path)
    script = f"""
import os, sys, warnings
from usdmotion.cli import _show_warning
from usdmotion.errors import UsdMotionWarning
from usdmotion.io import read_motion
from usdmotion.usd_diagnostics import usd_diagnostics
warnings.showwarning = _show_warning
with usd_diagnostics({str(path)!r}):
    os.write(2, b"native: something C++ said\\n")
    warnings.warn("ours, inside the block", UsdMotionWarning)
    print("TypeError: No to_python (by-value) converter found", file=sys.stderr)
    read_motion({str(path)!r})
os.write(2, b"after the block\\n")
"""
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        "usdmotion: warning: ours, inside the block",
        f"usdmotion: warning: {path}: USD: native: something C++ said",
        f"usdmotion: warning: {path}: USD: TypeError: No to_python (by-value) converter found",
        "after the block"]


def test_4_native_stderr_is_dropped_when_the_read_fails_and_nests(capfd):
    from usdmotion.errors import UsdReadError
    from usdmotion.usd_diagnostics import native_stderr, usd_diagnostics

    with pytest.raises(UsdReadError), usd_diagnostics("x.usdc"):
        with native_stderr() as inner:
            os.write(2, b"inner\n")
        assert inner == ["inner"]
        os.write(2, b"outer\n")
        raise UsdReadError("x.usdc", "refused")
    os.write(2, b"restored\n")
    assert capfd.readouterr().err == "restored\n"


@pytest.mark.parametrize("name", ["convert_usdc_007.usdc", "convert_usdc_008.usdc"])
def test_4_a_usdc_whose_counts_ask_for_gigabytes_is_refused_without_taking_them(tmp_path, name):
    """Fuzz finds: 19 kB crate files whose stored counts made USD allocate and fill 8.5 GB
    (the campaign's process was killed by the OOM killer) and 3.7 GB. Read capped, each is
    one line and the process stays small. The child's own peak RSS (``wait4``); a 16 GiB
    ``RLIMIT_AS`` only keeps a regression from taking the machine with it."""
    import resource

    path = FUZZ / name
    err = tmp_path / "err.txt"

    def safety_net():
        resource.setrlimit(resource.RLIMIT_AS, (16 << 30, resource.getrlimit(resource.RLIMIT_AS)[1]))

    with open(err, "wb") as stderr:
        proc = subprocess.Popen([sys.executable, "-m", "usdmotion", "info", str(path)], stdout=subprocess.DEVNULL,
                                stderr=stderr, preexec_fn=safety_net)
        _, status, usage = os.wait4(proc.pid, 0)
    assert os.waitstatus_to_exitcode(status) == 2
    line = assert_one_line_error(2, err.read_text(), path, "damaged", "bad_alloc")
    assert "@" not in line  # USD's ``while reading @file@`` is not repeated
    assert usage.ru_maxrss < 1 << 20, f"peak RSS {usage.ru_maxrss / 1024:.0f} MiB"  # kB


def test_4_a_read_past_the_end_of_a_crate_file_is_named_damaged_in_one_line():
    from usdmotion.usd_diagnostics import usd_error_message

    said = ("Error in 'pxrInternal_v0_26_11__pxrReserved__::UsdStage::Open' at line 1 in file stage.cpp : "
            "'Encountered: Read out-of-bounds: 3743481696 bytes at offset 19202 in a mapping of length 19397, "
            "while reading @/data/take.usdc@'")
    assert usd_error_message(said) == (None, "damaged: a size stored in the file points past its end (USD: Read "
                                             "out-of-bounds: 3743481696 bytes at offset 19202 in a mapping of "
                                             "length 19397)")


def test_4_the_address_space_cap_nests_and_restores_the_limit_before_it():
    import resource

    from usdmotion.address_space import _in_use, budget, capped_address_space

    before = resource.getrlimit(resource.RLIMIT_AS)
    with capped_address_space(WALK):
        first = resource.getrlimit(resource.RLIMIT_AS)[0]
        assert first != resource.RLIM_INFINITY and first >= budget(WALK)
        with capped_address_space(WALK):  # a second read beside it (a Studio thread) gets room too
            assert resource.getrlimit(resource.RLIMIT_AS)[0] == first + budget(WALK)
        assert resource.getrlimit(resource.RLIMIT_AS)[0] >= first
    assert resource.getrlimit(resource.RLIMIT_AS) == before
    stricter = _in_use() + (1 << 30)  # a limit the user set (ulimit -v), lower than the cap would be: kept
    resource.setrlimit(resource.RLIMIT_AS, (stricter, before[1]))
    try:
        with capped_address_space(WALK):
            assert resource.getrlimit(resource.RLIMIT_AS)[0] == stricter
    finally:
        resource.setrlimit(resource.RLIMIT_AS, before)


# -------------------------------------------------------- 6. options and documents


def test_6_a_joint_map_of_nested_arrays_is_refused_not_an_internal_error(tmp_path, capfd):
    path = tmp_path / "map.json"
    path.write_text('{"joints": ' + "[" * 5000 + "]" * 5000 + "}")  # ~10 kB
    code, _, err = cli(capfd, "retarget", WALK, tmp_path / "out.bvh", "--units", "asf", "--remove", "LThumb",
                       "--map", path)
    assert_one_line_error(code, err, path, "nested more than")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.json"]


NESTED = "[" * 5000 + "]" * 5000  # ~10 kB: deeper than Python's JSON decoder recurses


@pytest.mark.parametrize(("name", "text", "command"), [
    # fuzz campaign find: segment-eval's check for a saved segments JSON recursed into the labels
    ("labels.json", NESTED, ["segment-eval", WALK, "{file}", "--units", "asf"]),
    ("labels.json", "5", ["segment-eval", WALK, "{file}", "--units", "asf"]),  # ``"cuts" in 5``: TypeError
    ("pipeline.json", NESTED, ["edit", WALK, "{out}.bvh", "--units", "asf", "--pipeline", "{file}"]),
    ("take.gltf", '{"asset": {"version": "2.0"}, "extras": ' + NESTED + "}", ["convert", "{file}", "{out}.usda"]),
])
def test_6_every_json_input_refuses_absurd_nesting_in_one_line(tmp_path, capfd, name, text, command):
    path = tmp_path / name
    path.write_text(text)
    args = [str(a).replace("{file}", str(path)).replace("{out}", str(tmp_path / "out")) for a in command]
    code, _, err = cli(capfd, *args)
    line = assert_one_line_error(code, err, path)
    assert "internal error" not in line and len(line) > len(f"usdmotion: error: {path}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_6_json_or_none_refuses_what_parse_text_refuses():
    from usdmotion.schemas import json_or_none

    assert json_or_none(b'{"cuts": [1]}') == {"cuts": [1]}
    assert json_or_none(NESTED) is None
    assert json_or_none("[NaN]") is None
    assert json_or_none(b"\xff{") is None
    assert json_or_none("{") is None


@pytest.mark.parametrize("content", [b"garbage\x00\x01", b"#usda 1.0\ndef Camera \"c\" {\n", b"",
                                     # found by the property test: USD quotes the non-UTF-8 byte in its
                                     # parse error, and the binding cannot even decode its own message
                                     b'#usda 1.0\n(\n    metedef Camera \x80"cam"\n{\n}\n',
                                     # campaign find: finite in USD's doubles, inf in the renderer's float32
                                     b'#usda 1.0\ndef Camera "cam"\n{\n    double3 xformOp:translate = (1e39, 1, 6)\n'
                                     b'    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'])
def test_6_a_corrupted_camera_file_names_the_file(tmp_path, capfd, content):
    camera = tmp_path / "cam.usda"
    camera.write_bytes(content)
    code, _, err = cli(capfd, "render", WALK, tmp_path / "out.mp4", "--units", "asf", "--camera", camera,
                       "--frames", "0:2")
    line = assert_one_line_error(code, err, camera)
    assert len(line) > len(f"usdmotion: error: {camera}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.usda"]


@pytest.mark.parametrize("option", [("--msaa", "-1"), ("--msaa", "3"), ("--quality", "99"), ("--fps", "inf"),
                                    ("--speed", "nan"), ("--grid-scale", "inf"), ("--frames", "-1:"),
                                    ("--size", "10x10")])
def test_6_render_options_are_checked_before_any_work(tmp_path, capfd, option):
    missing = tmp_path / "missing.bvh"  # never read: the option is refused first
    code, _, err = cli(capfd, "render", missing, tmp_path / "out.mp4", *option)
    line = assert_one_line_error(code, err, "")
    assert "missing.bvh" not in line
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------- 7. signals


@pytest.fixture(scope="module")
def big_bvh(tmp_path_factory, walk):
    """A 40,000-frame walk (~25 MB): long enough to be caught mid-write."""
    n = 40_000
    k = n // walk.n_frames + 1
    big = walk.with_frames(np.tile(walk.rotations, (k, 1, 1))[:n], np.tile(walk.root_translation, (k, 1))[:n])
    return write_bvh(big, tmp_path_factory.mktemp("big") / "big.bvh")


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_7_a_signal_during_the_usd_write_removes_the_temporary_file(big_bvh, tmp_path, sig, code):
    out = tmp_path / "big.usdc"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "usdmotion", "convert", str(big_bvh), str(out), "--units", "asf"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".big.*.tmp.usdc")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)  # the atomic writer's temporary file appears: the USD write has begun
    assert proc.poll() is None, "the convert ended before its write could be interrupted"
    sent = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    print(f"{signal.Signals(sig).name}: exited {time.monotonic() - sent:.2f} s after the signal")
    assert proc.returncode == code, err
    assert err.strip().splitlines() == [
        "usdmotion: error: " + ("interrupted" if sig == signal.SIGINT else "terminated by SIGTERM")
        + "; no partial output was kept"]
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------- 8. lenient cases decided


def test_8_nan_infinite_and_huge_weights_in_a_joint_map_are_refused(tmp_path):
    from usdmotion.ops.retarget.jointmap import JointMapError, load_joint_map

    for text, fragment in (('{"auto": true, "weights": {"Hips": NaN}}', "NaN"),
                           ('{"auto": true, "weights": {"Hips": Infinity}}', "Infinity"),
                           ('{"auto": true, "weights": {"Hips": 1e400}}', "/weights/Hips")):
        path = tmp_path / "map.json"
        path.write_text(text)
        with pytest.raises(JointMapError, match=fragment) as info:
            load_joint_map(path)
        assert info.value.path == str(path)


def test_8_an_all_zero_weight_map_is_refused(walk, tmp_path, capfd):
    path = tmp_path / "zero.json"
    path.write_text(json.dumps({"auto": True, "weights": {n: 0 for n in walk.joint_names
                                                          if n not in ("LThumb", "LThumb_End")}}))
    code, _, err = cli(capfd, "retarget", WALK, tmp_path / "out.bvh", "--units", "asf", "--remove", "LThumb",
                       "--map", path)
    assert code == 2 and "0 target joint(s) could be matched" in err
    assert not (tmp_path / "out.bvh").exists()


def test_8_an_end_site_without_offset_is_accepted_as_a_tip_at_its_joint(tmp_path):
    text = WALK.read_text()
    start = text.index("End Site")
    block_end = text.index("}", start)
    body = text[start:block_end]
    offset_line = next(line for line in body.splitlines() if "OFFSET" in line)
    path = tmp_path / "tip.bvh"
    path.write_text(text[:start] + body.replace(offset_line, "") + text[block_end:])
    motion = read_bvh(path)
    tip = int(np.flatnonzero(motion.end_sites)[0])
    assert np.all(motion.offsets[tip] == 0)
    reference = read_bvh(WALK)
    assert np.array_equal(np.delete(motion.offsets, tip, 0), np.delete(reference.offsets, tip, 0))


# ------------------------------------------------ huge takes: memory of a long convert


def test_long_take_memory_extent_is_the_min_max_of_all_joint_positions():
    """The chunked bounds the USD writer authors as ``extent`` equal the min/max of the full
    ``(F, J, 3)`` positions (chunks of 7 frames: not a divisor of the take)."""
    from usdmotion.kinematics import joint_positions, position_bounds

    motion = read_motion(WALK, units="asf").sliced(0, 101)
    positions = joint_positions(motion).reshape(-1, 3)
    lo, hi = position_bounds(motion, chunk_frames=7)
    assert np.array_equal(lo, positions.min(axis=0)) and np.array_equal(hi, positions.max(axis=0))


def test_long_take_memory_rows_are_not_copied_and_dropped_when_not_written(tmp_path):
    """The parsed rows go into the Motion as they are (``source_channels`` shares the parser's
    array); a USD or glTF output drops them (only a BVH write uses them), a BVH keeps them."""
    from usdmotion.io.bvh import motion_from_bvh, parse_bvh
    from usdmotion.io.convert import kept_for

    data = parse_bvh(WALK.read_bytes(), WALK)
    motion = motion_from_bvh(data)
    assert motion.source_channels is data.values
    assert kept_for(motion, tmp_path / "a.usdc").source_channels is None
    assert kept_for(motion, tmp_path / "a.glb").source_channels is None
    assert kept_for(motion, tmp_path / "a.bvh") is motion


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
def test_long_take_memory_rows_parse_from_a_view_of_the_file(newline):
    """The rows are read from a memoryview of the file's bytes (no copy of a long take's rows),
    whatever the line ends: the same numbers as the text says."""
    from usdmotion.io.bvh_rows import parse_rows

    rng = np.random.default_rng(3)
    expected = np.round(rng.uniform(-180, 180, (257, 6)), 4)
    buf = (newline.join(" ".join(f"{v:.4f}" for v in row) for row in expected) + newline).encode()
    rows = parse_rows(memoryview(buf), 6, 10, None)
    assert rows.values.shape == (257, 6) and np.array_equal(rows.values, expected)


# ------------------------------------------------------------------ docs/errors.md


def test_errors_catalogue_lists_every_message_of_the_package():
    import importlib.util

    spec = importlib.util.spec_from_file_location("errors_catalogue",
                                                  HERE.parent / "scripts" / "errors_catalogue.py")
    catalogue = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(catalogue)
    doc = (HERE.parent / "docs" / "errors.md").read_text("utf-8")
    assert doc == catalogue.render(), "docs/errors.md is out of date: run .venv/bin/python scripts/errors_catalogue.py"
    found = catalogue.messages()
    assert len(found) > 250
    for _, _, message in found:  # independent of render(): each message text is in the document
        longest = max(catalogue._clean(message).split("…"), key=len).strip()
        assert longest in doc, message  # _clean already escaped it as the table does


# ------------------------------------------------------------- fuzz reproducers


def _reproducers() -> list[dict]:
    manifest = FUZZ / "manifest.json"
    return json.loads(manifest.read_text()) if manifest.is_file() else []


@pytest.mark.parametrize("case", _reproducers(), ids=lambda c: f"{c['entry_point']}-{c['file']}")
def test_fuzz_reproducers_stay_fixed(case, tmp_path):
    """Each defect the campaign found: the same command now ends ``ok`` or ``clean``
    (classified exactly as the campaign does)."""
    from fuzz_support import amc_seed_text, asf_seed_text, expand, run_case

    src = FUZZ / case["file"]
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    walk = tmp_path / "walk120.bvh"  # the campaign's {walk} seed: the first 120 frames of the CMU walk
    if any("{walk}" in a for a in case["args"]):
        write_bvh(read_motion(WALK).sliced(0, 120), walk)
    seeds = {"asf": tmp_path / "seed.asf", "amc": tmp_path / "seed.amc"}  # the campaign's ASF/AMC seeds
    seeds["asf"].write_text(asf_seed_text())
    seeds["amc"].write_text(amc_seed_text())
    args = expand(case["args"], src, out_dir / "out", walk, seeds)
    outcome = run_case(args, out_dir)
    assert outcome.kind in ("ok", "clean"), f"{outcome.reason}\n{outcome.stderr}"

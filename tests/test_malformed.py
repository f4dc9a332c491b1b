"""Every malformed BVH gives a typed error naming its line, and the CLI one line, exit 2,
no traceback and no output file (corpus: tests/data/malformed, built by make_corpus.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from usdmotion.cli import main
from usdmotion.errors import BvhParseError
from usdmotion.io.bvh import read_bvh

CORPUS = Path(__file__).parent / "data" / "malformed"
MANIFEST = json.loads((CORPUS / "manifest.json").read_text())


def test_corpus_is_complete_and_current():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_corpus", CORPUS / "make_corpus.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert len(MANIFEST) >= 40
    assert set(MANIFEST) == set(module.CASES)
    for name, (content, _, _) in module.CASES.items():
        data = content if isinstance(content, bytes) else content.encode("utf-8")
        assert (CORPUS / MANIFEST[name]["file"]).read_bytes() == data, name


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_typed_error_names_file_and_line(name):
    case = MANIFEST[name]
    path = CORPUS / case["file"]
    with pytest.raises(BvhParseError) as info:
        read_bvh(path)
    error = info.value
    assert error.path == str(path)
    assert error.line == case["line"]
    assert case["message"] in error.message
    assert str(error).startswith(f"{path}:{case['line']}")
    assert "\n" not in str(error)


@pytest.mark.parametrize("name", sorted(MANIFEST))
@pytest.mark.parametrize("ext", [".usdc", ".bvh"])
def test_cli_prints_one_line_exits_2_and_writes_nothing(name, ext, tmp_path, capsys):
    case = MANIFEST[name]
    out = tmp_path / f"out{ext}"
    code = main(["convert", str(CORPUS / case["file"]), str(out)])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("usdmotion: error: ")
    assert f"{case['file']}:{case['line']}" in lines[0]
    assert "Traceback" not in captured.err + captured.out
    assert list(tmp_path.iterdir()) == []


def test_console_script_subprocess_has_no_traceback(tmp_path):
    case = MANIFEST["giant_swing_paper"]
    out = tmp_path / "swing.usda"
    result = subprocess.run([sys.executable, "-m", "usdmotion", "convert", str(CORPUS / case["file"]), str(out)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"usdmotion: error: {CORPUS / case['file']}:8:21: OFFSET has 4 values, expected 3"]  # the 4th value
    assert not out.exists()


def test_lenient_option_recovers_frame_count_mismatch(tmp_path, capsys):
    out = tmp_path / "ok.usda"
    path = CORPUS / MANIFEST["frames_more_than_rows"]["file"]
    assert main(["convert", str(path), str(out), "--lenient"]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "Frames: 5" in err and "keeping 2" in err
    assert out.is_file()

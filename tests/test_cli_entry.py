"""The ``usdmotion`` console script as a user runs it (whole processes): no command shows
the help (exit 0, no error line); Ctrl-C while the CLI is still importing is one line and
exit 130, no traceback."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

USDMOTION = Path(sys.executable).parent / "usdmotion"
WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
INTERRUPTED = "usdmotion: error: interrupted; no partial output was kept"


@pytest.mark.parametrize("args, listed", [([], ["convert", "info", "batch", "studio"]),
                                          (["batch"], ["convert", "analyze", "segment", "retarget", "render"])],
                         ids=["usdmotion", "usdmotion-batch"])
def test_no_command_prints_the_help_only(args, listed):
    done = subprocess.run([str(USDMOTION), *args], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert "Usage:" in done.stdout and all(f" {name} " in done.stdout for name in listed), done.stdout


def _interrupt_while_importing() -> tuple[int, list[str], bool]:
    """Start ``usdmotion info``, send SIGINT as soon as it imports typer (after the entry point
    has begun); return the exit code, the stderr lines that are not import timings, and
    whether the signal arrived before ``usdmotion.cli`` had finished importing."""
    env = dict(os.environ, PYTHONPROFILEIMPORTTIME="1")  # -X importtime: a line as each import completes
    proc = subprocess.Popen([str(USDMOTION), "info", str(WALK), "--units", "asf"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)
    lines = []
    for line in proc.stderr:
        lines.append(line.rstrip("\n"))
        if line.startswith("import time:") and "typer" in line:
            proc.send_signal(signal.SIGINT)
            break
    lines += proc.stderr.read().splitlines()
    code = proc.wait(timeout=120)
    imported = {line.split("|")[-1].strip() for line in lines if line.startswith("import time:")}
    return code, [line for line in lines if not line.startswith("import time:")], "usdmotion.cli" not in imported


def test_ctrl_c_during_start_up_is_one_line_and_exit_130():
    during_imports = 0
    for _ in range(5):  # the signal lands within the first tenth of a second; count those that hit the imports
        code, messages, early = _interrupt_while_importing()
        assert code == 130 and messages == [INTERRUPTED], messages
        during_imports += early
        if during_imports >= 2:
            break
    assert during_imports >= 1  # at least one interrupt arrived while the CLI was importing


def test_png_still_ends_without_library_diagnostics(tmp_path):
    """A successful command that wrote PNGs (OpenImageIO) ends with its one line on stdout and
    nothing on stderr: no binding's "leaked instance" report from the interpreter's exit."""
    still = tmp_path / "strobe.png"
    done = subprocess.run([str(USDMOTION), "render", str(WALK), str(still), "--units", "asf", "--size", "320x180",
                           "--strobe", "3", "--frames", "100:200"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"wrote {still}") and still.stat().st_size > 0
    assert done.stderr == ""

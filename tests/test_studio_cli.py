"""``usdmotion studio``: bad roots are one line and exit 2; a real start serves the page."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import urllib.request

from studio_support import REPO


def test_missing_root_is_one_line_exit_2(tmp_path, capsys):
    from usdmotion.cli import main

    assert main(["studio", str(tmp_path / "nope"), "--no-open"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"usdmotion: error: {tmp_path / 'nope'}: no such file or folder"
    (tmp_path / "notes.txt").write_text("x")
    assert main(["studio", str(tmp_path / "notes.txt"), "--no-open"]) == 2
    assert "not a motion file" in capsys.readouterr().err


def test_studio_command_serves_the_bundled_data_on_localhost(tmp_path):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "usdmotion", "studio", "usdmotion/data", "--units", "asf",
                             "--port", "0", "--no-open", "--out", str(tmp_path / "out")],
                            cwd=REPO, env=env, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert line.startswith("usdmotion studio: http://127.0.0.1:"), line
        url = line.split()[2]
        deadline = time.monotonic() + 30
        while True:
            try:
                page = urllib.request.urlopen(url, timeout=10).read().decode()
                break
            except OSError:
                assert time.monotonic() < deadline
                time.sleep(0.1)
        assert "<title>usdmotion studio</title>" in page and "/vendor/three/build/three.module.js" in page
        takes = urllib.request.urlopen(url + "api/takes", timeout=10).read().decode()
        assert '"0/cmu_12_01_walk.bvh"' in takes
    finally:
        proc.terminate()
        proc.wait(20)
    assert not (tmp_path / "out").exists()  # nothing written unless a body was asked for

"""The CLI's reading options are declared once and offered by every command that reads motion."""

from __future__ import annotations

from pathlib import Path

import pytest

from usdmotion.cli import _load_commands, app, main
from usdmotion.errors import InputError
from usdmotion.io import read_motion, write_motion

WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"

READING = ("--units", "--up-axis", "--root-offset", "--lenient", "--ignore-joint-positions", "--skeleton")
#: Commands that do not read a motion file.
NOT_READING = {"synth"}
DETECTOR = ("--param", "--cutoff", "--penalty", "--min-length", "--refine", "--role", "--preset")


def command_names() -> list[str]:
    _load_commands()
    return sorted(c.name or c.callback.__name__.replace("_", "-") for c in app.registered_commands)


def help_text(capsys, command: str) -> str:
    assert main([command, "--help"]) == 0
    return capsys.readouterr().out


def test_the_command_list_is_complete():
    names = command_names()
    assert {"convert", "info", "trim", "segment-eval", "synth"} <= set(names) and len(names) >= 20


@pytest.mark.parametrize("command", sorted(set(command_names()) - NOT_READING))
def test_every_reading_command_offers_the_reading_options(capsys, monkeypatch, command):
    monkeypatch.setenv("COLUMNS", "200")  # rich would shorten long option names
    text = help_text(capsys, command)
    missing = [option for option in READING if option not in text]
    assert missing == []


@pytest.mark.parametrize("command", ["segment", "segment-eval"])
def test_both_segment_commands_offer_the_detector_options(capsys, monkeypatch, command):
    monkeypatch.setenv("COLUMNS", "200")  # rich would shorten long option names
    text = help_text(capsys, command)
    assert [option for option in DETECTOR if option not in text] == []


def test_editing_commands_pass_lenient_on(tmp_path, capsys):
    # A BVH whose 'Frames:' promises more rows than it has: strict reading fails, --lenient reads it.
    lines = tmp_path / "src.bvh"
    motion = read_motion(WALK)
    write_motion(motion, lines)
    text = lines.read_text().replace(f"Frames: {motion.n_frames}", f"Frames: {motion.n_frames + 5}")
    lines.write_text(text)
    out = tmp_path / "out.bvh"
    assert main(["trim", str(lines), str(out), "--frames", "0:10"]) == 2
    assert "Frames" in capsys.readouterr().err and not out.exists()
    assert main(["trim", str(lines), str(out), "--frames", "0:10", "--lenient"]) == 0
    assert read_motion(out).n_frames == 10


def test_skeleton_is_refused_for_bvh(tmp_path, capsys):
    with pytest.raises(InputError, match="--skeleton does not apply to BVH"):
        read_motion(WALK, skeleton="Armature")
    assert main(["info", str(WALK), "--skeleton", "Armature"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usdmotion: error: ") and "--skeleton" in err and "Traceback" not in err

"""Issue 15 item 9: Euler range summaries unwrap; frame times are written back as read."""

from __future__ import annotations

import numpy as np
import pytest

from usdmotion.io import read_motion, write_motion
from usdmotion.io.bvh import motion_from_bvh, parse_bvh
from usdmotion.ops.analyse import analyse
from usdmotion.ops.analyse.report import joint_summary
from usdmotion.rotations import quat_conjugate, quat_mul

# A thigh whose X angle swings 150° → 210° → 150°; the file writes it wrapped to ±180°.
SWING = [150, 165, 180, 195, 210, 195, 180, 165, 150]
WRAPPED = [((a + 180) % 360) - 180 for a in SWING]


def _swing_motion():
    rows = "".join(f"0 90 0 0 0 0 {x} 0 0\n" for x in WRAPPED)
    text = ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation "
            "Zrotation\nJOINT LeftUpLeg\n{\nOFFSET 10 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\nEnd Site\n{\n"
            f"OFFSET 0 -40 0\n}}\n}}\n}}\nMOTION\nFrames: {len(WRAPPED)}\nFrame Time: 0.01\n{rows}")
    return motion_from_bvh(parse_bvh(text))


def test_euler_range_of_a_swing_through_180_degrees_is_unwrapped():
    motion = _swing_motion()
    assert np.ptp(WRAPPED) > 300  # the file's values do wrap
    rom = joint_summary(analyse(motion), motion.joint_index("LeftUpLeg"))["range_of_motion"]
    q = motion.rotations[:, 1]
    relative = quat_mul(quat_conjugate(q[0]), q)  # independent: rotation angle from the first frame
    swept = np.degrees(2 * np.arccos(np.clip(np.abs(relative[:, 0]), 0, 1))).max()
    assert rom["x"]["range"] == pytest.approx(swept, abs=1e-3) == pytest.approx(60.0, abs=1e-3)


@pytest.mark.parametrize("via", [".bvh", ".usda"])
def test_frame_time_is_written_back_as_read(shared_file, tmp_path, via):
    source = shared_file("other_rigs/ad_cartwheel_clean.bvh")  # Frame Time: 0.008342
    stated = next(line for line in source.read_text().splitlines() if line.startswith("Frame Time"))
    motion = read_motion(source, units="in", up_axis="Z")
    middle = write_motion(motion, tmp_path / f"mid{via}")
    back = write_motion(read_motion(middle), tmp_path / "back.bvh")
    written = next(line for line in back.read_text().splitlines() if line.startswith("Frame Time"))
    assert written.split(":")[1].strip() == stated.split(":")[1].strip()
    assert read_motion(back).fps == motion.fps

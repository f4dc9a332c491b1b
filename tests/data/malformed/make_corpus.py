"""Write the malformed-BVH corpus used by tests/test_malformed.py.

Run ``python tests/data/malformed/make_corpus.py`` to regenerate. Every case is a small
valid file with one defect; ``manifest.json`` records, for each file, the 1-based line
the error must name (found from a marker substring, so it cannot drift) and a fragment
of the expected message.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent

VALID = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.033333
0 90 0 0 0 0 0 0 0
1 90 0 10 0 0 5 0 0
"""

# The gymnast model exactly as printed in the paper (ALGORITHMS.md §2): an OFFSET with
# four numbers, Body and Legs as siblings, unbalanced braces.
GIANT_SWING_PAPER = """HIERARCHY
ROOT Arms
{
  OFFSET 0.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Body
  {
    OFFSET 0 0 10.0 0.0
    CHANNELS 3 Zrotation Xrotation Yrotation
  }
  JOINT Legs
  {
    OFFSET 0 0 12.0 0.0
    CHANNELS 3 Zrotation Xrotation Yrotation
  }
  End Site
  {
    OFFSET 0 0 16.0 0.0
  }
} } }
MOTION
Frames: 23
Frame Time: 0.033333
0.0 0.0 0.0 16.6 0.0 0.0 7.0 0.0 0.0 -2.7 0.0 0.0
"""


LAST_LINE = "<last line with content>"


def sub(old: str, new: str, text: str = VALID, count: int = 1) -> str:
    assert old in text, old
    return text.replace(old, new, count)


def deep_unclosed(depth: int) -> str:
    lines = ["HIERARCHY", "ROOT j0", "{", "  OFFSET 0 0 0", "  CHANNELS 3 Zrotation Xrotation Yrotation"]
    for k in range(1, depth):
        lines += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["}"] * (depth - 3)  # three braces short
    lines += ["MOTION", "Frames: 1", "Frame Time: 0.04", " ".join(["0"] * 3 * depth)]
    return "\n".join(lines) + "\n"


# name: (content, marker substring whose first line is the error line (None = line 1,
#        LAST_LINE = the last line with content), message fragment)
CASES: dict[str, tuple[str | bytes, str | None, str]] = {
    "empty": ("", None, "empty file"),
    "whitespace_only": ("  \n\t\n\n", None, "empty file"),
    "binary_nul": ("HIERARCHY\nROOT Hips\x00\x00\n{\n", "ROOT Hips", "NUL"),
    "non_utf8_name": (sub("ROOT Hips", "ROOT H\xefps").encode("latin-1"), "ROOT H", "not UTF-8"),
    "non_utf8_motion": (sub("1 90 0 10", "1 9\xff0 0 10").encode("latin-1"), "1 9", "not UTF-8"),
    "json_not_bvh": ('{"frames": 2, "joints": []}\n', None, "expected HIERARCHY"),
    "no_hierarchy_keyword": (sub("HIERARCHY\n", ""), "ROOT Hips", "expected HIERARCHY"),
    "joint_instead_of_root": (sub("ROOT Hips", "JOINT Hips"), "JOINT Hips", "expected ROOT"),
    "root_without_name": (sub("ROOT Hips", "ROOT"), "ROOT", "has no name"),
    "missing_open_brace": (sub("ROOT Hips\n{\n", "ROOT Hips\n"), "OFFSET 0 0 0", "expected '{'"),
    "offset_four_values": (sub("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 10 0 0\n    CHANNELS"),
                           "OFFSET 0 10 0 0", "OFFSET has 4 values, expected 3"),
    "offset_two_values": (sub("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 10\n    CHANNELS"),
                          "OFFSET 0 10\n", "OFFSET has 2 values, expected 3"),
    "offset_not_number": (sub("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 ten 0\n    CHANNELS"), "ten",
                          "is not a number"),
    "offset_nan": (sub("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 nan 0\n    CHANNELS"), "nan", "not a finite"),
    "offset_inf": (sub("OFFSET 0 0 0", "OFFSET inf 0 0"), "OFFSET inf", "not a finite"),
    "channels_count_not_int": (sub("CHANNELS 3", "CHANNELS three"), "CHANNELS three", "not an integer"),
    "channels_count_too_big": (sub("CHANNELS 3", "CHANNELS 9"), "CHANNELS 9", "outside 0..6"),
    "channels_fewer_names": (sub("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrotation"),
                             "End Site", "lists 2 channel names"),
    "channels_unknown_name": (sub("Xrotation Yrotation\n    End", "Xrotation Wrotation\n    End"), "Wrotation",
                              "lists 2 channel names"),
    "channels_duplicate": (sub("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Zrotation Yrotation"),
                           "Zrotation Zrotation", "listed twice"),
    "channels_more_names": (sub("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 2 Zrotation Xrotation Yrotation"),
                            "CHANNELS 2", "lists more channel names"),
    "joint_without_offset": (sub("    OFFSET 0 10 0\n    CHANNELS", "    CHANNELS"), "  }\n}", "has no OFFSET"),
    "second_offset": (sub("  OFFSET 0 0 0\n", "  OFFSET 0 0 0\n  OFFSET 1 1 1\n"), "OFFSET 1 1 1", "second OFFSET"),
    "second_channels": (sub("    CHANNELS 3 Zrotation Xrotation Yrotation\n",
                            "    CHANNELS 3 Zrotation Xrotation Yrotation\n    CHANNELS 1 Zrotation\n"),
                        "CHANNELS 1", "second CHANNELS"),
    "missing_close_brace": (sub("  }\n}\nMOTION", "  }\nMOTION"), "MOTION", "1 '}' missing"),
    "extra_close_brace": (sub("}\nMOTION", "}\n}\nMOTION"), "}\nMOTION", "unexpected '}'"),
    "unknown_keyword": (sub("    CHANNELS 3", "    ROTATION 0 0 0\n    CHANNELS 3"), "ROTATION", "unexpected 'ROTATION'"),
    "end_site_misspelt": (sub("End Site", "End Sight"), "End Sight", "expected 'End Site'"),
    "channels_in_end_site": (sub("      OFFSET 0 10 0\n    }", "      OFFSET 0 10 0\n      CHANNELS 1 Zrotation\n    }"),
                             "CHANNELS 1", "unexpected 'CHANNELS' in End Site"),
    "second_root": (sub("}\nMOTION", "}\nROOT Other\n{\n  OFFSET 0 0 0\n}\nMOTION"), "ROOT Other", "second ROOT"),
    "truncated_in_hierarchy": (VALID[: VALID.index("    End Site")], "CHANNELS 3", "ends inside the hierarchy"),
    "no_motion_section": (VALID[: VALID.index("MOTION")], LAST_LINE, "no MOTION section"),
    "missing_frames_line": (sub("Frames: 2\n", ""), "0 90 0 0", "expected 'Frames:'"),
    "frames_not_integer": (sub("Frames: 2", "Frames: two"), "Frames: two", "not an integer"),
    "frames_negative": (sub("Frames: 2", "Frames: -5"), "Frames: -5", "negative"),
    "frames_absurd": (sub("Frames: 2", "Frames: 1000000000000"), "Frames: 1000000000000", "absurd"),
    "frames_more_than_rows": (sub("Frames: 2", "Frames: 5"), "Frames: 5", "2 complete motion rows"),
    "frames_fewer_than_rows": (sub("Frames: 2", "Frames: 1"), "Frames: 1", "2 complete motion rows"),
    "missing_frame_time": (sub("Frame Time: 0.033333\n", ""), "0 90 0 0", "expected 'Frame Time:'"),
    "frame_time_zero": (sub("Frame Time: 0.033333", "Frame Time: 0"), "Frame Time: 0", "positive"),
    "frame_time_negative": (sub("Frame Time: 0.033333", "Frame Time: -0.01"), "Frame Time: -0.01", "positive"),
    "frame_time_text": (sub("Frame Time: 0.033333", "Frame Time: fast"), "Frame Time: fast", "not a number"),
    "frame_time_nan": (sub("Frame Time: 0.033333", "Frame Time: nan"), "Frame Time: nan", "positive"),
    "motion_header_garbage": (sub("Frames: 2", "Frames: 2\nhello world"), "hello world", "expected 'Frame Time:'"),
    "row_truncated": (VALID.rstrip("\n")[:-6] + "\n", "1 90 0 10", "truncated motion row has 6 values"),
    "row_too_many_values": (sub("1 90 0 10 0 0 5 0 0", "1 90 0 10 0 0 5 0 0 7"), "1 90 0 10", "has 10 values"),
    "row_too_few_middle": (sub("0 90 0 0 0 0 0 0 0", "0 90 0 0 0 0 0 0"), "0 90 0 0", "has 8 values"),
    "row_not_number": (sub("1 90 0 10", "1 90 abc 10"), "abc", "'abc' is not a number"),
    "row_comma_decimal": (sub("1 90 0 10", "1 90,5 0 10"), "90,5", "'90,5' is not a number"),
    "row_nan": (sub("1 90 0 10", "1 nan 0 10"), "1 nan", "non-finite"),
    "row_inf": (sub("0 90 0 0 0", "0 90 0 -inf 0"), "0 90 0 -inf", "non-finite"),
    "giant_swing_paper": (GIANT_SWING_PAPER, "OFFSET 0 0 10.0 0.0", "OFFSET has 4 values, expected 3"),
    "deep_nesting_unclosed": (deep_unclosed(1_000), "MOTION", "3 '}' missing"),
    # issue 16 item 2: numbers beyond float32 (USD's samples) or absurd (MAX_ABS_VALUE = 1e15)
    "row_beyond_float32": (sub("1 90 0 10", "1e39 90 0 10"), "1e39 90", "value beyond ±1e+15"),
    "row_1e308": (sub("1 90 0 10", "1 1e308 0 10"), "1 1e308", "value beyond ±1e+15"),
    "offset_beyond_float32": (sub("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 1e39 0\n    CHANNELS"),
                              "OFFSET 0 1e39", "beyond ±1e+15"),
    # item 8: a frame time of 1e300 s is a typo, not a recording (MIN_FPS .. MAX_FPS)
    "frame_time_huge": (sub("Frame Time: 0.033333", "Frame Time: 1e300"), "Frame Time: 1e300", "one an hour"),
    "frame_time_tiny": (sub("Frame Time: 0.033333", "Frame Time: 1e-300"), "Frame Time: 1e-300",
                        "one frame a microsecond"),
    # MAX_JOINT_DEPTH = 1,000: joint j1001 is one level too deep (issue 16 item 1).
    "chain_too_deep": (deep_unclosed(1_005), "JOINT j1001\n", "1001 levels deep; at most 1000"),
}


def expected_line(content: str | bytes, marker: str | None) -> int:
    if marker is None:
        return 1
    text = content.decode("latin-1") if isinstance(content, bytes) else content
    if marker == LAST_LINE:
        return text.rstrip().count("\n") + 1
    return text[: text.index(marker)].count("\n") + 1


def main() -> None:
    manifest = {}
    for name, (content, marker, fragment) in CASES.items():
        path = HERE / f"{name}.bvh"
        data = content if isinstance(content, bytes) else content.encode("utf-8")
        path.write_bytes(data)
        manifest[name] = {"file": path.name, "line": expected_line(content, marker), "message": fragment}
    (HERE / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    print(f"wrote {len(manifest)} malformed BVH files to {HERE}")


if __name__ == "__main__":
    main()

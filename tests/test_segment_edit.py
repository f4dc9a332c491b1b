"""A person's cuts in the segments document (the Studio's editor, ``segment-eval --cuts``):
``edited``, per-segment labels checked by the schema, and the edits from detected to labelled cuts."""

from __future__ import annotations

import json

import numpy as np
import pytest

from studio_support import WALK
from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.ops.segment.detect import segment
from usdmotion.ops.segment.evaluate import Labels, edits_to_labels
from usdmotion.ops.segment.files import edited, segments_document, write_segments_json
from usdmotion.schemas import load_document, validate


@pytest.fixture(scope="module")
def walk_seg():
    return segment(read_motion(WALK, units="asf"))


def test_edited_cuts_make_a_valid_document_with_labels(walk_seg, tmp_path):
    seg = edited(walk_seg, [100, 300])
    assert seg.bounds().tolist() == [[0, 99], [100, 299], [300, 523]] and seg.edited and seg.confidence is None
    path = write_segments_json(seg, tmp_path / "walk.segments.json", "walk.bvh", labels=["  walk\tstart ", "", "turn"])
    doc = load_document(path, "segments")  # the schema accepts labels and "edited"
    assert [s.get("label") for s in doc["segments"]] == ["walk start", None, "turn"]
    assert doc["edited"] is True and "cut_details" not in doc and doc["method"] == walk_seg.method
    assert segment(read_motion(WALK, units="asf")).to_dict().get("edited") is None  # the CLI's output is unchanged
    with pytest.raises(Exception, match="/segments/0/label"):
        validate({**doc, "segments": [{**doc["segments"][0], "label": ""}, *doc["segments"][1:]]}, "segments", "x")


@pytest.mark.parametrize("cuts, message", [([0, 100], "within 1..523"), ([100, 524], "within 1..523"),
                                           ([200, 100], "increasing"), ([100, 100], "increasing"),
                                           ([1.5], "whole frame"), ([True], "whole frame"),
                                           # a Studio fuzz find: an OverflowError (a 500) converting to int64
                                           ([100, 2**63], "within 1..523"), ([-(2**70)], "within 1..523")])
def test_bad_cuts_are_refused(walk_seg, cuts, message):
    with pytest.raises(ValueError, match=message):
        edited(walk_seg, cuts)


def test_labels_must_be_one_line_of_text_per_segment(walk_seg):
    seg = edited(walk_seg, [100])
    with pytest.raises(ValueError, match="one label"):
        segments_document(seg, labels=["a"])
    with pytest.raises(ValueError, match="longer than 200"):
        segments_document(seg, labels=["a", "x" * 201])


def test_edits_to_labels_pairs_nearest_first():
    labels = Labels(cuts=np.array([110, 200, 700]), bands=np.array([[110, 110], [200, 200], [690, 720]]))
    plan = edits_to_labels([905, 100, 205, 500], labels, tolerance_frames=60)
    assert plan.moved == ((100, 110), (205, 200), (500, 700)) and plan.deleted == (905,) and plan.added == ()
    assert plan.needed == 1 and plan.kept == 0  # 500 was no hit (outside 640..760); 100 and 205 were
    plan = edits_to_labels([200], labels, tolerance_frames=60)
    assert plan.kept == 1 and plan.moved == () and plan.added == (110, 700)


def test_segment_eval_scores_a_saved_file(walk_seg, tmp_path, capsys):
    labels = tmp_path / "walk_segments.csv"
    labels.write_text("segment,label,start_frame\n1,a,1\n2,b,201\n3,c,401\n")  # cuts 200 and 400 (0-based)
    saved = write_segments_json(edited(walk_seg, [190, 400, 480]), tmp_path / "mine.segments.json")
    assert main(["segment-eval", str(WALK), str(labels), "--units", "asf", "--cuts", str(saved), "--json"]) == 0
    score = json.loads(capsys.readouterr().out)["methods"]["mine.segments.json"]
    assert (score["true_positives"], score["detected"], score["labelled"]) == (2, 3, 2)
    other = json.loads(saved.read_text())
    other["frames"] = 600
    (tmp_path / "other.json").write_text(json.dumps(other))
    assert main(["segment-eval", str(WALK), str(labels), "--units", "asf", "--cuts", str(tmp_path / "other.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == (f"usdmotion: error: {tmp_path / 'other.json'}: segments of a 600-frame take, the motion has "
                   "524 frames")

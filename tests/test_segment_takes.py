"""Issue 18: the shipped detector on the four labelled CMU takes stays within the figures reported
in docs/segment.md (one test per take, the same settings for all), its confidence and change
regions on signals whose change is known, and the segments JSON / table carrying them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from usdmotion.cli import main
from usdmotion.io import read_motion
from usdmotion.ops.segment import detect as S
from usdmotion.ops.segment.evaluate import load_labels, score_cuts

REPO = Path(__file__).resolve().parents[1]
SKELETON = "cmu86/86.asf"
#: take: (motion, labels, hits, cuts) as reported in docs/segment.md for the shipped defaults
#: (in-sample: the defaults were chosen on these four takes; the out-of-sample figures are the
#: leave-one-take-out table of benchmarks/segment.py).
REPORTED = {
    "86_01": ("cmu86/86_01.amc", "cmu86/groundtruth86.json", 6, 6),
    "14_14": ("cmu14/max_14_14_exercise_routine.bvh", "cmu14/14_14_segments.csv", 5, 5),
    "13_29": ("mocap6/13_29.amc", "mocap6/13_29_segments.csv", 5, 5),
    "13_30": ("mocap6/13_30.amc", "mocap6/13_30_segments.csv", 4, 4),
}


@pytest.mark.parametrize("take", sorted(REPORTED))
def test_labelled_take_within_reported_figures(take, shared_file):
    motion_file, label_file, hits, cuts = REPORTED[take]
    path = shared_file(motion_file)
    motion = read_motion(path, skeleton=shared_file(SKELETON) if path.suffix == ".amc" else None)
    labels = load_labels(shared_file(label_file))
    seg = S.segment(motion)
    score = score_cuts(seg.cuts, labels, int(round(0.5 * motion.fps)))
    assert score.detected == cuts and score.true_positives >= hits, (seg.cuts.tolist(), labels.cuts.tolist())
    # Every cut stays in its own change region, and every region lies between its neighbours.
    assert np.all((seg.regions[:, 0] <= seg.cuts) & (seg.cuts <= seg.regions[:, 1]))
    assert np.all(seg.regions[1:, 0] > seg.cuts[:-1]) and np.all(seg.regions[:-1, 1] < seg.cuts[1:])
    assert np.all((0 <= seg.confidence) & (seg.confidence <= 1))


def test_amc_and_derived_bvh_segment_alike(shared_file):
    """86_01 read from the AMC and from the shared BVH derived from it give the same cuts."""
    amc = S.segment(read_motion(shared_file("cmu86/86_01.amc"), skeleton=shared_file(SKELETON)))
    bvh = S.segment(read_motion(shared_file("cmu86/86_01_from_amc_cgspeed_layout.bvh")))
    assert amc.cuts.tolist() == bvh.cuts.tolist()
    np.testing.assert_allclose(amc.confidence, bvh.confidence, atol=1e-3)


def _two_regimes(rng, n=600, fps=10.0):
    """Pooled-rate features: regime A, then regime B from sample ``n``; and a stationary copy."""
    t = np.arange(2 * n) / fps
    x = 0.05 * rng.normal(size=(2 * n, 6))
    x[:, 0] += np.sin(2 * np.pi * 0.7 * t)
    x[n:, 1:3] += 1.0
    return x


def test_confidence_and_region_of_a_known_change():
    rng = np.random.default_rng(5)
    x = _two_regimes(rng)
    gamma = S.median_gamma(x)
    penalty = S.penalty_for_length(x.shape[0])
    cuts = S.kernel_change_points(x, penalty, 10, gamma)
    assert cuts.tolist() == [600]
    conf, regions = S.cut_confidence(x, cuts, penalty, 10, gamma)
    assert conf[0] > 0.9 and regions[0, 0] <= 600 <= regions[0, 1] and regions[0, 1] - regions[0, 0] <= 4
    # A cut forced into the stationary half gains little: low confidence, and a wide region.
    conf2, regions2 = S.cut_confidence(x, np.array([300, 600]), penalty, 10, gamma)
    assert conf2[0] < S.LOW_CONFIDENCE < conf2[1]
    assert regions2[0, 1] - regions2[0, 0] > 10 * (regions2[1, 1] - regions2[1, 0] + 1)
    # Brute force: the gain is the cost drop of splitting [0, 600 + …) at the cut, the cost the
    # Gaussian-kernel scatter of each segment.
    def cost(seg):
        d2 = ((seg[:, None] - seg[None]) ** 2).sum(-1)
        return len(seg) - np.exp(-gamma * d2).sum() / len(seg)
    gain = cost(x[0:1200]) - cost(x[0:600]) - cost(x[600:1200])
    assert conf[0] == pytest.approx(max(0.0, 1 - penalty / gain), abs=1e-9)


def test_refinement_never_leaves_the_change_region():
    energy = np.ones(400)
    energy[100] = 0.0                                      # a deep rest 30 frames before the cut
    assert S.refine_to_rest(energy * np.abs(np.arange(400) - 100), np.array([130]), 10.0, 10.0).tolist() == [100]
    ramp = np.abs(np.arange(400) - 100).astype(float)
    assert S.refine_to_rest(ramp, np.array([130]), 10.0, 10.0, regions=np.array([[120, 140]])).tolist() == [120]


def test_merge_transitions():
    cuts, spans = S.merge_transitions(np.array([50, 60, 200, 300, 305, 500]), 800, 12)
    assert cuts.tolist() == [55, 200, 302, 500]
    assert spans.tolist() == [[50, 60], [200, 200], [300, 305], [500, 500]]
    assert S.merge_transitions(np.array([50, 60]), 800, 0)[0].tolist() == [50, 60]


def test_cli_table_and_json_carry_confidence(shared_file, tmp_path, capsys):
    import jsonschema

    main(["segment", "--help"])
    if "--skeleton" not in capsys.readouterr().out:
        pytest.skip("the CLI --skeleton option is not on this branch yet")
    out = tmp_path / "seg.json"
    code = main(["segment", str(shared_file("mocap6/13_30.amc")), "--skeleton", str(shared_file(SKELETON)),
                 "--out", str(out)])
    stdout = capsys.readouterr().out
    assert code == 0
    doc = json.loads(out.read_text())
    jsonschema.validate(doc, json.loads((REPO / "schemas" / "segments.schema.json").read_text()))
    assert [d["frame"] for d in doc["cut_details"]] == doc["cuts"]
    assert "cut confidence" in stdout
    assert all(d["low_confidence"] == (d["confidence"] < S.LOW_CONFIDENCE) for d in doc["cut_details"])


def test_cli_confidence_column_on_a_bvh(shared_file, tmp_path, capsys):
    import jsonschema

    out = tmp_path / "seg.json"
    code = main(["segment", str(shared_file("cmu86/86_01_from_amc_cgspeed_layout.bvh")), "--out", str(out)])
    stdout = capsys.readouterr().out
    assert code == 0
    doc = json.loads(out.read_text())
    jsonschema.validate(doc, json.loads((REPO / "schemas" / "segments.schema.json").read_text()))
    assert "cut confidence" in stdout and len(doc["cut_details"]) == len(doc["cuts"]) == 6
    for detail in doc["cut_details"]:
        assert detail["region"][0] <= detail["frame"] <= detail["region"][1]
        assert f"{detail['confidence']:.2f}" in stdout

"""The detector variants of ``benchmarks/segment_experiments.py`` (not shipped; the reported
negative results rest on them): vectorised PPCA against a per-window computation, the full-rate
refinement against a known junction, and the snapping / pause rules by hand."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def X():
    spec = importlib.util.spec_from_file_location("segment_experiments", REPO / "benchmarks" / "segment_experiments.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


def direct_ppca_distance(x, start, k, window, keep):
    """Barbič's H(K) written out for one K: PPCA covariance from an eigendecomposition of the
    biased covariance of x[start:K], then the mean Mahalanobis distance of x[K:K+window]."""
    past = x[start:k]
    mu = past.mean(axis=0)
    lam, vec = np.linalg.eigh(np.cov(past, rowvar=False, bias=True))
    lam, vec = lam[::-1], vec[:, ::-1]
    d = x.shape[1]
    r = min(int(np.argmax(np.cumsum(lam) / lam.sum() >= keep)) + 1, d - 1)
    sigma2 = lam[r:].mean()
    cov = vec[:, :r] @ np.diag(lam[:r]) @ vec[:, :r].T + sigma2 * (np.eye(d) - vec[:, :r] @ vec[:, :r].T)
    diff = x[k:k + window] - mu
    return float(np.mean(np.sum(diff * np.linalg.solve(cov, diff.T).T, axis=1)))


def test_ppca_distance_matches_a_direct_computation(X):
    rng = np.random.default_rng(3)
    mix = rng.normal(size=(8, 8))
    x = np.concatenate([rng.normal(size=(300, 8)) @ mix * 0.1 + 2.0,
                        rng.normal(size=(300, 8)) @ mix.T * 0.1 + 2.5])
    ks, h = X.ppca_distance(x, 40, 60, 7, 0.95)
    assert ks[0] == 100 and np.all(np.diff(ks) == 7) and ks[-1] + 60 <= x.shape[0]
    expected = [direct_ppca_distance(x, 40, int(k), 60, 0.95) for k in ks]
    np.testing.assert_allclose(h, expected, rtol=1e-6)
    # The distance is highest when the next window lies wholly in the new regime.
    assert abs(ks[np.argmax(h)] - 300) <= 7


def fake_take(X, angles, fps=30.0, activity=None):
    from usdmotion.ops.segment.evaluate import Labels

    motion = type("M", (), {"fps": fps})()
    speed = np.abs(np.gradient(angles, axis=0)) * fps
    activity = speed.mean(axis=1) if activity is None else activity
    return X.Take("fake", motion, Labels(np.zeros(0, int), np.zeros((0, 2), int)), "test", angles, speed,
                  np.zeros((angles.shape[0], 10)), activity)


def test_ppca_cuts_a_two_regime_signal_at_the_change(X):
    rng = np.random.default_rng(4)
    fps, n = 120.0, 1200
    t = np.arange(2 * n) / fps
    angles = np.full((2 * n, 8), 2.5) + 0.02 * rng.normal(size=(2 * n, 8))
    angles[:, :2] += 0.3 * np.sin(2 * np.pi * t)[:, None]          # a cyclic action ...
    angles[n:, 4:6] -= 0.8                                           # ... then a new pose
    cuts = X.ppca(fake_take(X, angles, fps), threshold=15.0)
    assert cuts.size >= 1 and abs(cuts[0] - n) <= 0.5 * fps


def test_refinement_moves_a_late_cut_back_to_the_junction(X, shared_file):
    from usdmotion.io import read_motion
    from usdmotion.ops.segment.evaluate import synthetic_take

    walk = read_motion(shared_file("bandai1/dataset-1_walk_normal_001.bvh"))
    punch = read_motion(shared_file("bandai1/dataset-1_punch_normal_001.bvh"))
    take, labels = synthetic_take([walk, punch], blend_s=0.5)
    t = X.make_take("walk-punch", take, labels, "test")
    true = int(labels.cuts[0])
    late = np.array([true + int(0.6 * take.fps)])
    refined = X.refine(t, late, context_s=2.0)
    assert abs(int(refined[0]) - true) <= 0.1 * take.fps, (refined, true)
    # A cut already on the junction stays there.
    assert abs(int(X.refine(t, np.array([true]), context_s=2.0)[0]) - true) <= 0.1 * take.fps


def test_snap_and_pause_rules_by_hand(X):
    np.testing.assert_array_equal(X.snap(np.array([100, 300, 520]), np.array([90, 500]), 20), [90, 300, 500])
    np.testing.assert_array_equal(X.snap(np.array([100, 120]), np.array([110]), 20), [110])  # two cuts, one candidate
    activity = np.full(600, 1.0)
    activity[200:290] = 0.1                                 # a 3 s pause at 30 fps, middle 244
    t = fake_take(X, np.zeros((600, 8)), 30.0, activity)
    np.testing.assert_array_equal(X.pause_centre(t, np.array([295, 450]), 0.3), [244, 450])
    np.testing.assert_array_equal(X.pause_centre(t, np.array([310]), 0.3), [310])  # 0.7 s away: out of reach

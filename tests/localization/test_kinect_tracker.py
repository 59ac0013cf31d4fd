"""The multi-Kinect leader tracker (Min et al. Alg. 1's "whenever the sensor detects a leader"):
fusion of one robot's estimates from overlapping Kinects, identities kept by gated assignment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.localization.kinect.pipeline import PoseEstimate
from parcover_env.localization.kinect.tracker import KinectTracker


def est(x, y, th=0.0, n=4, k="A") -> PoseEstimate:
    return PoseEstimate(x, y, th, n, kinect=k)


def test_tracker_fuses_kinects_and_keeps_identities():
    tr = KinectTracker(gate=0.3)
    pred = {7: (1.0, 1.0, 0.0), 9: (2.0, 1.0, 0.0)}
    out = tr.update([[est(2.02, 1.0, 0.1), est(1.01, 1.0)], [est(2.0, 1.02, -0.1, k="B")]], pred, stamp=1.0)
    assert set(out) == {7, 9}
    np.testing.assert_allclose(out[9], [2.01, 1.01, 0.0], atol=1e-6)  # fused, equal weights
    assert tr.age(7, 1.5) == pytest.approx(0.5) and tr.age(3, 1.5) == np.inf
    out = tr.update([[est(5.0, 5.0)]], pred)  # far from every prediction: gated out
    assert out == {} and len(tr.unassigned) == 1
    free = KinectTracker()
    ids = free.update([[est(1.0, 1.0), est(3.0, 1.0)]])
    for step in range(1, 5):  # robots move 5 cm per frame; ids follow them
        nxt = free.update([[est(3.0 + 0.05 * step, 1.0), est(1.0 + 0.05 * step, 1.0)]])
        assert set(nxt) == set(ids)
        for k in ids:
            assert abs(nxt[k][0] - ids[k][0] - 0.05 * step) < 1e-9
    with pytest.raises(ValueError):
        KinectTracker(gate=0)


def test_tracker_single_estimate_is_the_weighted_formula_bit_for_bit():
    """One estimate (one leader seen by one Kinect): the fused pose is the marker-weighted mean and
    circular mean of the general formula, bit for bit; with one prediction it is matched inside
    the gate only."""
    rng = np.random.default_rng(6)
    for x, y, th, n in zip(rng.uniform(-9, 9, 50), rng.uniform(-9, 9, 50), rng.uniform(-4, 4, 50),
                           rng.integers(1, 9, 50), strict=True):
        w, xy = np.array([float(n)]), np.array([[x, y]])
        want = np.array([*(w @ xy / w.sum()), math.atan2(float(w @ np.sin([th])), float(w @ np.cos([th])))])
        got = KinectTracker().fuse([est(float(x), float(y), float(th), int(n))])
        assert len(got) == 1 and got[0].tobytes() == want.tobytes()
    tr = KinectTracker(gate=0.25)
    out = tr.update([[est(1.0, 1.25, 0.5)]], {4: (1.0, 1.0, 0.0)})  # exactly at the gate: matched
    assert list(out) == [4] and out[4].tolist() == [1.0, 1.25, 0.5] and tr.unassigned == []
    assert tr.update([[est(1.0, 1.2500001)]], {4: (1.0, 1.0, 0.0)}) == {} and len(tr.unassigned) == 1
    assert KinectTracker().update([[est(1.0, 1.0)]], {}) == {}


def test_tracker_clusters_from_the_estimate_with_most_markers():
    """Fusion anchors each cluster on the estimate with the most markers: within ``fuse_radius`` of
    the anchor (distance equal to the radius included) joins it, the others start a cluster."""
    tr = KinectTracker(fuse_radius=0.125)
    chain = [est(0.0, 0.0, n=4), est(0.1, 0.0, n=2), est(0.2, 0.0, n=2)]  # the third is 0.2 from the anchor
    fused = tr.fuse(chain[::-1])
    assert len(fused) == 2 and fused[1].tolist() == [0.2, 0.0, 0.0]
    assert fused[0][0] == pytest.approx((4 * 0.0 + 2 * 0.1) / 6)  # marker-weighted
    assert len(tr.fuse([est(0.0, 0.0), est(0.125, 0.0)])) == 1  # exactly at the radius: one robot
    with pytest.raises(ValueError, match="gate and fuse_radius must be > 0, got 0.3, 0"):
        KinectTracker(gate=0.3, fuse_radius=0)


def test_tracker_without_predictions_numbers_new_tracks_from_zero():
    """No predictions: unmatched estimates open tracks 0, 1, ... (skipping ids in use); tracks are
    then followed by their last poses; ``unassigned`` is emptied; the stamp defaults to 0."""
    tr = KinectTracker(gate=0.3)
    assert tr.unassigned == [] and tr.poses == {}
    first = tr.update([[est(1.0, 1.0), est(3.0, 1.0)]])
    assert sorted(first) == [0, 1] and tr.unassigned == [] and tr.age(0, 0.5) == 0.5
    again = tr.update([[est(1.1, 1.0), est(3.1, 1.0), est(6.0, 6.0)]], stamp=2.0)
    assert again[0].tolist()[:2] == [1.1, 1.0] and again[1].tolist()[:2] == [3.1, 1.0] and sorted(again) == [0, 1, 2]
    tr.poses[3] = np.array([9.0, 9.0, 0.0])  # an id in use is skipped
    assert sorted(tr.update([[est(0.0, 5.0)]], stamp=3.0)) == [4]


def test_tracker_assignment_gate_is_inclusive_with_several_robots():
    """Several estimates and predictions: minimum-cost matching, each within the gate (equal to the
    gate included); an estimate beyond it is left unassigned."""
    tr = KinectTracker(gate=0.25)
    pred = {7: (1.0, 1.0, 0.0), 9: (2.0, 1.0, 0.0)}
    out = tr.update([[est(1.0, 1.25), est(2.0, 1.2500001)]], pred)
    assert list(out) == [7] and out[7].tolist()[:2] == [1.0, 1.25] and len(tr.unassigned) == 1

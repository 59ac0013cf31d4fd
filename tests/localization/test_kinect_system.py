"""KinectSystem: the hand-over of promoted followers (formation poses) and identity tracking."""

from __future__ import annotations

import math

import numpy as np
import pytest

import parcover_env
from parcover_env.geometry.poses import compose
from parcover_env.localization.kinect.system import KinectSystem, handover_poses


def test_handover_poses_chain_down_the_column():
    n = 4
    promoted = np.array([False, True, True, True])
    predecessor = np.array([-1, 0, 1, 2])
    rel_xy = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.1], [0.4, 0.0]])
    rel_heading = np.array([0.0, 0.0, 0.2, 0.0])
    visible = np.array([False, True, True, False])
    reference = np.array([[5.6, 9.2, math.pi / 2], [9.0, 9.0, 0.0], [9.0, 9.0, 0.0], [9.0, 9.0, 0.0]])
    out = handover_poses(promoted, predecessor, rel_xy, rel_heading, visible, reference)
    assert sorted(out) == [1, 2]  # robot 3 did not see robot 2: no hand-over pose
    # robot 1 sees robot 0 straight ahead at 0.5 m, same heading: 0.5 m behind it (south, heading north)
    assert np.allclose(out[1], [5.6, 8.7, math.pi / 2])
    # robot 2 is placed from robot 1's hand-over pose (not from reference[1]): its measurement of
    # robot 1 maps its pose back onto robot 1's
    assert np.allclose(compose(out[2], [0.5, 0.1, 0.2]), out[1])
    assert out[2][2] == pytest.approx(math.pi / 2 - 0.2)
    c, s = math.cos(0.2), math.sin(0.2)  # robot 1 heads north: robot 2's frame is turned by -0.2 rad
    assert np.allclose(out[2][:2], [5.6 - 0.5 * s + 0.1 * c, 8.7 - 0.5 * c - 0.1 * s])
    # robot 1 did not see robot 0: robot 2 is placed from the pose the system holds for robot 1
    visible[1] = False
    out = handover_poses(promoted, predecessor, rel_xy, rel_heading, visible, reference)
    assert sorted(out) == [2]
    assert np.allclose(compose(out[2], [0.5, 0.1, 0.2]), reference[1])
    # not promoted, or no robot ahead: nothing
    assert handover_poses(np.zeros(n, bool), predecessor, rel_xy, rel_heading, visible, reference) == {}
    assert handover_poses(promoted, np.full(n, -1), rel_xy, rel_heading, visible, reference) == {}


def _tree_system():
    env = parcover_env.parallel_env("tree", preset="ideal")
    system = KinectSystem(env.scenario, env.map)
    system.reset()
    return system, env.n_robots


def _column(n):
    """``tree`` seed 46 at t = 32.2 s: robots 5, 6, 7 in a column heading north; 6 and 7
    were just promoted, and their odometry estimates sit side by side between their true positions."""
    true = np.tile([1.0, 1.0, 0.0], (n, 1))
    true[5] = [5.59, 9.21, math.pi / 2]
    true[6] = [5.60, 8.66, math.pi / 2]
    true[7] = [5.60, 8.09, math.pi / 2]
    predicted = true.copy()
    predicted[6, :2] = [5.68, 8.38]
    predicted[7, :2] = [5.46, 8.39]
    markers = np.zeros(n, bool)
    markers[[5, 6, 7]] = True
    return true, predicted, markers


def test_promoted_robots_matched_by_their_drifted_estimates_swap():
    system, n = _tree_system()
    true, predicted, markers = _column(n)
    fixes = system.update(0.0, true, markers, predicted, np.random.default_rng(0))
    assert np.hypot(*(fixes[6][:2] - true[7, :2])) < 0.05  # robot 6 is given robot 7's pose
    assert np.hypot(*(fixes[7][:2] - true[6, :2])) < 0.05


def test_handover_keeps_identities_and_ends_at_the_first_detection():
    system, n = _tree_system()
    true, predicted, markers = _column(n)
    # the formation places them: robot 6 saw robot 5 0.55 m ahead, robot 7 saw robot 6 0.57 m ahead
    poses = {6: np.array([5.59, 8.66, math.pi / 2]), 7: np.array([5.59, 8.09, math.pi / 2])}
    system.hand_over(poses, predicted)
    assert sorted(system.handover) == [6, 7]
    # the correction moves on with the estimate: 1 cm of odometry later the reference is 1 cm on
    ref = compose(system.handover[6], predicted[6] + [0.0, 0.01, 0.0])
    assert np.allclose(ref, [5.59, 8.67, math.pi / 2])
    fixes = system.update(0.0, true, markers, predicted, np.random.default_rng(0))
    for i in (5, 6, 7):
        assert np.hypot(*(fixes[i][:2] - true[i, :2])) < 0.05
    assert system.handover == {}  # detected: matched by their (now fixed) estimates from here on


def test_handover_of_an_undetected_robot_lasts_until_its_markers_go():
    system, n = _tree_system()
    true, predicted, markers = _column(n)
    system.hand_over({6: true[6]}, predicted)
    far = true.copy()
    far[6] = [50.0, 50.0, 0.0]  # out of every view: not detected, the hand-over stays
    system.update(0.0, far, markers, predicted, np.random.default_rng(0))
    assert 6 in system.handover
    markers[6] = False
    system.update(1.0, far, markers, predicted, np.random.default_rng(0))
    assert 6 not in system.handover

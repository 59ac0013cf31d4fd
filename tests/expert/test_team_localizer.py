"""Team localization: which readings a teammate may explain (pure geometry, hand-built scans)."""

from __future__ import annotations

import numpy as np

from parcover_env.expert.team_localizer import teammate_mask


def test_only_short_readings_ending_near_a_teammate_are_masked():
    pose = np.array([0.0, 0.0, np.pi / 2])  # facing +y
    angles = np.radians([0.0, 90.0, 180.0, 270.0])  # robot frame: ahead (+y), left (-x), behind, right (+x)
    expected = np.full(4, 2.0)  # the known map: a wall 2 m away all round
    ranges = np.array([0.5, 2.0, 0.5, 0.5])  # three short readings, one wall reading
    others = np.array([[0.0, 0.8]])  # a teammate believed 0.8 m ahead
    # reach 0.4 m: the reading ahead ends at (0, 0.5), 0.3 m from the teammate -> masked; the one
    # behind ends at (0, -0.5), 1.3 m away -> kept; the one to the right at (0.5, 0) -> 0.94 m, kept
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([0.4]))
    assert m.tolist() == [True, False, False, False]
    # a reading as long as the map's is never blamed on a teammate, however uncertain it is
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([5.0]))
    assert m.tolist() == [True, False, True, True]
    # a smaller reach leaves the reading ahead in the comparison
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([0.25]))
    assert not m.any()

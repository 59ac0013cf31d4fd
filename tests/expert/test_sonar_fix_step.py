"""The expert's scan logic (:meth:`SonarFixer.step`) on hand-built situations: when a scan is due
(its distances, the staleness and stop thresholds at their edges), the retries after a refused fix,
the counts of scans, and a whole scan of the robot's own, turning in place until it is localized."""

from __future__ import annotations

import numpy as np
from sonar_fix_helpers import ODOM, make_fixer, ranges_at, step

from parcover_env.expert.sonar_fix import SCAN_REQUEST, _State
from parcover_env.geometry.poses import compose
from parcover_env.localization.sonar.service import HELD, REJECTED


def _state(**kw) -> _State:
    return _State(np.zeros(3), np.eye(3) * 1e-3, last_odom=ODOM.copy(), **kw)


def test_a_scan_is_due_after_rescan_distance_or_final_rescan_distance_at_the_route_end():
    fixer = make_fixer(rescan_distance=2.0, final_rescan_distance=0.2)
    fixer.states["robot_0"] = st = _state(driven_since_scan=0.3)
    assert step(fixer) is None  # 0.3 m on: not yet
    assert step(fixer, at_end=True) == (0.0, fixer.scan_rate)  # at its route's end 0.2 m is enough
    fixer.states["robot_0"] = st = _state(driven_since_scan=2.0)  # exactly rescan_distance: due
    assert step(fixer) == (0.0, fixer.scan_rate)
    assert st.scan is not None


def test_a_scan_needs_a_fix_older_than_stale_after_and_a_speed_up_to_stop_speed():
    fixer = make_fixer(stale_after=8.0, stop_speed=0.005)
    fixer.states["robot_0"] = _state()
    assert step(fixer, fix_age=8.0) is None  # exactly stale_after: not stale yet
    assert step(fixer, fix_age=8.05, speed=0.005) == (0.0, fixer.scan_rate)  # stop_speed counts as standing


def test_scans_in_a_row_after_a_refused_fix_count_up_to_refused_rescans():
    fixer = make_fixer(refused_rescans=2, rescan_distance=2.0)
    fixer.states["robot_0"] = st = _state(driven_since_scan=0.0, refused=np.array([0.5, 0.0, 0.0]))
    assert step(fixer) == (0.0, fixer.scan_rate) and st.retries == 1
    st.scan, st.driven_since_scan = None, 0.0  # that scan refused its fix again
    assert step(fixer) == (0.0, fixer.scan_rate) and st.retries == 2
    st.scan, st.driven_since_scan = None, 0.0
    assert step(fixer) is None and st.retries == 2  # no third one in a row
    assert fixer.stats["sonar_scans"] == 2


def test_the_env_service_counts_each_scan_and_each_miss():
    fixer = make_fixer(env_scan=True, refused_rescans=5)
    fixer.states["robot_0"] = st = _state()
    for k in (1, 2):
        assert step(fixer, check=True) == SCAN_REQUEST
        assert step(fixer, scanning=False, result=REJECTED) is None
        assert fixer.stats == {"sonar_scans": k, "sonar_localized": 0, "sonar_failed": k}
    assert st.missed and st.retries == 1  # the second scan was the first retry after a miss


def test_a_relocating_robot_scans_once_it_has_driven_the_chosen_distance_without_a_retry():
    fixer = make_fixer(env_scan=True, relocate_distance=0.5, refused_rescans=2)
    fixer.states["robot_0"] = st = _state()
    assert step(fixer, check=True) == SCAN_REQUEST
    assert step(fixer, scanning=False, result=HELD) is None
    assert st.relocate and st.driven_since_scan == 0.0
    st.retries = 1
    fixer.scan_after("robot_0", 0.3)
    assert step(fixer, speed=2.0) is None  # 0.2 m
    assert step(fixer, speed=1.0) == (0.0, 0.0)  # 0.3 m: due, still rolling
    assert step(fixer) == SCAN_REQUEST and st.retries == 0  # not a retry: the count starts over


def _own_scan(fixer, true, odom_offset, mates=None, others=None) -> tuple[_State, np.ndarray, int]:
    """A stale leader at ``true`` whose odometry is ``true + odom_offset`` turns in place at its scan
    rate until its own scan is complete; the ring reads the tree map (and teammates at ``mates``).
    Returns its state, its odometry pose at the end and the number of steps."""
    odom = true + odom_offset
    fixer.states["robot_0"] = st = _State(np.zeros(3), np.diag([0.01, 0.01, 0.001]), last_odom=odom.copy())
    steps = 0
    while True:
        pose = np.array([true[0], true[1], odom[2] - odom_offset[2]])
        out = fixer.step("robot_0", odom, 100.0, 0.0, ranges_at(fixer, pose, fixer.beams, mates), True,
                         others=others)
        steps += 1
        if out is None:
            return st, odom, steps
        assert out == (0.0, fixer.scan_rate)
        odom = odom + [0.0, 0.0, fixer.scan_rate * fixer.dt]


def test_a_whole_scan_of_its_own_turns_until_each_bin_is_read_and_localizes_the_robot():
    fixer = make_fixer()
    true = np.array([1.0, 1.0, 0.3])  # a corner of the tree map
    st, odom, steps = _own_scan(fixer, true, np.array([0.1, -0.05, 0.02]))
    # eight beams 45 degrees apart, 0.06 rad per step: after the first reading and 12 turns (41 degrees)
    # every 5-degree bin has a reading within 2 degrees of its centre
    assert steps == 13
    belief = compose(st.correction, odom)
    np.testing.assert_allclose(belief, [1.0, 1.0, odom[2] - 0.02], atol=2e-3)
    assert st.scan is None and st.driven_since_scan == 0.0 and not st.missed
    assert fixer.stats == {"sonar_scans": 1, "sonar_localized": 1, "sonar_failed": 0}
    st, odom, _ = _own_scan(fixer, true, np.array([0.1, -0.05, 0.02]))
    assert fixer.stats == {"sonar_scans": 2, "sonar_localized": 2, "sonar_failed": 0}


def test_teammates_next_to_the_robot_are_drawn_into_the_map_of_its_scan():
    mates = np.array([[1.45, 1.0], [1.0, 1.45], [1.4, 1.4]])  # three teammates around it block its ring
    true, offset = np.array([1.0, 1.0, 0.3]), np.array([0.1, -0.05, 0.02])
    fixer = make_fixer()
    st, odom, _ = _own_scan(fixer, true, offset, mates=mates, others=mates)
    np.testing.assert_allclose(compose(st.correction, odom)[:2], true[:2], atol=2e-3)
    # believed elsewhere (not next to it), they explain nothing: no fix
    fixer = make_fixer()
    st, _, _ = _own_scan(fixer, true, offset, mates=mates, others=mates + 5.0)
    assert not np.any(st.correction) and st.missed and fixer.stats["sonar_failed"] == 1

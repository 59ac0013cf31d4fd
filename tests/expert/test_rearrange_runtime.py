"""Rearrangement reacting to blocking that depends on the run (our extension, issue 42 item 3).

The paper's rearrangement (Kim, Pearce & Amato §3.2) moves pairs of PLANNED subgoals. Here a
teammate has finished its route and stands where its run left it, in the line of sight of a robot
still on its way: the robot reacts alone (the teammate will not move), and does not react in the
same situation without the standing teammate. The hand-built case with hand-computed angles is
``tests/expert/test_rearrange.py::test_rearrangement_reacts_to_a_body_standing_in_the_line_of_sight``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import parcover_env
from parcover_env.expert.navigator import SonarNavigator
from parcover_env.localization.sonar.subgoals import unblocked_scan_angle


@pytest.fixture(scope="module")
def hallway():
    env = parcover_env.parallel_env("hallway", preset="ideal")
    obs, _ = env.reset(seed=0)
    return env, obs


def _nav(hallway) -> SonarNavigator:
    env, obs = hallway
    nav = SonarNavigator.for_env(env)
    nav.reset(obs)
    return nav


def _best_angle(nav, i, xy, k, bodies) -> tuple[float, int]:
    """Widest unblocked scan angle (deg) from ``xy`` over the features available at node ``k`` of
    robot ``i``'s path, and that feature."""
    args = (nav.radius, nav.sonar_cfg.range_max, nav.incidence, nav.cone)
    feats = np.flatnonzero(nav.scores[i].available[k])
    vals = [unblocked_scan_angle(xy, nav.features[g], bodies, *args) for g in feats]
    return math.degrees(max(vals)), int(feats[int(np.argmax(vals))])


def test_robot_reacts_to_a_teammate_standing_at_the_hallways_far_end(hallway):
    """Robot 0 is done and stands at (10.12, 6.35) (its path's point at label 14.5); robot 1, still
    on its way, has its subgoal at label 14.0, (10.59, 5.83), where eq. 1 chose the corner
    (9.3, 7.62). Robot 0, 0.70 m away, hides 57 deg of that corner: 77.5 of 134.5 deg left (robot 1's
    other corner there, (11.3, 7.62), keeps 126 deg). Robot 1 moves 0.235 m on along its path to
    (10.55, 6.07), where the corner (11.3, 7.62) is wholly in view: 134.5 deg, 57 deg gained."""
    nav = _nav(hallway)
    targets = np.array([14.5, 14.0])
    ends = np.array([p.s[-1] for p in nav.paths])
    windows = np.stack([targets - 0.5, np.minimum(targets + 2.5, ends)], axis=1)
    standing = nav.paths[0].point(14.5)[None]
    assert standing[0] == pytest.approx([10.116, 6.352], abs=1e-3)
    res = nav.rearranger.rearrange(nav.paths, nav.scores, targets.copy(), windows, np.array([1]), standing=standing)
    assert res.reacted == (1,) and res.pairs == 0 and not np.isfinite(res.goals).any()
    assert res.targets[0] == 14.5  # the standing robot keeps its subgoal
    assert res.targets[1] - 14.0 == pytest.approx(0.235, abs=1e-3)  # a path node, 0.05 m apart
    old, new = nav.paths[1].point(14.0), nav.paths[1].point(res.targets[1])
    assert old == pytest.approx([10.586, 5.835], abs=1e-3) and new == pytest.approx([10.549, 6.071], abs=1e-3)
    args = (nav.radius, nav.sonar_cfg.range_max, nav.incidence, nav.cone)
    chosen = nav.features[int(nav.scores[1].feature[nav.paths[1].index(14.0)])]
    assert chosen.point == pytest.approx([9.3, 7.62])
    assert math.degrees(unblocked_scan_angle(old, chosen, np.zeros((0, 2)), *args)) == pytest.approx(134.5)
    assert math.degrees(unblocked_scan_angle(old, chosen, standing, *args)) == pytest.approx(77.5)
    angle, feature = _best_angle(nav, 1, new, nav.paths[1].index(res.targets[1]), standing)
    assert angle == pytest.approx(134.5) and nav.features[feature].point == pytest.approx([11.3, 7.62])
    # the same situation without the standing teammate: nothing fires
    res = nav.rearranger.rearrange(nav.paths, nav.scores, targets.copy(), windows, np.array([1]))
    assert res.reacted == () and np.array_equal(res.targets, targets)


def test_navigator_plan_reacts_to_a_done_teammate_off_its_plan(hallway):
    """In the navigator's plan step (Fig. 1 lines 3-6): robot 1 is done and, by its belief, stands
    half-way between robot 0's first subgoal (label 2.05, (2.84, 1.33)) and the corner (1.7, 2.4)
    eq. 1 chose there, at (2.27, 1.86), not where its plan put it: of that corner's 38.5 deg, 9 are
    left in view, and no other corner is available there. Robot 0's subgoal moves 0.554 m back
    along its path (within the 0.6 m cap) to (2.29, 1.32), where the corner (0, 2) keeps 41 deg in
    view (32 deg gained). With robot 1 done at its start (out of the way) the same plan step keeps
    the subgoal and nothing fires."""
    control = _nav(hallway)
    control.done[1] = True
    control._plan()
    assert control.targets[0] == pytest.approx(2.05) and control.stats()["sonar_reacted"] == 0
    sub = control.paths[0].point(control.targets[0])
    corner = control.features[int(control.scores[0].feature[control.paths[0].index(control.targets[0])])].point
    assert sub == pytest.approx([2.844, 1.328], abs=1e-3) and corner == pytest.approx([1.7, 2.4])
    body = sub + 0.5 * (corner - sub)
    nav = _nav(hallway)
    nav.done[1] = True
    nav.last_odom[1, :2] = body  # its belief: the odometry pose, no correction yet
    nav._plan()
    st = nav.stats()
    assert st["sonar_reacted"] == 1 and st["sonar_rearranged"] == 0
    assert control.targets[0] - nav.targets[0] == pytest.approx(0.554, abs=1e-3)
    k_old, k_new = (nav.paths[0].index(t) for t in (control.targets[0], nav.targets[0]))
    new = nav.paths[0].point(nav.targets[0])
    assert new == pytest.approx([2.291, 1.318], abs=1e-3)
    before, f_before = _best_angle(nav, 0, sub, k_old, body[None])
    after, f_after = _best_angle(nav, 0, new, k_new, body[None])
    assert (before, after) == (pytest.approx(9.0), pytest.approx(41.0))
    assert nav.features[f_before].point == pytest.approx([1.7, 2.4])
    assert nav.features[f_after].point == pytest.approx([0.0, 2.0])

"""The expert steers by its own route tracker on its belief, measures "off its route" from its progress
on (issue 42: generated:201, 289, 314; traces in ``docs/expert_benchmark.md``)."""

from __future__ import annotations

import math

import numpy as np

import parcover_env
from parcover_env.expert.scripted import route_from
from parcover_env.geometry import rotate

RELOCATE = {"observation": {"scan": {"enabled": True, "confirm_widened": True}},
            "expert": {"sonar_fix": {"relocate_distance": 0.5}}}


def _expert(seed: int):
    from parcover_env.expert import expert_for

    env = parcover_env.parallel_env(f"generated:{seed}", overrides=RELOCATE)
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    expert.reset(obs)
    return env, expert, obs


def test_route_from_cuts_the_polyline_at_an_arc_length():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 0.5), [[0.5, 0.0], [2.0, 0.0], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 2.0), [[2.0, 0.0], [2.0, 3.0]])  # at a vertex: from it
    np.testing.assert_allclose(route_from(route, 3.5), [[2.0, 1.5], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 9.0), [[2.0, 3.0], [2.0, 3.0]])  # past the end
    np.testing.assert_allclose(route_from(route, -1.0), route)


def test_off_route_is_measured_from_the_progress_on_so_a_goal_behind_a_wall_gives_way_to_a_seen_vertex():
    """generated:201, robot 5 (traced): coming back west along the corridor to its turn north at
    (3.03, 5.38) -> (3.08, 6.48), its progress jumped to the next leg (3.08, 6.48) -> (4.08, 6.78) in
    the room above; at (3.45, 5.77), 0.4 m from the leg it needs, its goal lay behind the room's wall."""
    env, expert, _ = _expert(201)
    route = env.mission.routes[5]
    np.testing.assert_allclose(route[3:6], [[3.03, 5.38], [3.08, 6.48], [4.08, 6.78]], atol=0.01)
    assert expert.cfg.off_route_distance == 0.5
    pose = np.array([3.45, 5.77, 1.08])
    expert.track.progress[5] = 5.29  # as traced, on the leg in the room
    goal = expert.track.goals()[5]
    np.testing.assert_allclose(goal, [4.06, 6.89], atol=0.02)
    rel = rotate(goal - pose[:2], -pose[2])
    out = expert._visible_goal(5, pose, rel)
    np.testing.assert_allclose(out, rotate(route[4] - pose[:2], -pose[2]), atol=1e-9)  # the turn, through the door
    # measured from the whole route (0.4 m from the leg it needs) the goal behind the wall stood
    track, expert.track = expert.track, None
    np.testing.assert_allclose(expert._visible_goal(5, pose, rel), rel)
    expert.track = track
    # progress still on the leg it needs (before the jump): its goal is in sight, unchanged
    expert.track.progress[5] = 3.49
    rel = rotate(expert.track.goals()[5] - pose[:2], -pose[2])
    np.testing.assert_allclose(expert._visible_goal(5, pose, rel), rel)


def test_the_goal_is_the_experts_own_tracker_point_also_without_a_correction():
    """generated:289 and 314 (traced): a promoted follower, its env estimate 0.6-1.3 m off while it
    followed, the env's progress stalled or on another leg; after the env's fix it steered by the
    env's goal into a wall, while its own tracker (on its chained belief) had the right one."""
    env, expert, obs = _expert(3)
    a = "robot_0"
    assert not expert.fixer.corrected(a)
    for i in range(len(obs)):  # the poses it steers by: the observed estimates (no correction)
        expert._last_odom[i] = expert._odom(obs[f"robot_{i}"])
    bel = expert.belief()
    env_goal = np.array([env.layout.get(obs[a], k)[0] for k in ("goal_dx", "goal_dy")])
    expert.track.progress[0] = 4.0  # its own progress differs from the env's (0 m, at the start)
    want = rotate(expert.track.goals()[0] - bel[0, :2], -bel[0, 2])
    got = expert._goal(obs[a], a, bel)
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert np.hypot(*(got - env_goal)) > 1.0
    # without sonar fixes (no tracker of its own) the observed goal is used
    assert np.allclose(expert._goal(obs[a], a, None), env_goal, atol=1e-6)


def test_the_pose_check_before_a_kpoi_reads_the_experts_own_goal():
    env, expert, obs = _expert(3)
    a = "robot_0"
    kpois = env.mission.kpois
    np.testing.assert_allclose(env.mission.routes[0][-1], [2.58, 0.32], atol=0.01)
    np.testing.assert_allclose(kpois[2], [2.59, 0.35], atol=0.01)
    odom = np.array([3.0, 0.6, math.pi])
    assert expert._kpoi_check(a, obs[a], odom) is None  # its progress at the start: no KPOI ahead
    expert.track.progress[0] = 9.0  # 0.39 m before its route's end, the KPOI
    assert np.hypot(*(expert.track.goals()[0] - odom[:2])) <= expert.cfg.sonar_fix.kpoi_check_distance
    assert expert._kpoi_check(a, obs[a], odom) == 2

"""The step's fast paths give the same numbers as their plain references (issue 8 optimizations)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from references import progress as reference

from parcover_env.config import SonarConfig
from parcover_env.envs import ParallelCoverageEnv
from parcover_env.geometry import rays
from parcover_env.localization.kinect.estimate_model import view_box
from parcover_env.scenarios.progress import RouteTracker as Mission
from parcover_env.sensors import sonar as sn


def _room_segments() -> np.ndarray:
    """A 6 m x 4 m room with a notch (concave corners) and a free-standing wall."""
    pts = np.array([[0, 0], [6, 0], [6, 4], [3.5, 4], [3.5, 3], [2.5, 3], [2.5, 4], [0, 4]], dtype=float)
    ring = np.concatenate([pts, np.roll(pts, -1, axis=0)], axis=1)
    return np.vstack([ring, [[1.0, 1.0, 1.0, 2.5]]])


@pytest.mark.parametrize("model", ["ray", "specular"])
def test_range_culled_sonar_matches_full_ray_casting(model, monkeypatch):
    rng = np.random.default_rng(3)
    seg = _room_segments()
    n, b, k = 6, 12, 5
    origins = np.c_[rng.uniform(0.2, 5.8, n), rng.uniform(0.2, 2.8, n)]
    axes = rng.uniform(-np.pi, np.pi, (n, b))
    ang = (axes[:, :, None] + np.linspace(-0.2, 0.2, k)).reshape(-1)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    reach = 1.5
    fan = dirs.reshape(n, b * k, 2)
    full = rays.cast_rays(origins, fan, seg, with_cos=True, cull=False)  # every segment, no range
    near = rays.cast_rays(origins, fan, seg, reach, with_cos=True, cull=True)
    flat = rays.cast_rays(np.repeat(origins, b * k, axis=0), dirs, seg, with_cos=True)  # one ray per origin
    np.testing.assert_array_equal(flat.distance, full.distance.ravel())
    t_full, i_full, c_full = full.distance.ravel(), full.index.ravel(), full.cos_incidence.ravel()
    t_near, i_near, c_near = near.distance.ravel(), near.index.ravel(), near.cos_incidence.ravel()
    close = t_full <= reach
    assert close.any() and (~close).any()  # both cases exercised
    np.testing.assert_array_equal(t_near[close], t_full[close])
    np.testing.assert_array_equal(i_near[close], i_full[close])
    np.testing.assert_array_equal(c_near[close], c_full[close])
    assert np.all(np.isinf(t_near[~close])) and np.all(i_near[~close] == -1)  # beyond reach: no hit
    owner = np.arange(n)
    d_full = rays.cast_rays_discs(np.repeat(origins, b * k, axis=0), dirs, origins, 0.2, np.repeat(owner, b * k))
    d_near = rays.cast_rays_discs(origins, fan, origins, 0.2, owner, reach, cull=True)
    np.testing.assert_array_equal(np.minimum(d_near.ravel(), reach), np.minimum(d_full, reach))
    # and the whole ring reads the same through either path
    cfg = SonarConfig(layout="ring", n_beams=72, range_max=reach, model=model)
    ring_axes = origins[:, :1] + np.arange(72) * (2 * np.pi / 72)
    monkeypatch.setattr(rays, "BOX_CULL", True)  # the box-culled path
    fast = sn.simulate_beams(cfg, origins, ring_axes, seg, origins, 0.2, owner)
    monkeypatch.setattr(rays, "BOX_CULL", False)  # every segment
    plain = sn.simulate_beams(cfg, origins, ring_axes, seg, origins, 0.2, owner)
    np.testing.assert_array_equal(fast, plain)
    assert np.any(fast < reach)


def test_compiled_mission_progress_matches_the_reference_on_a_noisy_drive():
    # an out-and-back route with KPOI vertices, a straight one and a single-vertex one
    routes = [np.array([[0, 0], [2, 0], [2, 2], [2, 0], [4, 0]], float),
              np.array([[0, 1], [1, 1], [3, 1], [5, 1]], float),
              np.array([[1, 3]], float)]
    kpois = np.array([[2, 2], [4, 0], [5, 1]], float)
    fast = Mission(kpois, 0.3, routes, waypoint_tol=0.2, lookahead=0.4)
    rng = np.random.default_rng(0)
    pos = np.array([[0, 0], [0, 1], [1, 3]], float)
    targets = [np.vstack([r, r[-1:]]) for r in routes]
    for step in range(400):  # drive each robot noisily along its route
        for i, t in enumerate(targets):
            goal = t[min(1 + step // 40, len(t) - 1)]
            d = goal - pos[i]
            pos[i] += 0.1 * d / max(np.hypot(*d), 1e-9) + rng.normal(0, 0.03, 2)
        before = fast.waypoint.copy()
        want_progress, want_waypoint = reference.advance_all(fast, pos)
        fast.update(pos, pos, step * 0.1)
        np.testing.assert_array_equal(fast.progress, want_progress)
        np.testing.assert_array_equal(fast.waypoint, want_waypoint)
        assert fast.waypoint[2] == 0
        assert np.array_equal(fast.advanced, fast.waypoint != before)
    assert fast.progress[0] > 5.0  # it went out to the KPOI, back and on


def test_goals_cache_follows_progress():
    m = Mission(np.array([[4.0, 0.0]]), 0.2, [np.array([[0, 0], [4, 0]], float)], waypoint_tol=0.15,
                lookahead=0.5)
    np.testing.assert_allclose(m.goals(), [[0.5, 0.0]])
    m.update(np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]), 0.1)
    np.testing.assert_allclose(m.goals(), [[1.5, 0.0]])
    np.testing.assert_allclose(m.remaining(np.array([[1.0, 0.0]])), [3.0])
    m.goals()[0, 0] = 99.0  # a copy: the cache is not exposed
    np.testing.assert_allclose(m.goals(), [[1.5, 0.0]])


def test_kinect_view_box_never_rejects_a_visible_robot():
    env = ParallelCoverageEnv("tree")
    sensor = env.kinects.sensors[0]
    x0, y0, x1, y1 = view_box(sensor)
    assert x1 > x0 and y1 > y0
    cam = sensor.camera
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(x0 - 2, x1 + 2, 4000), rng.uniform(y0 - 2, y1 + 2, 4000),
                np.full(4000, sensor.robot_height)]
    uv, z = cam.project(pts)
    in_image = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= cam.width - 1) & (uv[:, 1] >= 0) \
        & (uv[:, 1] <= cam.height - 1)
    assert in_image.any() and (~in_image).any()
    inside = (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)
    assert np.all(inside[in_image])  # every point the camera sees lies in the box


def test_fast_action_path_matches_validated_path():
    from parcover_env.sim.act_phase import _common_case, _validated, to_commands

    agents = ["robot_0", "robot_1"]
    acts = {a: np.array([2.0, -0.5], dtype=np.float32) for a in agents}
    np.testing.assert_array_equal(_common_case(acts, agents), _validated(acts, agents))
    np.testing.assert_allclose(to_commands(acts, agents, 0.2, 1.5), [[0.2, -0.75], [0.2, -0.75]])
    # anything unusual goes to the full validation
    assert _common_case({a: [0.1, 0.2] for a in agents}, agents) is None
    assert _common_case({a: np.array([np.nan, 0.0]) for a in agents}, agents) is None
    assert _common_case({a: np.array([1, 0]) for a in agents}, agents) is None
    assert _common_case({agents[0]: np.zeros(2)}, agents) is None


def test_sonar_config_replace_keeps_fast_path_exact_on_a_scenario(monkeypatch):
    env = ParallelCoverageEnv("tree")
    env.reset(seed=0)
    cfg = dataclasses.replace(env.scenario.robot.sonar, n_beams=72, model="specular")
    poses = env.world.poses()
    axes = poses[:, 2:3] + np.arange(72) * (2 * np.pi / 72)
    args = (cfg, poses[:, :2], axes, env.map.segments, poses[:, :2], env.scenario.robot.radius,
            np.arange(len(poses)))
    assert rays.BOX_CULL  # the culled path by default
    fast = sn.simulate_beams(*args)
    monkeypatch.setattr(rays, "BOX_CULL", False)
    plain = sn.simulate_beams(*args)
    np.testing.assert_array_equal(fast, plain)


def test_fast_action_path_with_a_scan_component():
    from parcover_env.sim.act_phase import _common_case, _validated, to_commands

    agents = ["robot_0", "robot_1"]
    acts = {a: np.array([2.0, -0.5, 0.7], dtype=np.float32) for a in agents}
    np.testing.assert_array_equal(_common_case(acts, agents, 3), _validated(acts, agents, 3))
    np.testing.assert_allclose(to_commands(acts, agents, 0.2, 1.5, width=3), [[0.2, -0.75, 0.7]] * 2, rtol=1e-6)
    assert _common_case({a: np.zeros(2) for a in agents}, agents, 3) is None  # wrong width: validated path

"""One Mission per scenario: maps and plan are built once and shared by env instances and the expert."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.planning import scenario_plan as planning_scenario
from parcover_env.scenarios import mission as mission_module
from parcover_env.world import map_model as map_module


@pytest.fixture
def counters(monkeypatch):
    """Count map-model and mission constructions, with every per-process cache emptied first."""
    map_module._cached_map_model.cache_clear()
    mission_module.mission_for.cache_clear()
    planning_scenario._cached_plan.cache_clear()
    planning_scenario._cached_roadmap.cache_clear()
    counts = {"maps": 0, "missions": 0}
    real_map, real_mission = map_module.MapModel.from_config.__func__, mission_module.build_mission

    def counting_map(cls, cfg, include_unknown=True):
        counts["maps"] += 1
        return real_map(cls, cfg, include_unknown)

    def counting_mission(scenario):
        counts["missions"] += 1
        return real_mission(scenario)

    monkeypatch.setattr(map_module.MapModel, "from_config", classmethod(counting_map))
    monkeypatch.setattr(mission_module, "build_mission", counting_mission)
    return counts


def test_env_construction_builds_the_true_and_known_map_once(counters):
    env = parcover_env.parallel_env("office")
    env.reset(seed=0)
    assert counters == {"maps": 2, "missions": 1}


def test_a_second_env_and_the_expert_reuse_the_mission(counters):
    first = parcover_env.parallel_env("office")
    second = parcover_env.parallel_env("office")
    obs, _ = second.reset(seed=1)
    expert_for(second).act(obs)
    assert counters == {"maps": 2, "missions": 1}
    assert second.mission is first.mission


def test_mission_routes_start_at_the_robots_and_end_at_their_plan_paths():
    env = parcover_env.parallel_env("tree")
    m = env.mission
    assert m.n_robots == env.n_robots == len(m.routes)
    for pose, route, path, lead_in in zip(m.start_poses, m.routes, m.plan.paths, m.lead_in_lengths):
        np.testing.assert_allclose(route[0], pose[:2])
        np.testing.assert_allclose(route[-len(path):], path)
        assert lead_in == pytest.approx(float(np.hypot(*np.diff(route[: len(route) - len(path) + 1], axis=0).T).sum()))


def test_mission_is_read_only():
    m = parcover_env.parallel_env("office").mission
    with pytest.raises(ValueError):
        m.routes[0][0, 0] = 1.0
    with pytest.raises(ValueError):
        m.start_poses[0, 0] = 1.0

"""Procedural scenarios: valid for every seed, deterministic, office-like and within the size budget."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Point, box

from parcover_env.errors import ConfigError
from parcover_env.scenarios import load_scenario
from parcover_env.scenarios.generator import generate_layout, generate_scenario_mapping
from parcover_env.world.map_model import MapModel

SEEDS = range(50)


@pytest.mark.parametrize("seed", SEEDS)
def test_every_seed_validates_and_respects_the_budget(seed):
    s = load_scenario(f"generated:{seed}")
    lay = generate_layout(seed)
    assert 6.0 <= s.map.size[0] <= 14.0 and 6.0 <= s.map.size[1] <= 14.0
    assert 2 <= len(lay.rooms) <= 8
    assert 3 <= len(s.kpois) <= 12
    assert len(s.kinects) >= 1
    assert s.name == f"generated-{seed}"
    # every room gets a door in the corridor wall and its KPOIs lie inside it
    for r in lay.rooms:
        assert r.x0 < r.door[0] < r.door[1] < r.x1
        for k in r.kpois:
            assert r.x0 < k[0] < r.x1 and r.y0 < k[1] < r.y1
    # desks stay clear of every KPOI
    desks = [box(*np.min(r.desk, axis=0), *np.max(r.desk, axis=0)) for r in lay.rooms if r.desk]
    for d in desks:
        assert all(d.distance(Point(k)) > 0.5 for k in s.kpois)


def test_deterministic_and_seed_dependent():
    assert generate_scenario_mapping("7") == generate_scenario_mapping("7")
    maps = {str(generate_scenario_mapping(str(i))["map"]) for i in range(10)}
    assert len(maps) == 10


def test_start_queue_holds_a_robot_per_kpoi_in_free_space():
    from parcover_env.world.placement import queue_poses

    for seed in range(0, 50, 7):
        s = load_scenario(f"generated:{seed}")
        poses = queue_poses(
            MapModel.from_config(s.map), s.queue, len(s.kpois), s.robot.radius, s.formation.spacing
        )
        assert poses.shape == (len(s.kpois), 3)


def test_bad_seed_text_is_a_config_error():
    with pytest.raises(ConfigError, match="integer seed"):
        load_scenario("generated:abc")
    with pytest.raises(ValueError, match="non-negative"):
        generate_layout(-1)


def test_generated_scenario_builds_an_env_and_steps():
    from parcover_env import parallel_env

    env = parallel_env("generated:3")
    obs, _ = env.reset(seed=0)
    assert set(obs) == set(env.possible_agents) and env.n_robots >= 1
    obs, *_ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(np.isfinite(o).all() for o in obs.values())

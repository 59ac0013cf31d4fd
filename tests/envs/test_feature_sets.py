"""Observation versions as named feature sets (:mod:`parcover_env.envs.feature_sets`): the registry, what
each set owns (entries, terms, fills, info values, state), and no version branch left in the engine."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import parcover_env
from parcover_env.config import ObservationConfig
from parcover_env.envs import critic_state
from parcover_env.envs.feature_sets import FEATURE_SETS, CoreFeatures, RouteFeatures, feature_set
from parcover_env.envs.obs_spec import ENTRIES
from parcover_env.envs.obs_v2 import target_kpois
from parcover_env.errors import ConfigError, ParcoverError
from parcover_env.mission.rewards import TERMS, TERMS_V2

PACKAGE = Path(parcover_env.__file__).resolve().parent
FORWARD = np.array([0.5, 0.1], dtype=np.float32)


def _env(version: int, scenario: str = "tree"):
    env = parcover_env.parallel_env(scenario, overrides={"observation": {"version": version}})
    env.reset(seed=3)
    return env


def test_the_registry_holds_every_version_the_schema_admits():
    assert {1: CoreFeatures, 2: RouteFeatures} == FEATURE_SETS and feature_set(2) is RouteFeatures
    for version in FEATURE_SETS:
        assert ObservationConfig(version=version).version == version
    with pytest.raises(ConfigError, match="version"):
        ObservationConfig(version=3)
    assert [fs.version for fs in FEATURE_SETS.values()] == list(FEATURE_SETS)
    assert [fs.name for fs in FEATURE_SETS.values()] == ["parcover_v1", "parcover_v2"]


def test_each_set_owns_its_sources_and_terms():
    assert CoreFeatures.terms == TERMS and RouteFeatures.terms == TERMS_V2 == ("own_kpoi", *TERMS)
    assert set(RouteFeatures.sources) - set(CoreFeatures.sources) == {"route", "teammates"}
    assert {e.source for e in ENTRIES} == set(RouteFeatures.sources)  # every entry belongs to some version
    by_name = {e.name: e for e in ENTRIES}
    assert by_name["x"].versions == (1, 2) and by_name["sonar"].versions == (1, 2)
    assert by_name["own_kpoi_cos"].versions == (2,) and by_name["mate_mask"].versions == (2,)


@pytest.mark.parametrize("version", [1, 2])
def test_an_env_observes_exactly_its_sets_entries(version):
    env = _env(version)
    fs = env.features
    assert type(fs) is FEATURE_SETS[version] and env.version == version
    entries = {e.name for e in ENTRIES if e.source in fs.sources}
    assert set(env.layout.names) <= entries
    assert {n for n in env.layout.names if by_source(n) in ("route", "teammates")} == (
        set() if version == 1 else {e.name for e in ENTRIES if e.source in ("route", "teammates")})
    assert env.terms == fs.terms  # no contact / uncertainty weight in tree


def by_source(name: str) -> str:
    return next(e.source for e in ENTRIES if e.name == name)


def test_version_1_owns_no_fills_info_or_routes():
    env = _env(1)
    fs = env.features
    assert fs.fills == () and fs.info == () and fs.route_facts is None and env.route_facts is None
    np.testing.assert_array_equal(env.state(), critic_state.state_v1(env))
    assert env.state_space.shape == (5 * env.n_robots + len(env.scenario.kpois) + 1,)
    with pytest.raises(ParcoverError, match=r"needs observation.version 2 \(parcover_v2\); this env is version 1"):
        env.route_done()
    _, _, _, _, infos = env.step(dict.fromkeys(env.agents, FORWARD))
    assert "route_done" not in infos["robot_0"]


def test_version_2_fills_its_entries_and_info_from_its_route_facts():
    env = _env(2)
    fs = env.features
    assert fs.fills == (fs.fill,) and [key for key, _ in fs.info] == ["route_done"]
    assert env.route_facts is fs.route_facts and env.state_space.shape == (critic_state.STATE_SIZE,)
    obs, _, _, _, infos = env.step(dict.fromkeys(env.agents, FORWARD))
    done = target_kpois(fs.route_facts, env.progress.visited[None])[1][0]
    np.testing.assert_array_equal(env.route_done(), done)
    assert [infos[a]["route_done"] for a in env.agents] == done.astype(float).tolist()
    assert list(infos["robot_0"])[-1] == "route_done"  # the set's own values come last
    col = env.layout.slices["done_mask"]
    np.testing.assert_array_equal(np.stack([obs[a][col][0] for a in env.agents]), done.astype(np.float32))
    np.testing.assert_array_equal(env.state(), critic_state.global_state(env, fs.route_facts, env.state_space))


def test_no_version_branch_in_the_engine():
    """The engine asks a feature set, never a version number (the schema's range check aside)."""
    branch = re.compile(r"version\s*(==|!=|>|<|\bin\b|\bnot in\b)|(==|!=)\s*\S*version\b")
    found = []
    for room in ("sim", "mission", "envs"):
        for path in (PACKAGE / room).rglob("*.py"):
            for i, line in enumerate(path.read_text().splitlines(), 1):
                code = line.split("#")[0]
                if branch.search(code) and '"""' not in code and not code.strip().startswith(("``", "*")):
                    found.append(f"{path.relative_to(PACKAGE)}:{i}: {line.strip()}")
    assert found == []

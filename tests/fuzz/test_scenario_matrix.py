"""Every scenario (the shipped ones and a generated map) under both presets, with every built-in
policy and the shipped checkpoints, as ``parcover run`` builds them: each runs a short episode, or
refuses in one line saying why. Every env version builds, resets and steps on every scenario under
both presets. The expert finishes office and hallway under the ``ideal`` preset (hallway's sonar
navigator read the covariance entries that preset drops: ``KeyError: 'sigma_major'``)."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_files import SHIPPED, files

import parcover_env as pe
from parcover_env import parcover_v0, parcover_v1, parcover_v2
from parcover_env.errors import ParcoverError
from parcover_env.harness.rollout import run_episode
from parcover_env.policies.registry import BASIC_POLICIES, make_policy, policy_overrides

SCENARIOS = (*pe.scenario_names(), "generated:3")
PRESETS = ("realistic", "ideal")
STEPS = 30


def _episode(scenario: str, preset: str, spec: str, steps: int) -> dict:
    env = pe.parallel_env(scenario, preset=preset, overrides=policy_overrides(spec, scenario))
    return run_episode(env, make_policy(spec, env, 0), 0, steps)


def test_the_matrix_covers_every_shipped_scenario_and_basic_policy():
    assert set(SCENARIOS) >= {"office", "tree", "hallway", "t_room", "triangle_room"}
    assert set(BASIC_POLICIES) == {"expert", "waypoint", "random"}


@pytest.mark.parametrize("policy", BASIC_POLICIES)
@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_basic_policies_run_everywhere(scenario, preset, policy):
    m = _episode(scenario, preset, policy, STEPS)
    assert m["steps"] == STEPS  # no mission ends this soon
    assert 0 <= m["kpois_visited"] <= len(pe.load_scenario(scenario).kpois)
    assert m["time"] == pytest.approx(STEPS * pe.load_scenario(scenario).physics.control_dt)


LEARNED = {
    "ppo_office": f"ppo:{SHIPPED / 'ppo_office.zip'}",
    "ppo_office_ideal": f"ppo:{SHIPPED / 'ppo_office_ideal.zip'}",
    "torchrl": f"torchrl:{SHIPPED / 'ippo_office_scratch'}",
    "torchrl_sampled": f"torchrl_sampled:{SHIPPED / 'mappo_generated_scan_sigma'}",
    "bc": "bc:BC",
}


@pytest.mark.parametrize("learned", sorted(LEARNED))
@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_learned_policies_run_or_refuse_in_one_line(scenario, preset, learned):
    pytest.importorskip("stable_baselines3" if learned.startswith("ppo") else "torch")
    spec = LEARNED[learned].replace("BC", str(files()["bc"]))
    try:
        m = _episode(scenario, preset, spec, 5)
    except ParcoverError as exc:  # a checkpoint of another observation layout: says so
        text = str(exc)
        assert "\n" not in text and "was trained on observations of shape" in text, text
        assert scenario.split(":")[0] in text or pe.load_scenario(scenario).name in text
        return
    assert m["steps"] == 5


def test_the_office_checkpoints_run_where_they_were_trained():
    """The refusals above are not blanket: each shipped office checkpoint runs on office."""
    pytest.importorskip("stable_baselines3")
    for spec, preset in ((LEARNED["ppo_office"], "realistic"), (LEARNED["ppo_office_ideal"], "ideal"),
                         (LEARNED["torchrl"], "realistic")):
        assert _episode("office", preset, spec, 3)["steps"] == 3


VERSIONS = {"v0": parcover_v0, "v1": parcover_v1, "v2": parcover_v2}


@pytest.mark.parametrize("version", sorted(VERSIONS))
@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_version_runs_on_every_scenario_and_preset(scenario, preset, version):
    env = VERSIONS[version].parallel_env(scenario, preset=preset)
    obs, _ = env.reset(seed=1)
    rng = np.random.default_rng(1)
    for _ in range(3):
        obs, rewards, *_ = env.step({a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32)
                                     for a in env.agents})
    for a, o in obs.items():
        assert env.observation_space(a).contains(o), a
        assert np.isfinite(rewards[a])
    assert env.state_space.contains(env.state().astype(env.state_space.dtype))
    assert env.metadata["name"] == f"parcover_{version}"


@pytest.mark.parametrize("scenario", ["office", "hallway"])
def test_the_expert_finishes_under_the_ideal_preset(scenario):
    env = pe.parallel_env(scenario, preset="ideal", overrides=policy_overrides("expert", scenario))
    assert "sigma_major" not in env.layout.slices  # the ideal preset's observation has no covariance entries
    m = run_episode(env, make_policy("expert", env, 0), 0)
    assert m["success"] and m["kpois_visited"] == len(env.scenario.kpois)
    assert m["steps"] < env.scenario.episode.max_steps
    if scenario == "hallway":  # the sonar navigator localized with the env's scans, from its own covariance
        assert m["sonar_scans"] > 0 and m["sonar_localized"] > 0

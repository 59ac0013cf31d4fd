"""The scripted experts run on what any policy can get: the env's layout, scenario, plan, the
mission's known map and routes, the sonar ring's beam angles, and the observations. A rollout with
every accessor of hidden state (true poses, the critic's state, the estimator's arrays, the true
map) made to raise still solves the mission."""

from __future__ import annotations

import types

import pytest

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.harness.rollout import run_episode


class _Hidden(Exception):
    pass


class PublicMission:
    """The mission without its true map (``map``: walls and the obstacles the robots do not know)."""

    def __init__(self, mission):
        self._mission = mission

    def __getattr__(self, name):
        if name == "map":
            raise _Hidden("the expert read the true map")
        return getattr(self._mission, name)


def _raise(*args, **kwargs):
    raise _Hidden("the expert read hidden state")


@pytest.mark.parametrize("scenario,seed,kind", [("generated:3", 3, "ScriptedExpert"),
                                                 ("hallway", 0, "SonarNavigator")])
def test_expert_runs_on_public_inputs_only(scenario, seed, kind, monkeypatch):
    env = parcover_env.parallel_env(scenario)
    public = types.SimpleNamespace(layout=env.layout, scenario=env.scenario, plan=env.plan, sonar=env.sonar,
                                   mission=PublicMission(env.mission))
    expert = expert_for(public)
    assert type(expert).__name__ == kind
    for name in ("true_poses", "pose_estimates", "pose_covariances", "state", "kinect_frames"):
        monkeypatch.setattr(env, name, _raise)
    m = run_episode(env, expert, seed)
    assert m["success"], f"{scenario}: {m['kpois_visited']}/{m['n_kpois']} KPOIs"


def test_expert_scans_through_the_env_service(monkeypatch):
    """With ``observation.scan`` the scripted expert asks the env for its sonar fixes: it never
    localizes a scan itself, and the env's fixes are what it counts."""
    from parcover_env.expert.team_localizer import TeamLocalizer

    monkeypatch.setattr(TeamLocalizer, "localize", _raise)
    env = parcover_env.parallel_env("generated:3", overrides={"observation": {"scan": {"enabled": True}}})
    public = types.SimpleNamespace(layout=env.layout, scenario=env.scenario, plan=env.plan, sonar=env.sonar,
                                   mission=PublicMission(env.mission))
    expert = expert_for(public)
    assert expert.fixer.env_scan
    monkeypatch.setattr(env, "true_poses", _raise)
    fixes = []
    obs, _ = env.reset(seed=3)
    expert.reset(obs)
    while env.agents:
        obs, _, _, _, infos = env.step(expert.act(obs))
        fixes += [i["sonar_fix"] for i in infos.values() if i["sonar_fix"]]
    m = env.metrics.summary()
    assert m["kpois_visited"] == m["n_kpois"]
    st = expert.stats()
    assert st["sonar_localized"] == fixes.count(1.0) >= 1 and st["sonar_failed"] == fixes.count(-1.0)

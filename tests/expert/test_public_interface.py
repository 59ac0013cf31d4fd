"""The scripted experts run on what any policy can get: the env's layout, scenario, plan, the
mission's known map and routes, the sonar ring's beam angles, and the observations. A rollout with
every accessor of hidden state (true poses, the critic's state, the estimator's arrays, the true
map) made to raise still solves the mission; the experts' sources name no such accessor; with the
env built as ``parcover run --policy expert`` builds it, they localize only through the env's sonar
service (the ``scan`` action)."""

from __future__ import annotations

import re
import types
from pathlib import Path

import pytest

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.harness.rollout import run_episode
from parcover_env.policies.registry import policy_overrides

HIDDEN = ("true_poses", "pose_estimates", "pose_covariances", "estimator", "scanner", "world", "kinect_frames",
          "state")


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
    env = parcover_env.parallel_env(scenario, overrides=policy_overrides("expert", scenario))
    public = types.SimpleNamespace(layout=env.layout, scenario=env.scenario, plan=env.plan, sonar=env.sonar,
                                   mission=PublicMission(env.mission))
    expert = expert_for(public)
    assert type(expert).__name__ == kind
    for name in ("true_poses", "pose_estimates", "pose_covariances", "state", "kinect_frames"):
        monkeypatch.setattr(env, name, _raise)
    assert expert.env_scan if kind == "SonarNavigator" else expert.fixer.env_scan
    m = run_episode(env, expert, seed)
    assert m["success"], f"{scenario}: {m['kpois_visited']}/{m['n_kpois']} KPOIs"


def test_expert_sources_name_no_hidden_accessor():
    pattern = re.compile(r"\.(" + "|".join(HIDDEN) + r")\b")
    folder = Path(parcover_env.__file__).parent / "expert"
    hits = [f"{p.name}: {line.strip()}" for p in sorted(folder.glob("*.py"))
            for line in p.read_text().splitlines()
            if pattern.search(line) and not line.lstrip().startswith(("from ", "import "))]
    assert hits == []
    assert pattern.search("pose = env.true_poses()[0]") and pattern.search("env.world.poses()")  # the grep bites


@pytest.mark.parametrize("scenario,seed", [("generated:3", 3), ("hallway", 0)])
def test_expert_scans_through_the_env_service(scenario, seed, monkeypatch):
    """With ``observation.scan`` (the expert's registered env) both experts ask the env for their
    sonar fixes: they never localize a scan themselves, and the env's fixes are what they count."""
    from parcover_env.expert.team_localizer import TeamLocalizer

    monkeypatch.setattr(TeamLocalizer, "localize", _raise)
    env = parcover_env.parallel_env(scenario, overrides=policy_overrides("expert", scenario))
    public = types.SimpleNamespace(layout=env.layout, scenario=env.scenario, plan=env.plan, sonar=env.sonar,
                                   mission=PublicMission(env.mission))
    expert = expert_for(public)
    monkeypatch.setattr(env, "true_poses", _raise)
    fixes = []
    obs, _ = env.reset(seed=seed)
    expert.reset(obs)
    while env.agents:
        obs, _, _, _, infos = env.step(expert.act(obs))
        fixes += [i["sonar_fix"] for i in infos.values() if i["sonar_fix"]]
    m = env.metrics.summary()
    assert m["kpois_visited"] == m["n_kpois"]
    st = expert.stats()
    assert st["sonar_localized"] == fixes.count(1.0) >= 1 and st["sonar_failed"] == fixes.count(-1.0)

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

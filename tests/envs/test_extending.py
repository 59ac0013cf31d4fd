"""The extension points of ``docs/extending.md``, done in tests: a reward term is one row of the term
table (its weight a field of ``RewardConfig``: here an existing one), a feature set's own info value is
one entry of its ``info``, and an entry of one feature set is its spec ``Entry`` and the set's fill
function; the engine (``sim/``) changes for none."""

from __future__ import annotations

import numpy as np

import parcover_env
from parcover_env.envs import feature_sets, obs_spec, observations
from parcover_env.envs.feature_sets import CoreFeatures
from parcover_env.envs.obs_spec import Entry
from parcover_env.mission import rewards
from parcover_env.mission.rewards import TERMS, Term

STILL = np.zeros(2, dtype=np.float32)


def test_a_reward_term_is_one_row_of_the_table(monkeypatch):
    """``steady``: the weight per step for every agent, optional (absent at weight 0), in place of ``uncertainty``."""
    table = {name: t for name, t in rewards.TERM_TABLE.items() if name != "uncertainty"}
    table["steady"] = Term("uncertainty", lambda c, x, shape: np.full(shape, c), optional=True, doc="per step")
    monkeypatch.setattr(rewards, "TERM_TABLE", table)
    env = parcover_env.parallel_env("tree", overrides={"rewards": {"uncertainty": -0.25}})
    assert env.terms == (*TERMS, "steady")
    env.reset(seed=1)
    _, rew, _, _, infos = env.step(dict.fromkeys(env.agents, STILL))
    for agent in env.agents:
        assert infos[agent]["reward_steady"] == -0.25
        parts = [infos[agent][f"reward_{t}"] for t in env.terms]
        assert rew[agent] == sum(parts)  # summed in the terms' order, the new one last
    assert parcover_env.parallel_env("tree").terms == TERMS  # weight 0: the term is absent


def test_a_feature_sets_own_info_value_is_one_entry(monkeypatch):
    """A version-1 set that also reports each robot's x estimate error (m) as ``x_error``."""

    class WithXError(CoreFeatures):
        def __init__(self, env):
            super().__init__(env)
            self.env = env
            self.info = (("x_error", self.x_error),)

        def x_error(self, visited: np.ndarray) -> np.ndarray:
            return (self.env.estimate[:, 0] - self.env.true_poses()[:, 0])[None]

    monkeypatch.setitem(feature_sets.FEATURE_SETS, 1, WithXError)
    env = parcover_env.parallel_env("tree")
    env.reset(seed=2)
    _, _, _, _, infos = env.step(dict.fromkeys(env.agents, STILL))
    errors = env.estimate[:, 0] - env.true_poses()[:, 0]
    assert [infos[a]["x_error"] for a in env.agents] == errors.tolist()
    assert list(infos["robot_0"])[-1] == "x_error"


def test_an_entry_of_a_feature_set_is_its_spec_entry_and_its_fill(monkeypatch):
    """``steps_left`` (the fraction of the step limit left): one ``Entry`` of a source only this set
    lists, and the set's fill function; the layout, bounds and space follow from the entry."""
    entry = Entry("steps_left", "-", "fraction of the step limit left", lambda s, b: (0.0, 1.0), "extra",
                  bounds_doc="[0, 1]")
    monkeypatch.setattr(obs_spec, "ENTRIES", (*obs_spec.ENTRIES, entry))
    monkeypatch.setattr(observations, "ENTRIES", (*observations.ENTRIES, entry))

    def fill(obs: np.ndarray, slices: dict[str, slice], x) -> None:
        obs[..., slices["steps_left"]] = (1.0 - x.scalars.time)[:, None, None]

    class WithStepsLeft(CoreFeatures):
        sources = (*CoreFeatures.sources, "extra")

        def __init__(self, env):
            super().__init__(env)
            self.fills = (fill,)

    monkeypatch.setitem(feature_sets.FEATURE_SETS, 1, WithStepsLeft)
    env = parcover_env.parallel_env("tree")
    assert env.layout.names[-1] == "steps_left" and env.layout.slices["steps_left"].stop == env.layout.size
    obs, _ = env.reset(seed=4)
    assert obs["robot_0"][-1] == 1.0
    for _ in range(3):
        obs, *_ = env.step(dict.fromkeys(env.agents, STILL))
    assert [obs[a][-1] for a in env.agents] == [np.float32(1.0 - 3 / 1500)] * env.n_robots  # tree: 1500 steps
    assert parcover_env.parallel_env("tree", overrides={"observation": {"version": 2}}).layout.names[-1] != "steps_left"

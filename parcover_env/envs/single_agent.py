"""Gymnasium view of a one-robot scenario (e.g. ``t_room``)."""

from __future__ import annotations

import gymnasium as gym

from parcover_env.envs import ParallelCoverageEnv
from parcover_env.envs.entry_checks import check_options, check_seed
from parcover_env.envs.slots import with_metrics

__all__ = ["SingleRobotCoverageEnv"]


class SingleRobotCoverageEnv(gym.Env):
    """A ``gymnasium.Env`` over a ParallelCoverageEnv whose team has exactly one robot.

    ``gymnasium.make("parcover_env/SingleRobotCoverage-v0", scenario="t_room")``. Multi-robot
    scenarios are refused unless ``overrides={"n_robots": 1}`` makes them single-robot.
    """

    metadata = ParallelCoverageEnv.metadata

    def __init__(self, scenario="t_room", render_mode=None, overrides=None, preset="realistic"):
        self.par = ParallelCoverageEnv(scenario, render_mode=render_mode, overrides=overrides, preset=preset)
        if self.par.n_robots != 1:
            raise ValueError(f"scenario '{self.par.scenario.name}' has {self.par.n_robots} robots; the single-agent "
                             "env needs 1 (pass overrides={'n_robots': 1})")
        self.agent = self.par.possible_agents[0]
        self.observation_space = self.par.observation_space(self.agent)
        self.action_space = self.par.action_space(self.agent)
        self.render_mode = render_mode

    def reset(self, *, seed=None, options=None):
        seed = check_seed(seed)  # before gymnasium's own seeding changes anything; numpy integers become int
        check_options(options)
        super().reset(seed=seed)
        obs, infos = self.par.reset(seed=seed, options=options)
        return obs[self.agent], infos[self.agent]

    def step(self, action):
        obs, rew, term, trunc, infos = self.par.step({self.agent: action})
        info = with_metrics(infos[self.agent])  # gymnasium's RecordEpisodeStatistics owns info["episode"]
        return obs[self.agent], rew[self.agent], term[self.agent], trunc[self.agent], info

    def render(self):
        return self.par.render()

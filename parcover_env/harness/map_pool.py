"""Training on a distribution of generated maps: one ParallelEnv with a fixed robot count.

A generated map fixes its team size (``n_robots: auto``: the PPCP planner's optimal r, 3-12 on the
generator's maps), but a MARL library's env has one agent list. :class:`MapPoolEnv` resolves this
by padding: its agents are ``robot_0 .. robot_{max_robots - 1}``; every reset draws one map of the
pool (``generated:A-B``, seeds ``A..B``) with the env's generator and runs that map's env, whose
``n`` robots are the first ``n`` agents. The other agents are padding: observation all zeros,
reward 0, actions ignored, ``info["pad"]`` 1 (0 for a real robot), ending with the team. All agents
act every step, so the library sees one fixed-shape group.

Fixed shapes across maps: the observation box and ``state_space`` are those of a map of
:data:`POOL_BOX` (the generator's largest sides, 14 m x 14 m) rather than of the drawn map, so a
policy scales every map's observations alike; the observation has the same entries on every
generated map (``observation.neighbours`` fixes the teammate block), and version 2's ``state()``
already has one shape. A policy trained here runs on any single ``generated:SEED`` env unchanged.

Evaluation maps are seeds >= :data:`FIRST_EVAL_SEED`; a pool reaching them is refused.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from parcover_env.errors import ConfigError

__all__ = ["POOL_PREFIX", "POOL_BOX", "FIRST_EVAL_SEED", "parse_pool", "is_pool", "MapPoolEnv"]

POOL_PREFIX = "generated:"
POOL_BOX = (0.0, 0.0, 14.0, 14.0)
"""Map bounds the pool's observation box and state space are built for (the generator's map sides
are 6-14 m, ``parcover_env.scenarios.generator``)."""
FIRST_EVAL_SEED = 1000
"""Generated maps from this seed on are evaluation maps: never drawn for training."""


def is_pool(scenario: str) -> bool:
    """Whether ``scenario`` names a pool of generated maps (``generated:A-B``)."""
    return isinstance(scenario, str) and scenario.startswith(POOL_PREFIX) and "-" in scenario[len(POOL_PREFIX):]


def parse_pool(scenario: str) -> tuple[int, ...]:
    """The seeds of ``generated:A-B`` (A..B inclusive); ConfigError naming the scenario otherwise."""
    a, _, b = scenario[len(POOL_PREFIX):].partition("-")
    if not (a.isdigit() and b.isdigit()) or int(a) > int(b):
        raise ConfigError(scenario, "", "a map pool is generated:A-B with seeds 0 <= A <= B")
    if int(b) >= FIRST_EVAL_SEED:
        raise ConfigError(scenario, "", f"seeds >= {FIRST_EVAL_SEED} are evaluation maps, not for training")
    return tuple(range(int(a), int(b) + 1))


class MapPoolEnv(ParallelEnv):
    """A ParallelEnv over the maps of ``scenario`` (``generated:A-B``), padded to ``max_robots``
    agents (see the module docstring). ``overrides``, ``preset`` and ``max_cycles`` go to every
    map's env; maps are built when first drawn and the ``cache`` most recently drawn are kept (a
    map's env holds ~6 MB; a rebuild takes ~0.1 s, a 5 % of an 800-step training episode)."""

    metadata = {"name": "parcover_map_pool", "render_modes": [], "is_parallelizable": True}

    def __init__(self, scenario: str, max_robots: int = 12, overrides: dict | None = None,
                 preset: str = "realistic", max_cycles: int | None = None, cache: int = 32):
        from parcover_env.envs import critic_state
        from parcover_env.envs.observations import ObservationLayout

        self.seeds = parse_pool(scenario)
        self.max_robots = max_robots
        self._kwargs = {"overrides": overrides, "preset": preset, "max_cycles": max_cycles}
        self._envs: OrderedDict = OrderedDict()
        self.cache = cache
        """Maps kept built (least recently drawn dropped first)."""
        self.possible_agents = [f"robot_{i}" for i in range(max_robots)]
        self.agents: list[str] = []
        first = self.map_env(self.seeds[0])
        self.scenario = first.scenario
        """The first map's scenario (the robot model and settings shared by every map)."""
        self._obs_space = ObservationLayout.build(first.scenario, POOL_BOX, first.sensors).space()
        self.state_space = (critic_state.state_space(first.scenario, POOL_BOX) if first.version == 2
                            else first.state_space)
        self._act_space = first.action_space(first.possible_agents[0])
        self.env = first
        """The env of the map drawn at the last reset."""
        self.map_seed = self.seeds[0]
        """The seed of that map (``generated:SEED``)."""
        self._rng = np.random.default_rng()

    def map_env(self, seed: int):
        """The env of map ``generated:SEED`` (built when first asked for, kept among the ``cache`` most
        recently asked for); ConfigError naming the map if it has more robots than ``max_robots`` or
        another observation shape than the pool's."""
        from parcover_env import parallel_env

        if seed not in self._envs:
            env = parallel_env(f"{POOL_PREFIX}{seed}", **self._kwargs)
            if env.n_robots > self.max_robots:
                raise ConfigError(f"{POOL_PREFIX}{seed}", "n_robots",
                                  f"{env.n_robots} robots, more than the pool's max_robots {self.max_robots}")
            shape = env.observation_space(env.possible_agents[0]).shape
            if self._envs and shape != self._obs_space.shape:
                raise ConfigError(f"{POOL_PREFIX}{seed}", "observation",
                                  f"observation shape {shape} differs from the pool's {self._obs_space.shape}")
            self._envs[seed] = env
            while len(self._envs) > max(self.cache, 1):
                self._envs.popitem(last=False)
        self._envs.move_to_end(seed)
        return self._envs[seed]

    @property
    def cached_seeds(self) -> tuple[int, ...]:
        """Seeds of the maps kept built, least recently drawn first."""
        return tuple(self._envs)

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_space

    @property
    def n_robots(self) -> int:
        """Agents of the pool (real robots of the drawn map plus padding)."""
        return self.max_robots

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.map_seed = int(self._rng.choice(self.seeds))
        self.env = self.map_env(self.map_seed)
        obs, infos = self.env.reset(seed=int(self._rng.integers(2**31)))
        self.agents = list(self.possible_agents)
        return self._pad_obs(obs), self._pad_infos(infos)

    def step(self, actions: dict):
        inner = {a: actions[a] for a in self.env.possible_agents}
        obs, rewards, terms, truncs, infos = self.env.step(inner)
        done, trunc = any(terms.values()), any(truncs.values())
        rewards = {a: float(rewards.get(a, 0.0)) for a in self.possible_agents}
        terms = dict.fromkeys(self.possible_agents, done)
        truncs = dict.fromkeys(self.possible_agents, trunc)
        out = self._pad_obs(obs), rewards, terms, truncs, self._pad_infos(infos)
        if done or trunc:
            self.agents = []
        return out

    def state(self) -> np.ndarray:
        return self.env.state()

    def _pad_obs(self, obs: dict) -> dict:
        zeros = np.zeros(self._obs_space.shape, dtype=np.float32)
        return {a: obs.get(a, zeros) for a in self.possible_agents}

    def _pad_infos(self, infos: dict) -> dict:
        """Every agent's info with the same keys: ``pad`` 0 for a real robot, 1 for padding (a copy
        of robot 0's info, its per-robot values zeroed); ``metrics/path_lengths`` padded to the pool."""
        template = infos[self.env.possible_agents[0]]
        pad = {k: (0.0 if k.startswith("reward_") or k in ("pose_error", "heading_error", "route_done", "sonar_fix")
                   else v) for k, v in template.items()}
        out = {}
        for a in self.possible_agents:
            info = dict(infos.get(a, pad))
            info["pad"] = 0.0 if a in infos else 1.0
            lengths = np.asarray(info.get("metrics/path_lengths", np.zeros(0)), dtype=float)
            if "metrics/path_lengths" in info:
                info["metrics/path_lengths"] = np.pad(lengths, (0, self.max_robots - len(lengths)))
            out[a] = info
        return out

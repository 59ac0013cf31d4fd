"""Batched worlds: K ParallelCoverageEnvs of one scenario stepped in one process as one SB3 VecEnv.

``BatchedVecEnv`` has one slot per robot per world (``num_envs = K x n_robots``; world ``k``'s
robots are slots ``k * n_robots ... (k + 1) * n_robots - 1``) and the semantics of
:class:`~parcover_env.envs.vec_env.ParallelVecEnv` (parameter sharing, auto-reset, per-world
seeding, ``terminal_observation`` / ``TimeLimit.truncated`` / ``metrics`` in the infos), so a
policy trained on one trains on the other. The worlds step through the same public stepper as
the ParallelEnv (:mod:`parcover_env.sim.pipeline`), with ``K`` worlds instead of one:

* the ``(K n_robots, A)`` actions go to the stepper as one ``(K, n_robots, A)`` block (validated
  there: a bad action raises the ActionError naming the agent before any world steps);
* each world steps its own pymunk space (one space per world); the drives, the wheel odometry
  and the Kinect systems (estimate model, tracker) of all worlds run in compiled calls over the
  ``(K, n_robots)`` axis, writing back into each world's own state;
* the sensors measure **all robots of all worlds** in one call each (the follower cameras' lines
  of sight, the sonar rings' casts, cross-talk and noise, and any other ``sensor`` entry of the
  observation spec): the worlds share the static walls, each robot sees the robots of its own
  world, and each world draws its random numbers from its own generator in the order the
  ParallelEnv does, so world ``k`` is bit for bit the ParallelEnv made with the same scenario,
  seed and actions (``tests/envs/test_batched.py``).

Seeding: ``seed(s)`` makes world ``k`` reset with seed ``s + k`` at the next ``reset()``; automatic
resets after an episode ends use no seed (the world continues its own generator) - exactly as K
separate ``parallel_env``s reset with ``s + k`` once and then with ``reset()``.

All robots of a world end together (terminated when every KPOI is visited, truncated at the step
limit), so there are no idle slots. Construction renders the static Kinect scenes once and shares
them (and the Mission) between the worlds.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from parcover_env.envs import slots
from parcover_env.envs.entry_checks import check_options, check_seed
from parcover_env.envs.parallel import ParallelCoverageEnv
from parcover_env.sim import pipeline

__all__ = ["BatchedVecEnv"]


def _shared_parts(env: ParallelCoverageEnv) -> dict[int, Any]:
    """A deepcopy memo sharing ``env``'s read-only, scenario-wide parts (Mission, map, plan and the
    rendered static Kinect scenes) instead of copying them."""
    agent = env.possible_agents[0]
    shared: list[Any] = [env.scenario, env.mission, env.map, env.known_map, env.plan, env.layout,
                         env.observation_space(agent), env.action_space(agent), env.state_space]
    if env.kinects is not None:
        shared.append(env.kinects.footprint)
        for s in env.kinects.sensors:
            shared += [s.nominal_static_depth, s.rays, s.pattern, s.camera]
            # reach-in kept: the rendered static scene (if rendered yet) has no public name without
            # rendering it; sharing it saves a copy of every Kinect's scene per world
            static = s._static
            if static is not None:
                shared.append(static)
    return {id(x): x for x in shared}


class BatchedVecEnv(VecEnv):
    """``n_envs`` worlds of ``scenario`` stepped together; see the module docstring."""

    def __init__(self, scenario: Any = "office", n_envs: int = 1, overrides: dict | None = None,
                 preset: str = "realistic", render_mode: str | None = None):
        if n_envs < 1:
            raise ValueError(f"n_envs must be >= 1, got {n_envs}")
        first = ParallelCoverageEnv(scenario, render_mode=render_mode, overrides=overrides, preset=preset)
        memo = _shared_parts(first)
        self.worlds: list[ParallelCoverageEnv] = [first] + [copy.deepcopy(first, dict(memo))
                                                            for _ in range(n_envs - 1)]
        self.n_robots = first.n_robots
        self.agents_per_world = list(first.possible_agents)
        obs_space = first.observation_space(first.possible_agents[0])
        self._zero = np.zeros(obs_space.shape, dtype=obs_space.dtype)
        self._seeds: list[int | None] = [None] * n_envs
        self._opts: list[dict | None] = [None] * n_envs
        self._actions: np.ndarray | None = None
        super().__init__(n_envs * self.n_robots, obs_space, first.action_space(first.possible_agents[0]))

    # ------------------------------------------------------------------ helpers
    @property
    def n_worlds(self) -> int:
        return len(self.worlds)

    def _world_of(self, slot: int) -> int:
        return int(slot) // self.n_robots

    def _reset_world(self, k: int, seed: int | None = None, options: dict | None = None) -> np.ndarray:
        obs, _ = self.worlds[k].reset(seed=seed, options=options)
        return np.stack([obs[a] for a in self.agents_per_world])

    # ------------------------------------------------------------------ VecEnv API
    def seed(self, seed: int | None = None) -> list[int | None]:
        """World ``k`` resets with ``seed + k`` at the next ``reset()``."""
        self._seeds = [None if seed is None else check_seed(seed, "seed(...)") + k for k in range(self.n_worlds)]
        return list(self._seeds)

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        for one in options if isinstance(options, list) else [options]:
            check_options(one)  # here, not half-way through the next reset()
        if isinstance(options, list):
            if len(options) != self.n_worlds:
                raise ValueError(f"options: expected {self.n_worlds} dicts (one per world), got {len(options)}")
            self._opts = list(options)
        else:
            self._opts = [options] * self.n_worlds

    def reset(self) -> np.ndarray:
        obs = [self._reset_world(k, self._seeds[k], self._opts[k]) for k in range(self.n_worlds)]
        self._seeds = [None] * self.n_worlds
        self._opts = [None] * self.n_worlds
        return np.concatenate(obs)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.shape[0] != self.num_envs:
            raise ValueError(f"actions: expected {self.num_envs} rows (one per agent slot), got {actions.shape}")
        self._actions = actions

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        acts, self._actions = self._actions, None
        n = self.n_robots
        # the (K N, A) slots as the (K, N, A) block of the worlds' agents (validated by the act phase)
        world_obs, out = pipeline.step(self.worlds, acts.reshape(self.n_worlds, n, *acts.shape[1:]),
                                      active=True)
        obs = world_obs.reshape(self.num_envs, *world_obs.shape[2:])  # the slots, world by world (a view)
        rewards = out.rewards.reshape(-1).astype(np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos = out.infos  # ``active`` set; a running episode's are complete (slots.slot_info adds nothing)
        copied = False
        for k, (t, tr) in enumerate(zip(out.terminated, out.truncated, strict=True)):
            if t or tr:  # all robots of a world end together
                if not copied:  # the terminal observations stay the worlds' rows: reset into a copy
                    obs, copied = obs.copy(), True
                o, rows = world_obs[k], slice(k * n, (k + 1) * n)
                for i, info in enumerate(infos[rows]):
                    slots.slot_info(info, o[i], t, tr)  # in place
                dones[rows] = True
                obs[rows] = self._reset_world(k)
        return obs, rewards, dones, infos

    def close(self) -> None:
        for w in self.worlds:
            w.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Attribute of the world behind each slot."""
        return [getattr(self.worlds[self._world_of(i)], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for k in dict.fromkeys(self._world_of(i) for i in self._get_indices(indices)):
            setattr(self.worlds[k], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Calls the method once per world behind the slots; one result per slot."""
        slots = list(self._get_indices(indices))
        results = {k: getattr(self.worlds[k], method_name)(*method_args, **method_kwargs)
                   for k in dict.fromkeys(self._world_of(i) for i in slots)}
        return [results[self._world_of(i)] for i in slots]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> list[np.ndarray | None]:
        """The top-down frame of the world behind each slot (``render_mode="rgb_array"``)."""
        frames = [w.render() for w in self.worlds]
        return [frames[self._world_of(i)] for i in range(self.num_envs)]


"""Stable-Baselines3 ``VecEnv`` over PettingZoo ParallelEnvs, with parameter sharing.

Every ParallelEnv contributes one slot per possible agent; a single policy acts for all slots.
Semantics (the SB3 conventions, applied per agent):

* ``seed(s)`` makes ParallelEnv ``i`` use seed ``s + i`` at the next ``reset()``; automatic resets
  after an episode ends use no seed (the env continues its own generator).
* When an agent's episode ends its slot reports ``done=True`` once, with
  ``info["terminal_observation"]`` (its last observation) and ``info["TimeLimit.truncated"]``
  (truncated and not terminated).
* An agent that finishes before its team (PettingZoo: it disappears from ``env.agents``) leaves an
  idle slot until the whole ParallelEnv resets: zero observation, zero reward, ``done=False``,
  ``info["active"] = False``; its actions are ignored (SuperSuit's "black death" convention).
* The env's end-of-episode metrics (flat ``metrics/<name>`` entries in ParallelCoverageEnv) are
  gathered into ``info["metrics"]`` (a dict); SB3 and ``VecMonitor`` own ``info["episode"]``
  (``{"r", "l", "t"}``).
* When every agent of a ParallelEnv is done the env is reset and the slots carry the new
  episode's first observations.

ParallelEnvs of different maps (``generated:SEED``) may differ in observation bounds and team
size; the VecEnv's observation space is the union of their boxes.

``multiprocess=True`` hosts each ParallelEnv in its own worker process (like ``SubprocVecEnv``).
:class:`~parcover_env.envs.batched.BatchedVecEnv` (``make_vec_env(..., backend="batched")``) steps
K worlds of one scenario in this process with the same semantics. SuperSuit is not needed. Wrap
the result in ``VecMonitor`` for episode statistics.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper, VecEnv

from parcover_env.envs.entry_checks import check_options, check_seed
from parcover_env.envs.slots import slot_info

__all__ = ["AgentSlots", "BACKENDS", "ParallelVecEnv", "make_vec_env"]  # + BatchedVecEnv (lazy)


class AgentSlots:
    """One ParallelEnv as a fixed array of agent slots with automatic reset (no SB3 needed)."""

    def __init__(self, env: Any):
        self.env = env
        self.agents = list(env.possible_agents)
        if not self.agents:
            raise ValueError("the ParallelEnv has no possible_agents")
        self.observation_space = env.observation_space(self.agents[0])
        self.action_space = env.action_space(self.agents[0])
        for a in self.agents[1:]:
            if env.observation_space(a) != self.observation_space or env.action_space(a) != self.action_space:
                raise ValueError(
                    f"parameter sharing needs identical spaces for every agent; '{a}' differs "
                    f"from '{self.agents[0]}'"
                )
        if not isinstance(self.observation_space, spaces.Box):
            raise ValueError(f"observation space must be a Box, got {self.observation_space}")
        self._zero = np.zeros(self.observation_space.shape, dtype=self.observation_space.dtype)

    @property
    def n(self) -> int:
        return len(self.agents)

    def _stack(self, obs: dict) -> np.ndarray:
        return np.stack(
            [np.asarray(obs[a], dtype=self._zero.dtype) if a in obs else self._zero for a in self.agents]
        )

    def reset(self, seed: int | None = None, options: dict | None = None) -> np.ndarray:
        obs, _ = self.env.reset(seed=seed, options=options or None)
        return self._stack(obs)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """Step the live agents; returns (obs, rewards, dones, infos), one row per slot."""
        live = set(self.env.agents)
        acts = {a: actions[i] for i, a in enumerate(self.agents) if a in live}
        obs, rew, term, trunc, infos = self.env.step(acts)
        still = set(self.env.agents)
        rewards = np.zeros(self.n, dtype=np.float32)
        dones = np.zeros(self.n, dtype=bool)
        out_infos: list[dict] = []
        for i, a in enumerate(self.agents):
            if a not in live:
                out_infos.append({"active": False})
                continue
            rewards[i] = float(rew.get(a, 0.0))
            t, tr = bool(term.get(a, False)), bool(trunc.get(a, False))
            dones[i] = t or tr or a not in still
            last = np.asarray(obs.get(a, self._zero), dtype=self._zero.dtype) if dones[i] else None
            out_infos.append(slot_info(dict(infos.get(a, {})), last, t, tr, ended=bool(dones[i])))
        if not still:
            return self.reset(), rewards, dones, out_infos
        return self._stack({a: obs[a] for a in still if a in obs}), rewards, dones, out_infos


def _worker(remote, parent_remote, env_fn_wrapper: CloudpickleWrapper) -> None:
    parent_remote.close()
    slots = AgentSlots(env_fn_wrapper.var())
    try:
        while True:
            cmd, data = remote.recv()
            if cmd == "step":
                remote.send(slots.step(data))
            elif cmd == "reset":
                remote.send(slots.reset(*data))
            elif cmd == "spaces":
                remote.send((slots.n, slots.observation_space, slots.action_space))
            elif cmd == "get_attr":
                remote.send(getattr(slots.env, data))
            elif cmd == "set_attr":
                remote.send(setattr(slots.env, data[0], data[1]))
            elif cmd == "env_method":
                name, args, kwargs = data
                remote.send(getattr(slots.env, name)(*args, **kwargs))
            elif cmd == "close":
                slots.env.close()
                remote.close()
                break
            else:
                raise NotImplementedError(f"unknown command {cmd!r}")
    except (KeyboardInterrupt, EOFError):
        pass


class _Remote:
    """Client side of a worker process hosting one ParallelEnv; same calls as AgentSlots."""

    def __init__(self, ctx, env_fn: Callable[[], Any]):
        self.pipe, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=_worker, args=(child, self.pipe, CloudpickleWrapper(env_fn)), daemon=True
        )
        self.proc.start()
        child.close()
        self.pipe.send(("spaces", None))
        self.n, self.observation_space, self.action_space = self.pipe.recv()

    def call(self, cmd: str, data: Any = None) -> Any:
        self.pipe.send((cmd, data))
        return self.pipe.recv()

    def close(self) -> None:
        with contextlib.suppress(BrokenPipeError, EOFError):
            self.pipe.send(("close", None))
        self.proc.join(timeout=5)


class ParallelVecEnv(VecEnv):
    """SB3 ``VecEnv`` with one slot per agent of every ParallelEnv made by ``env_fns``."""

    def __init__(
        self,
        env_fns: Sequence[Callable[[], Any]],
        multiprocess: bool = False,
        start_method: str | None = None,
    ):
        if not env_fns:
            raise ValueError("env_fns must hold at least one env factory")
        self.multiprocess = multiprocess
        if multiprocess:
            ctx = mp.get_context(
                start_method or ("forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn")
            )
            self._envs: list[Any] = [_Remote(ctx, fn) for fn in env_fns]
        else:
            self._envs = [AgentSlots(fn()) for fn in env_fns]
        first = self._envs[0]
        obs_space = first.observation_space
        for k, e in enumerate(self._envs[1:], start=1):
            o = e.observation_space
            if (
                e.action_space != first.action_space
                or o.shape != obs_space.shape
                or o.dtype != obs_space.dtype
            ):
                raise ValueError(
                    f"ParallelEnv {k} has spaces {o}, {e.action_space}; env 0 has {obs_space}, "
                    f"{first.action_space}: shapes and action spaces must match"
                )
            # different maps (domain randomization) differ only in bounds: use their union
            obs_space = spaces.Box(
                np.minimum(obs_space.low, o.low), np.maximum(obs_space.high, o.high), dtype=obs_space.dtype
            )
        sizes = [e.n for e in self._envs]
        self._offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self._env_seeds: list[int | None] = [None] * len(self._envs)
        self._env_options: list[dict | None] = [None] * len(self._envs)
        self._actions: np.ndarray | None = None
        super().__init__(int(self._offsets[-1]), obs_space, first.action_space)

    # ------------------------------------------------------------------ helpers
    @property
    def n_parallel_envs(self) -> int:
        return len(self._envs)

    def _call(self, k: int, cmd: str, data: Any = None) -> Any:
        e = self._envs[k]
        if self.multiprocess:
            return e.call(cmd, data)
        if cmd == "reset":
            return e.reset(*data)
        if cmd == "step":
            return e.step(data)
        if cmd == "get_attr":
            return getattr(e.env, data)
        if cmd == "set_attr":
            return setattr(e.env, data[0], data[1])
        name, args, kwargs = data
        return getattr(e.env, name)(*args, **kwargs)

    def _env_indices(self, indices) -> list[int]:
        """ParallelEnv indices behind the given slot indices (each once, in order)."""
        envs = [int(np.searchsorted(self._offsets, i, side="right") - 1) for i in self._get_indices(indices)]
        return list(dict.fromkeys(envs))

    # ------------------------------------------------------------------ VecEnv API
    def seed(self, seed: int | None = None) -> list[int | None]:
        """ParallelEnv ``i`` resets with ``seed + i`` at the next ``reset()``."""
        self._env_seeds = [None if seed is None else check_seed(seed, "seed(...)") + i for i in range(len(self._envs))]
        return list(self._env_seeds)

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        for one in options if isinstance(options, list) else [options]:
            check_options(one)  # here, not half-way through the next reset()
        if isinstance(options, list):
            if len(options) != len(self._envs):
                raise ValueError(
                    f"options: expected {len(self._envs)} dicts (one per ParallelEnv), got {len(options)}"
                )
            self._env_options = list(options)
        else:
            self._env_options = [options] * len(self._envs)

    def reset(self) -> np.ndarray:
        obs = [
            self._call(k, "reset", (self._env_seeds[k], self._env_options[k])) for k in range(len(self._envs))
        ]
        self._env_seeds = [None] * len(self._envs)
        self._env_options = [None] * len(self._envs)
        return np.concatenate(obs)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.shape[0] != self.num_envs:
            raise ValueError(
                f"actions: expected {self.num_envs} rows (one per agent slot), got {actions.shape}"
            )
        self._actions = actions

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        acts, self._actions = self._actions, None
        chunks = [acts[self._offsets[k] : self._offsets[k + 1]] for k in range(len(self._envs))]
        if self.multiprocess:
            for e, a in zip(self._envs, chunks, strict=False):
                e.pipe.send(("step", a))
            results = [e.pipe.recv() for e in self._envs]
        else:
            results = [e.step(a) for e, a in zip(self._envs, chunks, strict=False)]
        obs, rew, done, infos = zip(*results, strict=False)
        return (
            np.concatenate(obs),
            np.concatenate(rew),
            np.concatenate(done),
            [i for group in infos for i in group],
        )

    def close(self) -> None:
        for _k, e in enumerate(self._envs):
            if self.multiprocess:
                e.close()
            else:
                e.env.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Attribute of the ParallelEnv behind each slot."""
        out = []
        for i in self._get_indices(indices):
            k = int(np.searchsorted(self._offsets, i, side="right") - 1)
            out.append(self._call(k, "get_attr", attr_name))
        return out

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for k in self._env_indices(indices):
            self._call(k, "set_attr", (attr_name, value))

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Calls the method once per ParallelEnv behind the slots; one result per slot."""
        results = {
            k: self._call(k, "env_method", (method_name, method_args, method_kwargs))
            for k in self._env_indices(indices)
        }
        return [
            results[int(np.searchsorted(self._offsets, i, side="right") - 1)]
            for i in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> list[np.ndarray | None]:
        frames = [self._call(k, "env_method", ("render", (), {})) for k in range(len(self._envs))]
        return [
            frames[int(np.searchsorted(self._offsets, i, side="right") - 1)] for i in range(self.num_envs)
        ]


BACKENDS = ("batched", "process", "inprocess")
"""``make_vec_env`` backends: ``batched`` (K worlds in this process, the sonar of all their robots
in one vectorized call: :class:`~parcover_env.envs.batched.BatchedVecEnv`), ``process`` (one worker
process per world: :class:`ParallelVecEnv` with ``multiprocess=True``), ``inprocess`` (one
:class:`ParallelVecEnv` slot group per world, stepped one after the other)."""


def make_vec_env(
    scenario: Any = "office",
    n_envs: int = 1,
    overrides: dict | None = None,
    multiprocess: bool | None = None,
    monitor: bool = True,
    backend: str | None = None,
    preset: str = "realistic",
    render_mode: str | None = None,
) -> VecEnv:
    """``n_envs`` worlds of a scenario as one parameter-sharing SB3 VecEnv (+ ``VecMonitor``).

    ``num_envs = n_envs x n_robots`` slots (world ``k``'s robots are consecutive); ``seed(s)``
    makes world ``k`` reset with seed ``s + k`` at the next ``reset()``. ``backend``: one of
    :data:`BACKENDS`, default ``"inprocess"``; ``multiprocess=True`` (the older flag) means
    ``"process"``. Every backend gives the same observations, rewards, dones and infos for the same
    seeds and actions (``render_mode="rgb_array"`` for ``get_images``)."""
    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    if backend is None:
        backend = "process" if multiprocess else "inprocess"
    elif backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    elif multiprocess is not None and multiprocess != (backend == "process"):
        raise ValueError(f"multiprocess={multiprocess} contradicts backend={backend!r}")
    from stable_baselines3.common.vec_env import VecMonitor

    if backend == "batched":
        from parcover_env.envs.batched import BatchedVecEnv

        venv: VecEnv = BatchedVecEnv(scenario, n_envs, overrides, preset=preset, render_mode=render_mode)
    else:
        venv = ParallelVecEnv([_EnvFactory(scenario, overrides, preset, render_mode) for _ in range(n_envs)],
                              multiprocess=backend == "process")
    return VecMonitor(venv) if monitor else venv


class _EnvFactory:
    """Picklable factory of a ParallelCoverageEnv (for worker processes)."""

    def __init__(self, scenario: Any, overrides: dict | None, preset: str = "realistic",
                 render_mode: str | None = None):
        self.scenario, self.overrides, self.preset, self.render_mode = scenario, overrides, preset, render_mode

    def __call__(self):
        from parcover_env.envs import ParallelCoverageEnv

        return ParallelCoverageEnv(self.scenario, render_mode=self.render_mode, overrides=self.overrides,
                                   preset=self.preset)


def __getattr__(name: str) -> Any:
    if name == "BatchedVecEnv":  # lazily: the batched module imports the env
        from parcover_env.envs.batched import BatchedVecEnv

        return BatchedVecEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

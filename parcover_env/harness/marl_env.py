"""The robots of a PettingZoo ParallelEnv as one TorchRL env, converted as arrays.

TorchRL's ``PettingZooWrapper`` converts every agent's observation, reward, flags and each of its
35 info entries with one ``torch.tensor`` call apiece, and deep-copies the observations and infos
every step: profiled on ``parcover train ippo generated:0-499`` (12 agents), 14 ms of every 31 ms
training step against 4 ms for the env itself. :class:`RobotsEnv` is a plain TorchRL ``EnvBase``
with the same keys as that wrapper for a one-group env (``("robot", "observation")`` ``[N, D]``,
``("robot", "action")`` ``[N, A]``, ``("robot", "reward")`` / ``done`` / ``terminated`` /
``truncated`` ``[N, 1]``, the root flags ``[1]``, ``"state"`` if asked), built with one
``np.stack`` per entry, and only the info entries the trainer reads (:data:`INFO_KEYS`). It adds
``("robot", "real")`` ``[N, 1]`` bool: the agent is one of the map's robots, not padding of a map
pool (``info["pad"]``; every agent of a single scenario is real), the mask of the PPO loss
(:mod:`~parcover_env.harness.marl_loss`); with ``mask_done`` a robot whose own route is done
(``info["route_done"]``, env version 2) is not ``real`` either. Collection speed of both: the lab
page ``docs/lab/train_and_compare.md`` (measured then with ``benchmarks/train_throughput.py``, which now
times the whole training loop).

``max_steps`` (``MarlConfig.episode_steps``) cuts training episodes short: the env is truncated at
that step (bootstrapped like any truncation) while the ParallelEnv keeps its own step limit, so the
observation's ``time`` entry (elapsed fraction of the env's step limit) means in training what it
means in evaluation. At such a cut the episode metrics are the env's own if it emits them, else
the KPOIs visited so far (``progress.visited``; success 0).

All agents act every step and end together (the coverage env and its map pool guarantee it), so
there is no per-agent liveness mask. Several worlds run side by side through TorchRL's ``SerialEnv``
(:class:`parcover_env.harness.marl.EnvMaker`), so the policy runs once for all of them.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from parcover_env.harness.marl_loss import GROUP

__all__ = ["RobotsEnv", "INFO_KEYS"]

INFO_KEYS = ("pad", "metrics/kpois_visited", "metrics/n_kpois", "metrics/success")
"""Info entries kept under ``("robot", "info")`` (one float per agent; ``pad`` 0 when the env has none)."""


def _flags(shape: tuple[int, ...]) -> dict:
    return {k: Categorical(n=2, shape=torch.Size(shape), dtype=torch.bool) for k in ("done", "terminated", "truncated")}


class RobotsEnv(EnvBase):
    """``parallel`` (a ParallelEnv whose agents all act every step and end together) as a TorchRL env
    of the group ``"robot"``; ``with_state``: also ``"state"`` = ``parallel.state()`` (MAPPO's critic).
    The env's generator is the ParallelEnv's own (seed it with ``parallel.reset(seed=...)`` first)."""

    def __init__(self, parallel, with_state: bool = False, max_steps: int = 0, mask_done: bool = False):
        super().__init__(batch_size=torch.Size([]))
        self.parallel = parallel
        self.with_state = with_state
        self.max_steps = int(max_steps)
        """Truncate at this step of an episode (0: only the ParallelEnv's own end)."""
        self.steps = 0
        self.mask_done = bool(mask_done)
        """``("robot", "real")`` is false for a robot whose own route is done, too."""
        self.agents = list(parallel.possible_agents)
        n = len(self.agents)
        obs_space, act_space = parallel.observation_space(self.agents[0]), parallel.action_space(self.agents[0])
        group = {"observation": Unbounded(shape=(n, *obs_space.shape), dtype=torch.float32),
                 "real": Categorical(n=2, shape=torch.Size((n, 1)), dtype=torch.bool),
                 "info": Composite({k: Unbounded(shape=(n,), dtype=torch.float32) for k in INFO_KEYS}, shape=(n,))}
        obs = {GROUP: Composite(group, shape=(n,))}
        if with_state:
            obs["state"] = Unbounded(shape=parallel.state_space.shape, dtype=torch.float32)
        self.observation_spec = Composite(obs)
        low, high = (torch.tensor(np.broadcast_to(b, (n, *act_space.shape)), dtype=torch.float32)
                     for b in (act_space.low, act_space.high))
        self.action_spec = Composite({GROUP: Composite({"action": Bounded(low, high, shape=low.shape)}, shape=(n,))})
        self.reward_spec = Composite({GROUP: Composite({"reward": Unbounded(shape=(n, 1))}, shape=(n,))})
        self.done_spec = Composite({**_flags((1,)), GROUP: Composite(_flags((n, 1)), shape=(n,))})

    def _observation(self, obs: dict, infos: dict) -> dict:
        info = np.array([[float(infos[a].get(k, 0.0)) for k in INFO_KEYS] for a in self.agents], dtype=np.float32)
        real = info[:, 0:1] < 0.5
        if self.mask_done:
            real &= np.array([[infos[a].get("route_done", 0.0) < 0.5] for a in self.agents])
        group = {"observation": torch.from_numpy(np.stack([obs[a] for a in self.agents]).astype(np.float32)),
                 "real": torch.from_numpy(real),
                 "info": {k: torch.from_numpy(info[:, i].copy()) for i, k in enumerate(INFO_KEYS)}}
        out = {GROUP: TensorDict(group, batch_size=[len(self.agents)])}
        if self.with_state:
            out["state"] = torch.as_tensor(self.parallel.state(), dtype=torch.float32)
        return out

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        obs, infos = self.parallel.reset()
        self.steps = 0
        out = self._observation(obs, infos)
        n = len(self.agents)
        out[GROUP].update({k: torch.zeros(n, 1, dtype=torch.bool) for k in ("done", "terminated", "truncated")})
        out.update({k: torch.zeros(1, dtype=torch.bool) for k in ("done", "terminated", "truncated")})
        return TensorDict(out, batch_size=[])

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get((GROUP, "action")).detach().cpu().numpy()
        obs, rewards, terms, truncs, infos = self.parallel.step(dict(zip(self.agents, actions, strict=True)))
        self.steps += 1
        term = np.array([[bool(terms[a])] for a in self.agents])
        trunc = np.array([[bool(truncs[a])] for a in self.agents])
        if self.max_steps and self.steps >= self.max_steps and not (term | trunc).any():
            trunc[:] = True
            infos = self._cut_infos(infos)
        out = self._observation(obs, infos)
        out[GROUP].update({"reward": torch.tensor([[float(rewards[a])] for a in self.agents], dtype=torch.float32),
                           "terminated": torch.from_numpy(term), "truncated": torch.from_numpy(trunc),
                           "done": torch.from_numpy(term | trunc)})
        out.update({"terminated": torch.tensor([term.any()]), "truncated": torch.tensor([trunc.any()]),
                    "done": torch.tensor([(term | trunc).any()])})
        return TensorDict(out, batch_size=[])

    def _cut_infos(self, infos: dict) -> dict:
        """``infos`` with the KPOIs visited so far as the episode metrics (an episode cut at ``max_steps``
        before the env's own end; ``metrics/success`` 0). A map pool's counts are its drawn map's."""
        inner = getattr(self.parallel, "env", self.parallel)
        visited = np.asarray(inner.progress.visited)
        metrics = {"metrics/kpois_visited": float(visited.sum()), "metrics/n_kpois": float(visited.size),
                   "metrics/success": 0.0}
        return {a: {**infos.get(a, {}), **metrics} for a in self.agents}

    def _set_seed(self, seed: int | None) -> None:
        if seed is not None:
            self.parallel.reset(seed=seed)

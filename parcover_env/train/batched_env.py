"""The ``B`` worlds of :class:`~parcover_env.train.world_groups.WorldGroups` as one TorchRL env of batch ``[B]``.

:class:`BatchedRobotsEnv` has the keys of :class:`~parcover_env.harness.marl_env.RobotsEnv` with a
leading world axis, so ``parcover train``'s actor, critic and loss run on it unchanged:
``("robot", "observation")`` ``[B, N, D]``, ``("robot", "action")`` ``[B, N, A]``, ``("robot",
"reward")`` / ``done`` / ``terminated`` / ``truncated`` ``[B, N, 1]``, the root flags ``[B, 1]``,
``("robot", "real")`` ``[B, N, 1]``, ``("robot", "info", k)`` ``[B, N]`` for ``k`` in
:data:`~parcover_env.harness.marl_env.INFO_KEYS`, and ``"state"`` ``[B, S]`` when asked. Each entry
goes from the worlds' arrays to a tensor in one ``torch.from_numpy`` (no per-world env, no per-agent
dict). TorchRL's partial reset (``"_reset"`` ``[B, 1]``, the collector's after a world's episode
ends) resets the worlds it names; a map pool's world may idle there until its group draws its next
map (the module docstring of :mod:`~parcover_env.train.world_groups`): its steps are padding,
neither done nor counted.

``set_seed(s)`` (or ``seed``) seeds the worlds' generators; the next full reset draws from them.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from parcover_env.harness.marl_env import INFO_KEYS
from parcover_env.harness.marl_loss import GROUP
from parcover_env.train.world_groups import Transition, WorldGroups, WorldsConfig

__all__ = ["BatchedRobotsEnv"]

FLAGS = ("done", "terminated", "truncated")


def _flags(shape: tuple[int, ...]) -> dict:
    return {k: Categorical(n=2, shape=torch.Size(shape), dtype=torch.bool) for k in FLAGS}


class BatchedRobotsEnv(EnvBase):
    """The worlds of ``cfg`` (:class:`~parcover_env.train.world_groups.WorldsConfig`) as a TorchRL env of
    batch ``[cfg.worlds]`` of the group ``"robot"``; see the module docstring."""

    def __init__(self, cfg: WorldsConfig, seed: int | None = None):
        self.worlds = WorldGroups(cfg, seed)
        b, n = self.worlds.size, self.worlds.n_agents
        super().__init__(batch_size=torch.Size([b]))
        obs_space, act_space = self.worlds.observation_space, self.worlds.action_space
        group = {"observation": Unbounded(shape=(b, n, *obs_space.shape), dtype=torch.float32),
                 "real": Categorical(n=2, shape=torch.Size((b, n, 1)), dtype=torch.bool),
                 "info": Composite({k: Unbounded(shape=(b, n), dtype=torch.float32) for k in INFO_KEYS},
                                   shape=(b, n))}
        obs = {GROUP: Composite(group, shape=(b, n))}
        if cfg.state:
            obs["state"] = Unbounded(shape=(b, *self.worlds.state_space.shape), dtype=torch.float32)
        self.observation_spec = Composite(obs, shape=(b,))
        low, high = (torch.tensor(np.broadcast_to(x, (b, n, *act_space.shape)), dtype=torch.float32)
                     for x in (act_space.low, act_space.high))
        self.action_spec = Composite({GROUP: Composite({"action": Bounded(low, high, shape=low.shape)}, shape=(b, n))},
                                     shape=(b,))
        self.reward_spec = Composite({GROUP: Composite({"reward": Unbounded(shape=(b, n, 1))}, shape=(b, n))},
                                     shape=(b,))
        self.done_spec = Composite({**_flags((b, 1)), GROUP: Composite(_flags((b, n, 1)), shape=(b, n))}, shape=(b,))

    def _tensordict(self, t: Transition, stepped: bool) -> TensorDict:
        b, n = self.worlds.size, self.worlds.n_agents
        info = TensorDict({k: torch.from_numpy(t.info[k]) for k in INFO_KEYS}, batch_size=[b, n])
        group = {"observation": torch.from_numpy(t.observation), "real": torch.from_numpy(t.real[..., None]),
                 "info": info}
        term, trunc = torch.from_numpy(t.terminated[:, None]), torch.from_numpy(t.truncated[:, None])
        done = term | trunc
        if stepped:
            group["reward"] = torch.from_numpy(t.reward[..., None])
        for key, flag in zip(FLAGS, (done, term, trunc), strict=True):
            group[key] = flag[:, None].expand(b, n, 1)
        out = {GROUP: TensorDict(group, batch_size=[b, n]), "done": done, "terminated": term, "truncated": trunc}
        if t.state is not None:
            out["state"] = torch.from_numpy(t.state)
        return TensorDict(out, batch_size=[b])

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None
        if tensordict is not None:
            reset = tensordict.get("_reset", None)
            if reset is None:
                reset = tensordict.get((GROUP, "_reset"), None)
            if reset is not None:
                mask = reset.reshape(self.worlds.size, -1).any(-1).cpu().numpy()
        return self._tensordict(self.worlds.reset(mask), stepped=False)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get((GROUP, "action")).detach().cpu().numpy()
        return self._tensordict(self.worlds.step(actions), stepped=True)

    def _set_seed(self, seed: int | None) -> None:
        self.worlds.seed(seed)

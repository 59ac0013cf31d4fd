"""MAPPO's permutation-invariant critic on the version-2 state tokens (``critic: attention``).

``env.state()`` of an env with ``observation.version: 2`` is :data:`MAX_ROBOTS` robot tokens,
:data:`MAX_KPOIS` KPOI tokens (each with a mask column: 1 = real, 0 = padding) and the global
features (:mod:`parcover_env.envs.critic_state`). :class:`TokenCritic` values robot ``i`` by

1. scaling every token column to [-1, 1] by the state's bounds (x, y by the map's box, so every map
   is read in the same frame; not saved with the weights) and embedding robot and KPOI tokens with
   one shared MLP each (``embed`` wide);
2. self-attention among the robot tokens, then cross-attention from the robot tokens to the KPOI
   tokens (``torch.nn.MultiheadAttention`` with ``key_padding_mask`` = the padding), each a residual
   step followed by ``LayerNorm``;
3. the mean of the real robots' outputs (the team), robot ``i``'s own output (its token is row ``i``:
   agent order, so with ``N`` agents only the first ``N`` robot rows are read, the rest being padding by
   the layout; their masks still apply), the global features and robot ``i``'s own observation (the MAPPO paper's
   agent-specific state, Yu et al. 2022), concatenated into a tanh MLP with one output.

Nothing depends on the order of the other robots or of the KPOIs, nor on the contents of padded
tokens (masked keys get weight 0; the mean counts real robots only): one critic for 1-16 robots and
1-32 KPOIs, as BenchMARL's GNN critic. Needs the ``train`` extra (torch).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from parcover_env.envs.critic_state import GLOBAL_FEATURES, KPOI_FEATURES, MAX_KPOIS, MAX_ROBOTS, ROBOT_FEATURES

__all__ = ["TokenCritic"]

_RF, _KF, _GF = len(ROBOT_FEATURES), len(KPOI_FEATURES), len(GLOBAL_FEATURES)
_R, _K = MAX_ROBOTS * _RF, MAX_KPOIS * _KF


def _scale(low: np.ndarray, high: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """Centre and half-width of a box (half-width at least 1e-6)."""
    low_t, high_t = torch.as_tensor(low, dtype=torch.float32), torch.as_tensor(high, dtype=torch.float32)
    return (low_t + high_t) / 2, torch.clamp((high_t - low_t) / 2, min=1e-6)


def _embedder(n_in: int, width: int) -> nn.Module:
    return nn.Sequential(nn.Linear(n_in, width), nn.Tanh(), nn.Linear(width, width))


def _padding(mask: torch.Tensor) -> torch.Tensor:
    """``key_padding_mask`` (True = ignore) of a token mask; a row with no real token attends to all
    (its output is then unused or meaningless, but finite, instead of NaN)."""
    pad = ~mask
    return pad & ~pad.all(dim=-1, keepdim=True)


class TokenCritic(nn.Module):
    """``forward(state (..., STATE_SIZE), obs (..., N, obs_dim)) -> value (..., N, 1)`` (see the
    module docstring); ``state_low``/``state_high`` and ``obs_low``/``obs_high`` are the env's
    ``state_space`` and observation space bounds."""

    def __init__(self, *, state_low: np.ndarray, state_high: np.ndarray, obs_low: np.ndarray, obs_high: np.ndarray,
                 embed: int, heads: int, hidden: tuple[int, ...]):
        super().__init__()
        robot_c, robot_w = _scale(state_low[:_RF - 1], state_high[:_RF - 1])
        kpoi_c, kpoi_w = _scale(state_low[_R:_R + _KF - 1], state_high[_R:_R + _KF - 1])
        glob_c, glob_w = _scale(state_low[_R + _K:], state_high[_R + _K:])
        obs_c, obs_w = _scale(obs_low, obs_high)
        for name, value in (("robot_c", robot_c), ("robot_w", robot_w), ("kpoi_c", kpoi_c), ("kpoi_w", kpoi_w),
                            ("glob_c", glob_c), ("glob_w", glob_w), ("obs_c", obs_c), ("obs_w", obs_w)):
            self.register_buffer(name, value, persistent=False)  # the env's bounds, not learned: not saved
        self.robot_embed = _embedder(_RF - 1, embed)
        self.kpoi_embed = _embedder(_KF - 1, embed)
        self.obs_embed = _embedder(len(obs_low), embed)
        self.robot_attn = nn.MultiheadAttention(embed, heads, batch_first=True)
        self.kpoi_attn = nn.MultiheadAttention(embed, heads, batch_first=True)
        self.norm1, self.norm2 = nn.LayerNorm(embed), nn.LayerNorm(embed)
        layers: list[nn.Module] = []
        last = 3 * embed + _GF
        for width in hidden:
            layers += [nn.Linear(last, width), nn.Tanh()]
            last = width
        layers.append(nn.Linear(last, 1))
        self.head = nn.Sequential(*layers)

    def forward(self, state: torch.Tensor, obs: torch.Tensor) -> torch.Tensor:
        lead, n = obs.shape[:-2], obs.shape[-2]
        state = state.reshape(-1, state.shape[-1])
        obs = obs.reshape(-1, n, obs.shape[-1])
        b = state.shape[0]
        robots = state[:, :_R].reshape(b, MAX_ROBOTS, _RF)[:, :n]  # robot i is row i: rows n.. are padding
        kpois = state[:, _R:_R + _K].reshape(b, MAX_KPOIS, _KF)
        robot_mask, kpoi_mask = robots[..., -1] > 0.5, kpois[..., -1] > 0.5
        r = self.robot_embed((robots[..., :-1] - self.robot_c) / self.robot_w)
        k = self.kpoi_embed((kpois[..., :-1] - self.kpoi_c) / self.kpoi_w)
        r = self.norm1(r + self.robot_attn(r, r, r, key_padding_mask=_padding(robot_mask), need_weights=False)[0])
        r = self.norm2(r + self.kpoi_attn(r, k, k, key_padding_mask=_padding(kpoi_mask), need_weights=False)[0])
        real = robot_mask.unsqueeze(-1).to(r.dtype)
        team = (r * real).sum(dim=1) / real.sum(dim=1).clamp(min=1.0)
        glob = (state[:, _R + _K:] - self.glob_c) / self.glob_w
        own = self.obs_embed((obs - self.obs_c) / self.obs_w)
        x = torch.cat([r, own, team.unsqueeze(1).expand(b, n, -1), glob.unsqueeze(1).expand(b, n, -1)], dim=-1)
        return self.head(x).reshape(*lead, n, 1)

"""An SB3 features extractor that hides chosen observation entries from the networks.

The observation holds world-frame entries (position ``x, y`` and heading ``cos_theta, sin_theta``)
that mean nothing on a map the policy has never seen; every control-relevant entry (route waypoint,
predecessor, sonar) is already in the robot frame. ``SelectEntries`` keeps only the listed entry
indices, so a policy trained across procedural maps cannot latch onto where a map put its rooms.
Saved with the model (``policy_kwargs``) and rebuilt by ``PPO.load``; needs the ``train`` extra.
"""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

__all__ = ["SelectEntries", "keep_indices"]


def keep_indices(names: Sequence[str], slices: dict[str, slice], drop: Sequence[str]) -> list[int]:
    """Indices of every observation entry except those of the named fields ``drop`` (ordered)."""
    unknown = sorted(set(drop) - set(names))
    if unknown:
        raise ValueError(f"unknown observation fields {unknown}; known: {', '.join(names)}")
    size = max(s.stop for s in slices.values())
    hidden = {i for name in drop for i in range(size)[slices[name]]}
    return [i for i in range(size) if i not in hidden]


class SelectEntries(BaseFeaturesExtractor):
    """Features = the observation entries ``keep`` (indices into the flat observation), in order."""

    def __init__(self, observation_space: gym.spaces.Box, keep: Sequence[int]):
        keep = [int(i) for i in keep]
        n = int(observation_space.shape[0])
        if not keep or len(set(keep)) != len(keep) or min(keep) < 0 or max(keep) >= n:
            raise ValueError(f"keep must be distinct indices in [0, {n}), got {keep}")
        super().__init__(observation_space, features_dim=len(keep))
        self.register_buffer("keep", torch.as_tensor(keep, dtype=torch.long), persistent=False)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return observations.index_select(-1, self.keep)

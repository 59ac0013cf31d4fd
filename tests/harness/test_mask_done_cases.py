"""``RobotsEnv``'s ``("robot", "real")`` with ``mask_done`` on hand-built infos: a map pool's padding
stays not real whatever its ``route_done``, and an env without ``route_done`` (version 1) masks nobody."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.harness.marl_env import RobotsEnv  # noqa: E402
from parcover_env.harness.marl_loss import GROUP  # noqa: E402


class Fake:
    """A ParallelEnv of three agents whose reset infos are given."""

    possible_agents = ["a", "b", "c"]

    def __init__(self, infos):
        self.infos = infos

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, seed=None, options=None):
        return {a: np.zeros(2, np.float32) for a in self.possible_agents}, self.infos


def _real(infos, mask_done=True):
    return RobotsEnv(Fake(infos), mask_done=mask_done).reset()[GROUP, "real"].flatten().tolist()


def test_padding_stays_not_real_and_a_done_route_is_masked():
    infos = {"a": {"pad": 1.0, "route_done": 0.0}, "b": {"pad": 0.0, "route_done": 1.0},
             "c": {"pad": 0.0, "route_done": 0.0}}
    assert _real(infos) == [False, False, True]
    assert _real(infos, mask_done=False) == [False, True, True]


def test_without_route_done_nobody_is_masked():
    assert _real({"a": {}, "b": {"pad": 1.0}, "c": {"pad": 0.0}}) == [True, False, True]

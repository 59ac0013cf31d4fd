"""The AEC view of a ParallelEnv (PettingZoo's ``parallel_to_aec``) whose ``step`` checks each agent's
action when it is given: a bad action is one ActionError and is not kept (PettingZoo's converter
buffers the actions until the last agent's turn, so a NaN given by the first agent failed only
then, and again at every later step, as it stayed in the buffer)."""

from __future__ import annotations

from typing import Any

from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from parcover_env.sim.act_phase import to_commands

__all__ = ["CheckedAEC", "aec_env"]


class CheckedAEC(parallel_to_aec_wrapper):
    """``parallel_to_aec_wrapper`` with each live agent's action checked before it is buffered."""

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            width = self.env.action_space(agent).shape[0]
            to_commands({agent: action}, [agent], 1.0, 1.0, width)  # ActionError naming the agent
        super().step(action)


def aec_env(parallel) -> OrderEnforcingWrapper:
    """The AEC env of ``parallel`` (as ``pettingzoo.utils.parallel_to_aec`` builds it, with
    :class:`CheckedAEC`)."""
    return OrderEnforcingWrapper(CheckedAEC(parallel))

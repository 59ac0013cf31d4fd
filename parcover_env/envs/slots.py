"""What a vectorized or single-agent view of the env adds to an agent's info: its episode's metrics
(:func:`with_metrics`) and, in a VecEnv's slot, ``active``, ``terminal_observation`` and
``TimeLimit.truncated`` (:func:`slot_info`)."""

from __future__ import annotations

import numpy as np

from parcover_env.mission.metrics import episode_metrics

__all__ = ["with_metrics", "slot_info"]


def with_metrics(info: dict) -> dict:
    """``info`` with the episode's metrics gathered into ``info["metrics"]`` (a dict) on the step that
    ends it (Gymnasium's and SB3's wrappers own ``info["episode"]``)."""
    metrics = episode_metrics(info)
    if metrics is not None:
        info["metrics"] = metrics
    return info


def slot_info(info: dict, obs: np.ndarray, terminated: bool, truncated: bool, ended: bool | None = None) -> dict:
    """An active agent slot's info in a VecEnv: :func:`with_metrics`, ``active``, and when its episode
    ``ended`` (default: terminated or truncated) its last observation (``terminal_observation``) and
    ``TimeLimit.truncated``."""
    info = with_metrics(info)
    info["active"] = True
    if terminated or truncated if ended is None else ended:
        info["terminal_observation"] = obs
        info["TimeLimit.truncated"] = truncated and not terminated
    return info

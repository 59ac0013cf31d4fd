"""Compatibility name of the episode metrics' public reader (``from parcover_env.envs.metrics import
episode_metrics``, as the README shows it); the metrics live in :mod:`parcover_env.mission.metrics`."""

from parcover_env.mission.metrics import episode_metrics

__all__ = ["episode_metrics"]

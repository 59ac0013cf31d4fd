"""``obs_scale: rollout``: the networks' input scale set from the observations of the first batch.

By default (``obs_scale: box``) the actor scales every observation entry by the env's observation
box to [-1, 1] (:func:`~parcover_env.policies.torchrl_policy.box_scale`). The box holds every value an
entry can take, which for some entries is far wider than the values it takes: on the generated maps'
pool (14 m x 14 m box) the route goal ``goal_dx`` / ``goal_dy`` (the pure-pursuit point 0.4 m ahead,
the steering signal of the ``waypoint`` policy) reaches the network with a standard deviation of
~0.01 against ~0.5 for most entries (measured in ``docs/lab/train_and_compare.md``, 2026-11-26).

With ``obs_scale: rollout`` the trainer's first batch (collected by the untrained actor) is used
only to set the scale of each entry to its mean and standard deviation over the real robots (the
mean/std standardization of PPO's observation normalization, fixed after the first batch so that
the inputs do not drift under the learning policy); that batch is not learned from. An entry that
does not vary in the batch keeps its box scale, and a spread below ``floor`` of the box half-width
is raised to it (an entry nearly constant early, e.g. the elapsed time, does not blow up later).
The scale is saved in ``policy.pt`` as the box scale is: evaluation needs nothing else.
"""

from __future__ import annotations

__all__ = ["FLOOR", "observation_stats", "fit_scale"]

FLOOR = 0.01
"""Smallest half-width a fitted entry gets, as a fraction of its box half-width."""


def observation_stats(obs, real=None):
    """Mean and standard deviation ``(D,)`` of the observations ``obs [..., D]`` over the entries whose
    ``real [..., 1]`` (bool, a map pool's padding excluded) is true; over all when ``real`` is None."""
    import torch

    flat = obs.reshape(-1, obs.shape[-1]).to(torch.float64)
    if real is not None:
        flat = flat[real.reshape(-1)]
    if flat.shape[0] == 0:
        raise ValueError("no real robot's observation to fit the scale to")
    mean = flat.mean(dim=0)
    return mean, (flat - mean).pow(2).mean(dim=0).sqrt()


def fit_scale(scale, obs, real=None, floor: float = FLOOR) -> None:
    """Set a :func:`~parcover_env.policies.torchrl_policy.box_scale` module's ``centre`` and
    ``half_width`` to the observations' mean and standard deviation (:func:`observation_stats`); an
    entry with zero spread keeps its box values, a spread below ``floor`` x the box half-width
    becomes that floor."""
    import torch

    mean, std = observation_stats(obs, real)
    box_c, box_hw = scale.centre.to(torch.float64), scale.half_width.to(torch.float64)
    varies = std > 0
    centre = torch.where(varies, mean, box_c)
    half = torch.where(varies, torch.maximum(std, floor * box_hw), box_hw)
    scale.centre.copy_(centre.to(scale.centre.dtype))
    scale.half_width.copy_(half.to(scale.half_width.dtype))

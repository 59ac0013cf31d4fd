"""The PPO loss of ``parcover train`` (TorchRL's ``IPPOLoss`` / ``MAPPOLoss``) with a map pool's
padding agents left out of everything it learns from.

A map pool pads each map's robots to ``max_robots`` agents (:mod:`~parcover_env.harness.map_pool`);
the padding's observations are zeros and its rewards 0, so on a pool of 3-12 robots about half the
agent slots of a batch are padding. TorchRL's loss would average its objective, critic and entropy
terms over them, standardize every agent slot's advantages separately (turning the padding's
near-zero advantages into unit-variance noise) and feed their value targets to the value
normalizer. Here the ``(robot, "real")`` entry (:class:`~parcover_env.harness.marl_env.RobotsEnv`)
masks the loss terms (TorchRL's ``loss_mask_key``), :func:`standardize_advantage` standardizes the
advantages over the real robots of a minibatch, and the value normalizer is updated from the real
robots' targets only (:func:`prepare_minibatch`). With every agent real (a single scenario) this is
PPO's usual per-minibatch advantage normalization over all robots together.

torch and torchrl are imported inside the functions.
"""

from __future__ import annotations

from parcover_env.harness.marl_config import MarlConfig

__all__ = ["GROUP", "REAL", "build_loss", "standardize_advantage", "prepare_minibatch"]

GROUP = "robot"
"""TorchRL's group of the robots (``robot_0``, ``robot_1``, ... share the prefix)."""
REAL = (GROUP, "real")
"""``[..., robots, 1]`` bool: a map's robot, not a map pool's padding (:mod:`~parcover_env.harness.marl_env`)."""


def _real_robots_only(base):
    """A subclass of the TorchRL value normalizer ``base`` whose statistics ignore the loss's own
    ``update`` call and move through ``update_real(value_target, real)`` instead."""

    class RealRobotsNorm(base):
        def update(self, value_target) -> None:
            """Nothing: :func:`prepare_minibatch` updates the statistics from the real robots."""

        def update_real(self, value_target, real) -> None:
            """``base.update`` with the entries of ``value_target`` where ``real`` (broadcast) is true."""
            if real is not None:
                value_target = value_target[real.expand_as(value_target)].reshape(-1, *value_target.shape[-1:])
            base.update(self, value_target)

    RealRobotsNorm.__name__ = RealRobotsNorm.__qualname__ = f"RealRobots{base.__name__}"
    return RealRobotsNorm


def build_loss(algo: str, cfg: MarlConfig, actor, critic):
    """``IPPOLoss`` or ``MAPPOLoss`` with the group's keys, the configured value normalization and
    ``MultiAgentGAE(gamma, lmbda)`` as its value estimator. Its ``loss_mask_key`` is :data:`REAL`:
    the objective, critic and entropy terms are means over the real robots of a minibatch (all
    agents when the batch has no such entry); its own advantage normalization is off
    (:func:`standardize_advantage` replaces it), and its value normalizer's statistics move only
    through :func:`prepare_minibatch` (the real robots' value targets)."""
    from torchrl.modules import PopArtValueNorm, RunningValueNorm
    from torchrl.objectives import ValueEstimators
    from torchrl.objectives.multiagent import IPPOLoss, MAPPOLoss

    norm = {"popart": PopArtValueNorm, "running": RunningValueNorm}.get(cfg.value_norm)
    norm = _real_robots_only(norm) if norm else None
    cls = MAPPOLoss if algo == "mappo" else IPPOLoss
    loss = cls(actor, critic, value_norm=norm(shape=1) if norm else None, clip_epsilon=cfg.clip_epsilon,
               entropy_coeff=cfg.entropy_coeff, critic_coeff=cfg.critic_coeff,
               normalize_advantage=False)  # standardize_advantage does it, over the real robots only
    loss.loss_mask_key = REAL  # a map pool's padding agents add nothing to the loss terms
    # the action and log-prob keys are the actor's ((GROUP, "action"), (GROUP, "action_log_prob")):
    # ClipPPOLoss takes them from it
    loss.set_keys(reward=(GROUP, "reward"), value=(GROUP, "state_value"), done=(GROUP, "done"),
                  terminated=(GROUP, "terminated"), advantage=(GROUP, "advantage"),
                  value_target=(GROUP, "value_target"))
    loss.make_value_estimator(ValueEstimators.MAGAE, gamma=cfg.gamma, lmbda=cfg.gae_lambda)
    return loss


def standardize_advantage(td, enabled: bool = True):
    """``td`` with its ``(robot, "advantage")`` standardized over the real robots of every step
    (mean 0, standard deviation 1 over the entries where :data:`REAL` is true, or over all entries
    without it) and set to 0 on padding agents; unchanged when not ``enabled``. PPO's per-minibatch
    normalization, with padding left out of the statistics."""
    import torch

    if not enabled:
        return td
    adv = td.get((GROUP, "advantage"))
    real = td.get(REAL)
    real = torch.ones_like(adv, dtype=torch.bool) if real is None else real.reshape(adv.shape)
    n = real.sum().clamp_min(1)
    mean = torch.where(real, adv, 0.0).sum() / n
    std = (torch.where(real, adv - mean, 0.0).pow(2).sum() / n).sqrt().clamp_min(1e-4)
    td.set((GROUP, "advantage"), torch.where(real, (adv - mean) / std, 0.0))
    return td


def prepare_minibatch(loss, td, normalize_advantage: bool):
    """``td`` (a sampled minibatch with advantages and value targets) made ready for ``loss``: the
    value normalizer (if any) updated from the real robots' value targets, then the advantages
    standardized (:func:`standardize_advantage`, when ``normalize_advantage``)."""
    if loss.value_norm is not None:
        loss.value_norm.update_real(td.get((GROUP, "value_target")), td.get(REAL))
    return standardize_advantage(td, normalize_advantage)

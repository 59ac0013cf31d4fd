"""The ``bernoulli`` scan head: a Bernoulli "scan now" beside the TanhNormal ``(v, omega)`` of a TorchRL actor.

With the env's scan service (``observation.scan.enabled``) the action is ``(v, omega, scan)`` and the
env starts a scan when ``scan > 0``. A TanhNormal over all three components makes ``scan`` a
thresholded continuous output whose deterministic value ``tanh(loc)`` need not ever cross 0 even when
the sampled actor scans often (its trigger then lives in the noise). Here the actor's network has
``2 * 2 + 1`` outputs (:func:`~parcover_env.policies.torchrl_policy.head_outputs`): ``loc`` and the
pre-softplus scale of the drive ``(v, omega)`` and one scan logit ``l``; the distribution
(:class:`TanhNormalScan`) is the product of

- ``TanhNormal(loc, scale)`` on ``[-1, 1]^2`` for ``(v, omega)`` (TorchRL's, as the ``continuous``
  head has for every component), and
- ``Bernoulli(p = sigmoid(l))`` for "scan now",

one action tensor ``[..., 3]`` whose last component is :data:`SCAN_ON` (+1) for a sampled 1 and
:data:`SCAN_OFF` (-1) for a 0: the env's action box and ``scan > 0`` rule are unchanged, and the
trainer's keys (``action``, ``action_log_prob``) are those of the ``continuous`` head, so TorchRL's
PPO losses, collectors (local and Ray) and the map pool take it as they are. The heads are independent
given the observation:

- ``log_prob(a) = log TanhNormal(a_v, a_omega) + log Bernoulli(a_scan > 0)``;
- ``entropy() = H(drive) + H(Bernoulli)``, ``H(Bernoulli) = -p log p - (1 - p) log(1 - p)`` exactly;
  the TanhNormal has no closed-form entropy, so ``H(drive)`` is the one-sample estimate
  ``-log TanhNormal(x)``, ``x`` a reparameterized sample, which is what TorchRL's ``ClipPPOLoss``
  uses for the ``continuous`` head (``samples_mc_entropy=1``);
- the deterministic sample (evaluation, ``torchrl:``) is each head's: ``tanh(loc)`` and the
  Bernoulli's mode, scan iff ``p > 0.5`` (``l > 0``), so a learned scan trigger survives evaluation.

Public API: :class:`TanhNormalScan`, :class:`ScanParamExtractor`, :func:`scan_actor` (a TorchRL
``ProbabilisticActor`` around an :func:`~parcover_env.policies.torchrl_policy.actor_net`),
:func:`actor_head` (which head an actor has) and :func:`grown_scan_logit` (a new scan head's start,
:mod:`~parcover_env.harness.marl_grow`). torch and torchrl are imported at module level: import this
module lazily.
"""

from __future__ import annotations

import torch
from torch import distributions as D
from torch import nn

from parcover_env.harness.marl_loss import GROUP
from parcover_env.policies.torchrl_policy import SCAN_OFF, SCAN_ON

__all__ = ["TanhNormalScan", "ScanParamExtractor", "scan_actor", "actor_head", "grown_scan_logit",
           "SCAN_ON", "SCAN_OFF"]


class TanhNormalScan(D.Distribution):
    """``(v, omega) ~ TanhNormal(loc, scale)`` on ``[-1, 1]`` and ``scan ~ Bernoulli(sigmoid(scan_logit))``
    as one action ``[..., D + 1]`` (``D = loc.shape[-1]``), the scan mapped to ``SCAN_ON`` / ``SCAN_OFF``.
    ``loc``, ``scale``: ``[..., D]``; ``scan_logit``: ``[..., 1]``. Batch shape ``loc.shape[:-1]``; the
    log-probability and entropy have that shape (the module docstring gives both)."""

    arg_constraints: dict = {}
    has_rsample = False  # the scan is discrete: samples come from :meth:`sample`
    support = D.constraints.real

    def __init__(self, loc: torch.Tensor, scale: torch.Tensor, scan_logit: torch.Tensor):
        from torchrl.modules import TanhNormal

        if loc.ndim < 1 or scan_logit.shape != (*loc.shape[:-1], 1):
            raise ValueError(f"scan_logit of shape {tuple(scan_logit.shape)} does not fit loc of shape "
                             f"{tuple(loc.shape)}: expected {(*loc.shape[:-1], 1)}")
        self.drive = TanhNormal(loc, scale)  # on [-1, 1], the env's box; the log-prob sums the last dimension
        """The TanhNormal of the drive components."""
        self.scan = D.Bernoulli(logits=scan_logit[..., 0])
        """The Bernoulli of "scan now" (batch shape ``loc.shape[:-1]``)."""
        super().__init__(batch_shape=loc.shape[:-1], event_shape=torch.Size([loc.shape[-1] + 1]))

    @property
    def scan_probability(self) -> torch.Tensor:
        """``sigmoid(scan_logit)``: the probability of "scan now", ``[...]``."""
        return self.scan.probs

    @staticmethod
    def _to_action(bit: torch.Tensor) -> torch.Tensor:
        return torch.where(bit > 0.5, SCAN_ON, SCAN_OFF).to(bit.dtype).unsqueeze(-1)

    def sample(self, sample_shape: torch.Size | tuple = ()) -> torch.Tensor:
        """Drive from the TanhNormal, then the scan from the Bernoulli (torch's generator, in that order)."""
        with torch.no_grad():
            drive = self.drive.sample(torch.Size(sample_shape))
            bit = self.scan.sample(torch.Size(sample_shape))
        return torch.cat([drive, self._to_action(bit).to(drive.dtype)], dim=-1)

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        """``log TanhNormal(value[..., :-1]) + log Bernoulli(value[..., -1] > 0)``."""
        bit = (value[..., -1] > 0).to(self.scan.logits.dtype)
        return self.drive.log_prob(value[..., :-1]) + self.scan.log_prob(bit)

    def entropy(self) -> torch.Tensor:
        """The drive's one-sample entropy estimate plus the Bernoulli's exact entropy."""
        return -self.drive.log_prob(self.drive.rsample()) + self.scan.entropy()

    @property
    def deterministic_sample(self) -> torch.Tensor:
        """``tanh(loc)`` (the TanhNormal's, as TorchRL gives it) and the Bernoulli's mode (scan iff ``p > 0.5``)."""
        drive = self.drive.deterministic_sample
        bit = (self.scan.logits > 0).to(drive.dtype)
        return torch.cat([drive, self._to_action(bit)], dim=-1)


class ScanParamExtractor(nn.Module):
    """``[..., 2 D + 1]`` network outputs -> ``(loc [..., D], scale [..., D], scan_logit [..., 1])``: the
    first ``2 D`` through TorchRL's ``NormalParamExtractor`` (the ``continuous`` head's scale mapping,
    :func:`~parcover_env.policies.torchrl_policy.actor_scale`), the last one as the logit."""

    def __init__(self):
        super().__init__()
        from tensordict.nn import NormalParamExtractor

        self.normal = NormalParamExtractor()

    def forward(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        loc, scale = self.normal(out[..., :-1])
        return loc, scale, out[..., -1:]


def scan_actor(net: nn.Module, group: str = GROUP):
    """The stochastic actor of the ``bernoulli`` head: ``net`` (an ``actor_net`` with
    ``scan_head="bernoulli"``) reads ``(group, "observation")``, :class:`ScanParamExtractor` writes
    ``(group, "loc" | "scale" | "scan_logit")``, and a ``ProbabilisticActor`` of :class:`TanhNormalScan`
    writes ``(group, "action")`` and its ``(group, "action_log_prob")``."""
    from tensordict.nn import TensorDictModule
    from torchrl.modules import ProbabilisticActor

    keys = {"loc": (group, "loc"), "scale": (group, "scale"), "scan_logit": (group, "scan_logit")}
    module = TensorDictModule(nn.Sequential(net, ScanParamExtractor()), in_keys=[(group, "observation")],
                              out_keys=list(keys.values()))
    return ProbabilisticActor(module, in_keys=keys, out_keys=[(group, "action")], distribution_class=TanhNormalScan,
                              return_log_prob=True)


def actor_head(actor) -> str:
    """``"bernoulli"`` for an actor of :func:`scan_actor`, else ``"continuous"`` (the trainer's TanhNormal actor)."""
    return "bernoulli" if isinstance(actor.module[0].module[-1], ScanParamExtractor) else "continuous"


def grown_scan_logit(loc: float, std: float) -> float:
    """The scan logit (zero weights, this bias) that a grown ``bernoulli`` head starts with, from the
    ``init_grow_loc`` / ``init_grow_std`` a grown ``continuous`` scan starts with: the same probability
    of a sampled scan per step, ``P(N(loc, std) > 0) = Phi(loc / std)``, so the same deterministic
    decision (scan iff ``loc > 0``). ``loc=-1.5, std=0.5``: ``Phi(-3) = 0.00135``, logit -6.61."""
    x = torch.tensor(loc / std, dtype=torch.float64)
    return float(torch.special.log_ndtr(x) - torch.special.log_ndtr(-x))  # log p - log(1 - p), stable in the tails

"""A robot policy trained by ``parcover train`` (TorchRL IPPO/MAPPO), loaded with torch alone.

The checkpoint ``policy.pt`` is a dict: ``state_dict`` of :func:`actor_net` (the weights and the
observation box it scales by), ``obs_dim``, ``hidden``, ``act_dim`` (the env's action size) and
``scan_head`` (:data:`SCAN_HEADS`; a file without it has the ``continuous`` head). Every robot runs
the same network on its own observation (parameter sharing).

``continuous`` head: the network outputs the location and the pre-softplus scale of a TanhNormal
over every action component (TorchRL's ``NormalParamExtractor`` splits them). Acting takes the
distribution's deterministic sample ``tanh(loc)`` (spec ``torchrl:DIR``), or, with a ``sample_seed``
(spec ``torchrl_sampled:DIR``), a sample ``tanh(loc + scale * eps)`` as in training, ``eps`` standard
normal from a numpy Generator seeded with the episode's seed (bit-identical per seed, also after a
``deepcopy`` mid-episode). Both lie in the action box [-1, 1]. A policy whose ``scan`` component starts a
scan when it is above 0 scans, deterministically, only where ``loc > 0``; sampled, it also scans now
and then elsewhere, as it did in training.

``bernoulli`` head (an env with the scan service, ``MarlConfig.scan_head``): the TanhNormal covers
``(v, omega)`` only (outputs ``loc_v, loc_omega, pre_v, pre_omega``) and a fifth output is the logit
of a Bernoulli "scan now" (:mod:`~parcover_env.harness.marl_scan_head`). The ``scan`` component is
:data:`SCAN_ON` (+1: the env scans) or :data:`SCAN_OFF` (-1: it does not). Deterministic: the mode,
scan iff the logit is above 0 (probability above 0.5); sampled: ``(v, omega)`` as above, then one
uniform ``u`` per robot from the same Generator, scan iff ``u < sigmoid(logit)``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from parcover_env.errors import CheckpointError, ParcoverError
from parcover_env.policies.checkpoint_files import as_int, as_widths, build_or_explain, load_torch_dict
from parcover_env.policies.protocol import Policy

__all__ = ["actor_net", "box_scale", "TorchRLPolicy", "POLICY_FILE", "SIDECAR_FILE", "checkpoint_overrides",
           "SCALE_MIN", "actor_scale", "SCAN_HEADS", "SCAN_ON", "SCAN_OFF", "head_outputs", "head_act_dim"]

POLICY_FILE = "policy.pt"
"""The checkpoint's name in a ``parcover train`` output directory."""
SIDECAR_FILE = "run.json"
SCAN_HEADS = ("continuous", "bernoulli")
"""How an actor outputs the ``scan`` action component: ``continuous`` (one more TanhNormal component,
also the head of every action without ``scan``) or ``bernoulli`` (a separate Bernoulli "scan now")."""
SCAN_ON, SCAN_OFF = 1.0, -1.0
"""The ``scan`` component a ``bernoulli`` head gives the env for "scan" / "no scan" (the env scans when ``> 0``)."""
"""The run's sidecar beside the checkpoint (``parcover train``); its ``env_overrides`` are the
scenario overrides the policy was trained with (e.g. ``observation.version: 2``)."""


def checkpoint_overrides(path: str | Path) -> dict | None:
    """The env overrides of the checkpoint at ``path`` (``DIR`` or ``DIR/policy.pt``): the sidecar's
    ``env_overrides``, None when there is no sidecar or it has none (a run without overrides).
    ParcoverError if the sidecar is not a JSON object or its ``env_overrides`` is not a mapping."""
    import json

    path = Path(path)
    sidecar = (path if path.is_dir() else path.parent) / SIDECAR_FILE
    if not sidecar.is_file():
        return None
    try:
        data = json.loads(sidecar.read_text())
    except (OSError, ValueError) as exc:
        raise ParcoverError(f"cannot read the sidecar {sidecar}: {exc}") from None
    overrides = data.get("env_overrides") if isinstance(data, dict) else None
    if overrides is not None and not isinstance(overrides, dict):
        raise ParcoverError(f"{sidecar}: env_overrides must be a mapping, got {type(overrides).__name__}")
    return overrides or None


def box_scale(obs_low: np.ndarray, obs_high: np.ndarray):
    """``x -> (x - centre) / half_width``, a fixed affine map saved with the weights (buffers
    ``centre`` and ``half_width``), set to the centre and half-width of the box ``[obs_low,
    obs_high]`` (half-widths floored at 1e-6). ``parcover train`` with ``obs_scale: rollout`` later
    sets them to the mean and spread of the observations (:mod:`parcover_env.harness.marl_scale`)."""
    import torch
    from torch import nn

    class BoxScale(nn.Module):
        def __init__(self, low: np.ndarray, high: np.ndarray):
            super().__init__()
            low_t, high_t = torch.as_tensor(low, dtype=torch.float32), torch.as_tensor(high, dtype=torch.float32)
            self.register_buffer("centre", (low_t + high_t) / 2)
            self.register_buffer("half_width", torch.clamp((high_t - low_t) / 2, min=1e-6))

        def forward(self, x):
            return (x - self.centre) / self.half_width

    return BoxScale(obs_low, obs_high)


def head_outputs(act_dim: int, scan_head: str = "continuous") -> int:
    """The network outputs of an actor with ``act_dim`` action components and ``scan_head``:
    ``2 * act_dim`` (loc and pre-scale of each), or for ``bernoulli`` ``2 * (act_dim - 1) + 1`` (loc
    and pre-scale of each drive component, then the scan logit). ValueError for an unknown head, or a
    ``bernoulli`` head without a scan component beside a drive (``act_dim < 2``)."""
    if scan_head == "continuous":
        return 2 * act_dim
    if scan_head == "bernoulli" and act_dim >= 2:
        return 2 * (act_dim - 1) + 1
    raise ValueError(f"scan head {scan_head!r} with {act_dim} action components: expected one of {SCAN_HEADS}, "
                     "bernoulli with at least one drive component and the scan component")


def head_act_dim(outputs: int, scan_head: str = "continuous") -> int:
    """The action components of an actor with ``outputs`` network outputs (inverse of :func:`head_outputs`);
    ValueError if no actor of ``scan_head`` has that many."""
    act_dim = (outputs + 1) // 2
    if head_outputs(act_dim, scan_head) != outputs:
        raise ValueError(f"no actor with the {scan_head} scan head has {outputs} outputs")
    return act_dim


def actor_net(obs_low: np.ndarray, obs_high: np.ndarray, hidden: tuple[int, ...], act_dim: int,
              scan_head: str = "continuous"):
    """``obs -> distribution parameters`` per robot: the observation scaled by :func:`box_scale` (to
    [-1, 1] for the box ``[obs_low, obs_high]``), then a tanh MLP with :func:`head_outputs` outputs
    (``2 * act_dim`` (loc, pre-scale) for the ``continuous`` head). Works on any leading dimensions
    (time, robots)."""
    from torch import nn

    outputs = head_outputs(act_dim, scan_head)

    layers: list[nn.Module] = [box_scale(obs_low, obs_high)]
    last = len(obs_low)
    for width in hidden:
        layers += [nn.Linear(last, width), nn.Tanh()]
        last = width
    layers.append(nn.Linear(last, outputs))
    return nn.Sequential(*layers)


def _linear(net) -> list:
    """The ``Linear`` layers of an :func:`actor_net`, in order."""
    import torch

    return [m for m in net.modules() if isinstance(m, torch.nn.Linear)]


SCALE_MIN = 0.01
"""Smallest scale of the actor's TanhNormal (TorchRL's ``NormalParamExtractor``: ``biased_softplus(1.0)``)."""


def actor_scale(pre):
    """The TanhNormal scale of the actor's pre-softplus outputs ``pre`` (a torch tensor), as TorchRL's
    ``NormalParamExtractor`` maps them: ``softplus(pre + b) + SCALE_MIN``, ``b`` such that 0 maps to 1."""
    import torch

    return torch.nn.functional.softplus(pre + math.log(math.expm1(1.0 - SCALE_MIN))) + SCALE_MIN


class TorchRLPolicy(Policy):
    """The actor of a ``parcover train`` run: ``torchrl:DIR`` or ``torchrl:DIR/policy.pt``
    (deterministic), ``torchrl_sampled:...`` (``sample_seed``: actions sampled, see the module docstring)."""

    def __init__(self, path: str | Path, sample_seed: int | None = None):

        path = Path(path)
        file = path / POLICY_FILE if path.is_dir() else path
        if not file.is_file():
            raise ParcoverError(f"TorchRL policy checkpoint not found: {file}")
        what = "TorchRL policy"
        ckpt = load_torch_dict(file, what, ("obs_dim", "act_dim", "hidden", "state_dict"), weights_only=True)
        n, act_dim = as_int(ckpt["obs_dim"], file, what, "obs_dim"), as_int(ckpt["act_dim"], file, what, "act_dim")
        hidden = as_widths(ckpt["hidden"], file, what)
        head = ckpt.get("scan_head", "continuous")
        try:
            head_outputs(act_dim, head)
        except ValueError as exc:
            raise CheckpointError(file, what, f"ValueError: {exc}") from None

        def build():  # the box's centre and half-width come with the state dict
            net = actor_net(np.zeros(n), np.ones(n), hidden, act_dim, head)
            net.load_state_dict(ckpt["state_dict"])
            return net

        self._set(build_or_explain(file, what, build), act_dim, head, sample_seed)

    def _set(self, net, act_dim: int, scan_head: str, sample_seed: int | None) -> None:
        self.net = net
        self.net.eval()
        self.act_dim = act_dim
        self.scan_head: str = scan_head
        """:data:`SCAN_HEADS`: how the network outputs the ``scan`` component."""
        self.drive_dim = act_dim - 1 if scan_head == "bernoulli" else act_dim
        """Action components of the TanhNormal (all of them for the ``continuous`` head)."""
        self.obs_shape = (_linear(net)[0].in_features,)
        self.rng = None if sample_seed is None else np.random.default_rng(sample_seed)
        """The sampling noise's generator; None: deterministic (``tanh(loc)``, the scan head's mode)."""

    @classmethod
    def from_net(cls, net, act_dim: int, scan_head: str = "continuous",
                 sample_seed: int | None = None) -> TorchRLPolicy:
        """The policy of an in-memory :func:`actor_net` (e.g. a trainer's, before it is saved);
        ParcoverError if its outputs do not fit ``act_dim`` and ``scan_head``."""
        try:
            outputs = head_outputs(act_dim, scan_head)
        except ValueError as exc:
            raise ParcoverError(str(exc)) from None
        if outputs != _linear(net)[-1].out_features:
            raise ParcoverError(f"an actor_net with {act_dim} action components and the {scan_head} scan head has "
                                f"{outputs} outputs, not {_linear(net)[-1].out_features}")
        policy = cls.__new__(cls)
        cls._set(policy, net, act_dim, scan_head, sample_seed)  # the class's own setter, as __init__ uses it
        return policy

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        import torch

        agents = sorted(observations)
        if not agents:
            return {}
        obs = torch.as_tensor(np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents]))
        d = self.drive_dim
        with torch.no_grad():
            out = self.net(obs)
            loc = out[:, :d]
            if self.rng is None:
                actions = torch.tanh(loc).numpy().astype(np.float32)
            else:
                scale = actor_scale(out[:, d:2 * d]).double().numpy()
                u = loc.double().numpy() + scale * self.rng.standard_normal(scale.shape)
                actions = np.tanh(u).astype(np.float32)
            if self.scan_head == "bernoulli":
                logit = out[:, 2 * d].double().numpy()
                if self.rng is None:  # the mode: probability above 0.5
                    scan = logit > 0.0
                else:  # u < sigmoid(logit), written without overflow
                    scan = self.rng.random(len(agents)) < np.exp(-np.logaddexp(0.0, -logit))
                scan = np.where(scan, SCAN_ON, SCAN_OFF).astype(np.float32)
                actions = np.concatenate([actions, scan[:, None]], axis=1)
        return {a: actions[i] for i, a in enumerate(agents)}

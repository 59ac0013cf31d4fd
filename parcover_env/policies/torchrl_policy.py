"""A robot policy trained by ``parcover train`` (TorchRL IPPO/MAPPO), loaded with torch alone.

The checkpoint ``policy.pt`` is a dict: ``state_dict`` of :func:`actor_net` (the weights and the
observation box it scales by), ``obs_dim``, ``hidden`` and ``act_dim``. Every robot runs the same network on its
own observation (parameter sharing). The network outputs the location and the pre-softplus scale of
a TanhNormal distribution (TorchRL's ``NormalParamExtractor`` splits them). Acting takes the
distribution's deterministic sample ``tanh(loc)`` (spec ``torchrl:DIR``), or, with a ``sample_seed``
(spec ``torchrl_sampled:DIR``), a sample ``tanh(loc + scale * eps)`` as in training, ``eps`` standard
normal from a numpy Generator seeded with the episode's seed (bit-identical per seed, also after a
``deepcopy`` mid-episode). Both lie in the action box [-1, 1]. A policy whose ``scan`` component starts a
scan when it is above 0 scans, deterministically, only where ``loc > 0``; sampled, it also scans now
and then elsewhere, as it did in training.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from parcover_env.errors import ParcoverError
from parcover_env.policies.checkpoint_files import as_int, as_widths, build_or_explain, load_torch_dict
from parcover_env.policies.protocol import Policy

__all__ = ["actor_net", "box_scale", "TorchRLPolicy", "POLICY_FILE", "SIDECAR_FILE", "checkpoint_overrides",
           "SCALE_MIN", "actor_scale"]

POLICY_FILE = "policy.pt"
"""The checkpoint's name in a ``parcover train`` output directory."""
SIDECAR_FILE = "run.json"
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


def actor_net(obs_low: np.ndarray, obs_high: np.ndarray, hidden: tuple[int, ...], act_dim: int):
    """``obs -> (loc, scale parameter)`` per robot: the observation scaled by :func:`box_scale` (to
    [-1, 1] for the box ``[obs_low, obs_high]``), then a tanh MLP with ``2 * act_dim`` outputs. Works on
    any leading dimensions (time, robots)."""
    from torch import nn

    layers: list[nn.Module] = [box_scale(obs_low, obs_high)]
    last = len(obs_low)
    for width in hidden:
        layers += [nn.Linear(last, width), nn.Tanh()]
        last = width
    layers.append(nn.Linear(last, 2 * act_dim))
    return nn.Sequential(*layers)


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

        def build():  # the box's centre and half-width come with the state dict
            net = actor_net(np.zeros(n), np.ones(n), hidden, act_dim)
            net.load_state_dict(ckpt["state_dict"])
            return net

        self.net = build_or_explain(file, what, build)
        self.net.eval()
        self.act_dim = act_dim
        self.obs_shape = (n,)
        self.rng = None if sample_seed is None else np.random.default_rng(sample_seed)
        """The sampling noise's generator; None: deterministic ``tanh(loc)``."""

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        import torch

        agents = sorted(observations)
        if not agents:
            return {}
        obs = torch.as_tensor(np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents]))
        with torch.no_grad():
            out = self.net(obs)
            loc = out[:, : self.act_dim]
            if self.rng is None:
                actions = torch.tanh(loc).numpy().astype(np.float32)
            else:
                scale = actor_scale(out[:, self.act_dim:]).double().numpy()
                u = loc.double().numpy() + scale * self.rng.standard_normal(scale.shape)
                actions = np.tanh(u).astype(np.float32)
        return {a: actions[i] for i, a in enumerate(agents)}

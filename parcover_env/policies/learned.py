"""Learned policies (PPO, behaviour cloning) as ``act(observations) -> actions`` objects.

Both act per agent from one agent's observation vector (parameter sharing), exactly what the SB3
adapter (``parcover_env.envs.vec_env``) trains on. torch and SB3 are imported lazily.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from parcover_env.errors import CheckpointError, ParcoverError
from parcover_env.policies.checkpoint_files import as_int, as_widths, build_or_explain, first_line, load_torch_dict
from parcover_env.policies.protocol import Policy

__all__ = ["PPOPolicy", "BCPolicy", "ObsNormalizer", "vecnormalize_file"]


class ObsNormalizer:
    """``clip((obs - mean) / sqrt(var + eps), -clip, clip)``: SB3 VecNormalize's observation transform."""

    def __init__(self, mean: np.ndarray, var: np.ndarray, clip: float = 10.0, eps: float = 1e-8):
        self.mean = np.asarray(mean, dtype=np.float32)
        self.std = np.sqrt(np.asarray(var, dtype=np.float64) + eps).astype(np.float32)
        self.clip = float(clip)

    @classmethod
    def from_vecnormalize(cls, path: str | Path) -> ObsNormalizer:
        """Read the statistics saved by ``VecNormalize.save`` (no env needed)."""
        try:
            with open(path, "rb") as fh:
                vn = pickle.load(fh)
            return cls(vn.obs_rms.mean, vn.obs_rms.var, vn.clip_obs, vn.epsilon)
        except Exception as exc:  # a corrupt or foreign file (unpickling may raise anything): name it
            raise CheckpointError(path, "VecNormalize statistics", f"not a saved VecNormalize "
                                  f"({first_line(exc)})") from None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.clip((obs - self.mean) / self.std, -self.clip, self.clip).astype(np.float32)


def _stack(observations: dict[str, np.ndarray]) -> tuple[list[str], np.ndarray]:
    agents = sorted(observations)
    if not agents:
        return agents, np.empty((0, 0), dtype=np.float32)
    return agents, np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents])


def vecnormalize_file(model_file: Path) -> Path | None:
    """The observation statistics of a saved model: ``<stem>_vecnormalize.pkl`` beside it (shipped
    checkpoints, ``checkpoints/step_N.zip``), else ``vecnormalize.pkl`` in its directory, else None."""
    for cand in (model_file.with_name(model_file.stem + "_vecnormalize.pkl"), model_file.with_name("vecnormalize.pkl")):
        if cand.is_file():
            return cand
    return None


class PPOPolicy(Policy):
    """A saved SB3 PPO model (``model.zip`` + ``vecnormalize.pkl``, or ``NAME.zip`` +
    ``NAME_vecnormalize.pkl``, see :func:`vecnormalize_file`)."""

    def __init__(self, path: str | Path, deterministic: bool = True):
        from stable_baselines3 import PPO

        path = Path(path)
        model_file = path / "model.zip" if path.is_dir() else path
        if not model_file.is_file():
            raise ParcoverError(f"PPO checkpoint not found: {model_file}")
        try:
            self.model = PPO.load(str(model_file), device="cpu")
        except Exception as exc:  # a corrupt or foreign file: name it instead of a deep traceback
            problem = f"not an SB3 PPO model.zip ({first_line(exc)})"
            raise CheckpointError(model_file, "PPO checkpoint", problem) from None
        stats = vecnormalize_file(model_file)
        self.normalize = ObsNormalizer.from_vecnormalize(stats) if stats is not None else None
        self.deterministic = deterministic
        self.obs_shape = tuple(self.model.observation_space.shape)

    @classmethod
    def from_model(cls, model, normalize: ObsNormalizer | None, deterministic: bool = True) -> PPOPolicy:
        """A PPO model held in memory (e.g. one in training) with its observation statistics."""
        self = cls.__new__(cls)
        self.model, self.normalize, self.deterministic = model, normalize, deterministic
        self.obs_shape = tuple(model.observation_space.shape)
        return self

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        agents, obs = _stack(observations)
        if not agents:
            return {}
        if self.normalize is not None:
            obs = self.normalize(obs)
        actions, _ = self.model.predict(obs, deterministic=self.deterministic)
        actions = np.clip(actions, -1.0, 1.0).astype(np.float32)
        return {a: actions[i] for i, a in enumerate(agents)}


def make_mlp(n_in: int, n_out: int, hidden: tuple[int, ...] = (256, 256)):
    """The BC network: MLP with tanh output in [-1, 1] (the action box)."""
    import torch.nn as nn

    layers, last = [], n_in
    for h in hidden:
        layers += [nn.Linear(last, h), nn.ReLU()]
        last = h
    layers += [nn.Linear(last, n_out), nn.Tanh()]
    return nn.Sequential(*layers)


class BCPolicy(Policy):
    """A behaviour-cloned tanh-output MLP actor (``bc.pt``: ``n_in``, ``n_out``, ``hidden``,
    ``state_dict``, ``obs_mean``, ``obs_std``; written by ``docs/lab/scripts/train_bc.py``)."""

    def __init__(self, path: str | Path):

        path = Path(path)
        file = path / "bc.pt" if path.is_dir() else path
        if not file.is_file():
            raise ParcoverError(f"BC checkpoint not found: {file}")
        what = "BC actor"
        ckpt = load_torch_dict(file, what, ("n_in", "n_out", "hidden", "state_dict", "obs_mean", "obs_std"),
                               weights_only=False)
        n_in, n_out = as_int(ckpt["n_in"], file, what, "n_in"), as_int(ckpt["n_out"], file, what, "n_out")
        hidden = as_widths(ckpt["hidden"], file, what)

        def build():
            net = make_mlp(n_in, n_out, hidden)
            net.load_state_dict(ckpt["state_dict"])
            std = np.asarray(ckpt["obs_std"], dtype=np.float64)
            normalize = ObsNormalizer(ckpt["obs_mean"], std**2, clip=10.0, eps=0.0)
            if normalize.mean.shape != (n_in,) or normalize.std.shape != (n_in,):
                raise ValueError(f"obs_mean / obs_std have shapes {normalize.mean.shape} / {normalize.std.shape}, "
                                 f"n_in is {n_in}")
            return net, normalize

        self.net, self.normalize = build_or_explain(file, what, build)
        self.net.eval()
        self.obs_shape = (n_in,)

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        import torch

        agents, obs = _stack(observations)
        if not agents:
            return {}
        with torch.no_grad():
            actions = self.net(torch.as_tensor(self.normalize(obs))).numpy()
        return {a: actions[i].astype(np.float32) for i, a in enumerate(agents)}

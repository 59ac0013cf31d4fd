"""SB3 helpers of the scripts that train SB3 PPO networks (``examples/sb3_ppo.py``, and the recipes of the
shipped ``ppo_*`` checkpoints: ``baselines/train_ppo.py``, ``baselines/dagger.py``):

* :class:`EnvFactory` (picklable, for worker processes) and :func:`make_sb3_venv` (a ``ParallelVecEnv``
  wrapped in ``VecMonitor`` + ``VecNormalize``);
* :func:`observation_selection`: ``policy_kwargs`` that hide observation fields from the networks;
* :func:`bc_initialize`: clone demonstrations into an SB3 PPO actor-critic (mean action and value).

stable-baselines3 and torch (the ``train`` extra) are imported inside the functions that use them.
"""

from __future__ import annotations

import time

__all__ = ["EnvFactory", "make_sb3_venv", "observation_selection", "bc_initialize"]


class EnvFactory:
    """Picklable factory of a ParallelCoverageEnv with a preset (for worker processes)."""

    def __init__(self, scenario: str, preset: str, overrides: dict | None):
        self.scenario, self.preset, self.overrides = scenario, preset, overrides

    def __call__(self):
        from parcover_env.envs import ParallelCoverageEnv

        return ParallelCoverageEnv(self.scenario, overrides=self.overrides, preset=self.preset)


def make_sb3_venv(scenarios: list[str], seed: int, *, preset: str, gamma: float, max_steps: int = 0,
                  multiprocess: bool = False):
    """One ParallelEnv per entry of ``scenarios`` (one slot per robot) in ``VecMonitor`` and
    ``VecNormalize`` (observations and rewards, discount ``gamma``); ``max_steps`` > 0 overrides
    the episode length."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from parcover_env.envs.vec_env import ParallelVecEnv

    overrides = {"episode": {"max_steps": max_steps}} if max_steps else None
    base = ParallelVecEnv([EnvFactory(s, preset, overrides) for s in scenarios], multiprocess=multiprocess)
    base.seed(seed)
    return VecNormalize(VecMonitor(base), norm_obs=True, norm_reward=True, gamma=gamma)


def observation_selection(scenario: str, preset: str, drop_obs: str) -> dict:
    """``policy_kwargs`` entries that hide the comma-separated observation fields ``drop_obs``."""
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.policies.sb3_features import SelectEntries, keep_indices

    layout = ParallelCoverageEnv(scenario, preset=preset).layout
    drop = [f.strip() for f in drop_obs.split(",") if f.strip()]
    return {"features_extractor_class": SelectEntries,
            "features_extractor_kwargs": {"keep": keep_indices(layout.names, layout.slices, drop)}}


def _discounted(rewards, gamma: float):
    """(returns-to-go, running discounted return) of one episode's rewards."""
    import numpy as np

    r = np.asarray(rewards, dtype=np.float64)
    to_go, running = np.empty_like(r), np.empty_like(r)
    g = 0.0
    for t in range(len(r) - 1, -1, -1):
        g = r[t] + gamma * g
        to_go[t] = g
    acc = 0.0
    for t in range(len(r)):
        acc = acc * gamma + r[t]
        running[t] = acc
    return to_go, running


def bc_initialize(model, venv, eps: list[dict], *, gamma: float, seed: int, epochs: int, log_std: float,
                  learning_rate: float = 1e-3) -> dict:
    """Clone the demonstrations ``eps`` (one dict per robot-episode: ``observations``, ``actions``,
    ``rewards``) into the SB3 PPO ``model``: the actor's mean action by MSE, the critic onto the
    discounted returns-to-go; sets ``venv``'s VecNormalize statistics from the demonstrations and
    the actor's log-std to ``log_std``. Returns the fit's figures (samples, final MSEs, wall time)."""
    import numpy as np
    import torch

    t0 = time.time()
    obs = np.concatenate([e["observations"][:-1] for e in eps]).astype(np.float64)
    act = np.clip(np.concatenate([e["actions"] for e in eps]), -1, 1)
    # discounted returns-to-go (MC value targets) and the running discounted return VecNormalize tracks
    parts = [_discounted(e["rewards"], gamma) for e in eps]
    rtg, running = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    venv.obs_rms.mean, venv.obs_rms.var, venv.obs_rms.count = obs.mean(0), obs.var(0), float(len(obs))
    venv.ret_rms.mean, venv.ret_rms.var, venv.ret_rms.count = 0.0, float(running.var()), float(len(running))
    x = torch.as_tensor(venv.normalize_obs(obs.astype(np.float32)), dtype=torch.float32, device=model.device)
    y = torch.as_tensor(act, dtype=torch.float32, device=model.device)
    v = torch.as_tensor(np.clip(rtg / np.sqrt(venv.ret_rms.var + venv.epsilon), -venv.clip_reward * 50,
                                venv.clip_reward * 50), dtype=torch.float32, device=model.device)
    pol = model.policy
    opt = torch.optim.Adam(pol.parameters(), lr=learning_rate)
    gen = torch.Generator().manual_seed(seed)
    losses = []
    for _epoch in range(epochs):
        perm, tot_a, tot_v = torch.randperm(len(x), generator=gen), 0.0, 0.0
        for i in range(0, len(x), 512):
            idx = perm[i : i + 512]
            feats = pol.extract_features(x[idx])
            lat_pi, lat_vf = pol.mlp_extractor(feats)
            loss_a = torch.nn.functional.mse_loss(pol.action_net(lat_pi), y[idx])
            loss_v = torch.nn.functional.mse_loss(pol.value_net(lat_vf).squeeze(-1), v[idx])
            opt.zero_grad()
            (loss_a + 0.5 * loss_v).backward()
            opt.step()
            tot_a += loss_a.item() * len(idx)
            tot_v += loss_v.item() * len(idx)
        losses.append((tot_a / len(x), tot_v / len(x)))
    with torch.no_grad():
        pol.log_std.fill_(log_std)
    return {"bc_samples": int(len(x)), "bc_robot_episodes": len(eps), "bc_action_mse": losses[-1][0],
            "bc_value_mse": losses[-1][1], "bc_fit_wall_time_s": time.time() - t0}

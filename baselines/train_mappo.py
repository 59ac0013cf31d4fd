"""MAPPO: PPO with parameter sharing and a centralized critic (one readable file, CleanRL style).

    python baselines/train_mappo.py --scenario office --total-timesteps 300000 --out runs/mappo_office

Every robot acts from its own observation (decentralized actor, the same MLP for all robots); the
critic reads the robot's observation *and* the env's global ``state()`` (true poses and leader flags
of every robot, KPOI visited flags, elapsed time: ``ParallelCoverageEnv.state``), available only in
training (Yu et al. 2022, "The surprising effectiveness of PPO in cooperative multi-agent games").
Rollouts come from our SB3 VecEnv adapter (``parcover_env.envs.vec_env.ParallelVecEnv``, one slot per
robot); ``env_method("state")`` gives each slot its team's state. Episodes that hit the step limit
are treated as terminal (the observation carries the elapsed-time fraction).

Writes ``OUT/actor.pt`` (loadable as ``--policy mappo:OUT``: the actor MLP and its observation
normalization), ``OUT/curve.csv`` / ``curve.png`` and the sidecar ``OUT/actor.json``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "office"
    """One scenario (the global state's size depends on the team and KPOI count)."""
    preset: str = "realistic"
    seed: int = 0
    total_timesteps: int = 300_000
    """Agent-steps."""
    n_envs: int = 4
    n_steps: int = 128
    """Rollout length per slot between updates."""
    n_epochs: int = 5
    n_minibatches: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    clip_coef: float = 0.2
    vf_coef: float = 0.5
    ent_coef: float = 0.0
    max_grad_norm: float = 0.5
    hidden: str = "128,128"
    max_steps: int = 0
    """Override episode.max_steps (0 = the scenario's)."""
    out: str = "runs/mappo"
    device: str = "auto"
    threads: int = 1
    max_wall_time: float = 0.0
    """Stop after this many seconds (0 = no limit)."""


_ARGV: list[str] = []


def parse_args(argv=None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    _ARGV[:] = list(sys.argv[1:] if argv is None else argv)
    return tyro.cli(Args, args=argv, description=__doc__)


def mlp(n_in: int, hidden: tuple[int, ...], n_out: int):
    import torch.nn as nn

    layers, last = [], n_in
    for h in hidden:
        layers += [nn.Linear(last, h), nn.Tanh()]
        last = h
    layers.append(nn.Linear(last, n_out))
    return nn.Sequential(*layers)


def train(args: Args) -> Path:
    import numpy as np
    import torch
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    from parcover_env.envs.vec_env import ParallelVecEnv
    from parcover_env.harness.training import EnvFactory, RunRecord, plot_curve, write_csv
    from parcover_env.policies.learned import make_mlp

    record = RunRecord.start(__file__, _ARGV)  # the code that ran, even if HEAD moves meanwhile
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    device = torch.device(("cuda" if torch.cuda.is_available() else "cpu") if args.device == "auto" else args.device)
    overrides = {"episode": {"max_steps": args.max_steps}} if args.max_steps else None
    venv = ParallelVecEnv([EnvFactory(args.scenario, args.preset, overrides) for _ in range(args.n_envs)])
    venv.seed(args.seed)
    n, obs_dim = venv.num_envs, venv.observation_space.shape[0]
    hidden = tuple(int(h) for h in args.hidden.split(","))
    obs = venv.reset()
    state = np.stack(venv.env_method("state"))
    state_dim = state.shape[1]
    actor = make_mlp(obs_dim, 2, hidden).to(device)  # tanh mean in the action box (BC's network)
    log_std = torch.nn.Parameter(torch.full((2,), -0.5, device=device))
    critic = mlp(obs_dim + state_dim, hidden, 1).to(device)
    params = [*actor.parameters(), log_std, *critic.parameters()]
    opt = torch.optim.Adam(params, lr=args.learning_rate, eps=1e-5)
    obs_rms, state_rms, ret_rms = RunningMeanStd(shape=(obs_dim,)), RunningMeanStd(shape=(state_dim,)), RunningMeanStd()

    def norm(x, rms):
        return np.clip((x - rms.mean) / np.sqrt(rms.var + 1e-8), -10, 10).astype(np.float32)

    T = args.n_steps
    buf_o = np.zeros((T, n, obs_dim), np.float32)
    buf_s = np.zeros((T, n, state_dim), np.float32)
    buf_a = np.zeros((T, n, 2), np.float32)
    buf_lp, buf_r, buf_d, buf_v = (np.zeros((T, n), np.float32) for _ in range(4))
    running_ret = np.zeros(n)
    ep_ret, curve, steps, t0 = np.zeros(n), [], 0, time.time()
    while steps < args.total_timesteps and not (args.max_wall_time and time.time() - t0 > args.max_wall_time):
        for t in range(T):  # ------------------------------------------------------------ rollout
            obs_rms.update(obs)
            state_rms.update(state)
            o, s = norm(obs, obs_rms), norm(state, state_rms)
            with torch.no_grad():
                ot = torch.as_tensor(o, device=device)
                mean = actor(ot)
                dist = torch.distributions.Normal(mean, log_std.exp())
                a = dist.sample()
                buf_lp[t] = dist.log_prob(a).sum(-1).cpu().numpy()
                buf_v[t] = critic(torch.cat([ot, torch.as_tensor(s, device=device)], -1)).squeeze(-1).cpu().numpy()
            buf_o[t], buf_s[t], buf_a[t] = o, s, a.cpu().numpy()
            obs, rew, done, infos = venv.step(np.clip(buf_a[t], -1, 1))
            state = np.stack(venv.env_method("state"))
            ep_ret += rew
            running_ret = running_ret * args.gamma + rew  # reward scaling by the return's std (as VecNormalize)
            ret_rms.update(running_ret)
            running_ret[done] = 0.0
            buf_r[t] = np.clip(rew / np.sqrt(ret_rms.var + 1e-8), -10, 10)
            buf_d[t] = done
            for i in np.flatnonzero(done):
                m = infos[i].get("metrics", {})
                curve.append({"timesteps": steps + (t + 1) * n, "wall_time": time.time() - t0, "return": ep_ret[i],
                              "success": float(m.get("success", 0.0)),
                              "kpoi_fraction": m.get("kpois_visited", 0) / max(m.get("n_kpois", 1), 1)})
                ep_ret[i] = 0.0
        steps += T * n
        with torch.no_grad():  # ------------------------------------------------------------ GAE
            o = torch.as_tensor(norm(obs, obs_rms), device=device)
            s = torch.as_tensor(norm(state, state_rms), device=device)
            next_v = critic(torch.cat([o, s], -1)).squeeze(-1).cpu().numpy()
        adv, last = np.zeros_like(buf_r), np.zeros(n, np.float32)
        for t in range(T - 1, -1, -1):
            nv = next_v if t == T - 1 else buf_v[t + 1]
            nonterminal = 1.0 - buf_d[t]
            delta = buf_r[t] + args.gamma * nv * nonterminal - buf_v[t]
            last = delta + args.gamma * args.gae_lambda * nonterminal * last
            adv[t] = last
        ret = adv + buf_v
        flat = [torch.as_tensor(x.reshape(T * n, *x.shape[2:]), device=device)
                for x in (buf_o, buf_s, buf_a, buf_lp, adv, ret)]
        bo, bs, ba, blp, badv, bret = flat
        mb = T * n // args.n_minibatches
        for _epoch in range(args.n_epochs):  # ------------------------------------------------ update
            perm = torch.randperm(T * n, device=device)
            for k in range(args.n_minibatches):
                idx = perm[k * mb : (k + 1) * mb]
                dist = torch.distributions.Normal(actor(bo[idx]), log_std.exp())
                ratio = (dist.log_prob(ba[idx]).sum(-1) - blp[idx]).exp()
                a_ = badv[idx]
                a_ = (a_ - a_.mean()) / (a_.std() + 1e-8)
                pg = torch.max(-a_ * ratio, -a_ * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)).mean()
                v = critic(torch.cat([bo[idx], bs[idx]], -1)).squeeze(-1)
                loss = pg + args.vf_coef * ((v - bret[idx]) ** 2).mean() - args.ent_coef * dist.entropy().sum(-1).mean()
                opt.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(params, args.max_grad_norm)
                opt.step()
        recent = curve[-20:]
        print(f"{steps} steps, {time.time() - t0:.0f} s, {len(curve)} episodes, KPOI fraction (last 20) "
              f"{np.mean([c['kpoi_fraction'] for c in recent]) if recent else float('nan'):.2f}", flush=True)
    wall = time.time() - t0
    venv.close()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.save({"state_dict": actor.state_dict(), "n_in": obs_dim, "n_out": 2, "hidden": hidden,
                "obs_mean": obs_rms.mean.astype(np.float32), "obs_std": np.sqrt(obs_rms.var + 1e-8).astype(np.float32),
                "scenario": args.scenario, "algorithm": "mappo", "critic_state_dim": state_dim}, out / "actor.pt")
    write_csv(out / "curve.csv", curve)
    plot_curve(out)
    record.write_sidecar(out / "actor.json", {"algorithm": "mappo", "preset": args.preset, "seed": args.seed,
                                              "train_seeds": f"ParallelEnv k resets with seed {args.seed} + k",
                                              "timesteps": steps, "wall_time_s": wall,
                                              "training_episodes": len(curve), "device": str(device),
                                              "args": asdict(args)})
    print(f"{steps} agent-steps in {wall:.0f} s")
    return out


if __name__ == "__main__":
    print(f"wrote {train(parse_args())}")

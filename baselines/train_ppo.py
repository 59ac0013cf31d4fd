"""Train PPO with parameter sharing on a parcover scenario (one policy for every robot).

    python baselines/train_ppo.py --scenario office --total-timesteps 2000000 --out runs/ppo_office

Writes ``OUT/model.zip``, ``OUT/vecnormalize.pkl`` (observation statistics, read by
``parcover_env.policies.learned.PPOPolicy``), ``OUT/curve.csv`` and ``OUT/curve.png`` (learning curve).
``--scenario generated:RANDOM`` trains with domain randomization over procedural maps
(a new ``generated:<seed>`` map per ParallelEnv). TensorBoard only with ``--tensorboard DIR``.
"""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "office"
    """Scenario name or YAML path; ``generated:RANDOM`` = a different procedural map per env."""
    seed: int = 0
    total_timesteps: int = 1_000_000
    """Agent-steps (one per robot per env step)."""
    n_envs: int = 4
    """ParallelEnvs; slots = n_envs x n_robots."""
    multiprocess: bool = False
    n_steps: int = 512
    batch_size: int = 1024
    n_epochs: int = 5
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    ent_coef: float = 0.0
    net_arch: str = "128,128"
    max_steps: int = 0
    """Override episode.max_steps (0 = the scenario's)."""
    out: str = "runs/ppo"
    tensorboard: str = ""
    threads: int = 1
    """torch threads."""


def parse_args(argv=None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    return tyro.cli(Args, args=argv, description=__doc__)


def make_env_fns(args: Args):
    from parcover_env.envs.vec_env import _EnvFactory

    overrides = {"episode": {"max_steps": args.max_steps}} if args.max_steps else None
    if args.scenario == "generated:RANDOM":
        return [_EnvFactory(f"generated:{args.seed * 1000 + i}", overrides) for i in range(args.n_envs)]
    return [_EnvFactory(args.scenario, overrides) for _ in range(args.n_envs)]


def train(args: Args) -> Path:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from parcover_env.envs.vec_env import ParallelVecEnv

    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    venv = VecNormalize(
        VecMonitor(ParallelVecEnv(make_env_fns(args), multiprocess=args.multiprocess)),
        norm_obs=True,
        norm_reward=True,
        gamma=args.gamma,
    )
    curve: list[dict] = []

    class Curve(BaseCallback):
        next_report = 50_000

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=False):
                if done and "episode" in info:
                    m = info.get("metrics", {})
                    curve.append(
                        {
                            "timesteps": self.num_timesteps,
                            "return": info["episode"]["r"],
                            "length": info["episode"]["l"],
                            "success": float(m.get("success", 0.0)),
                            "kpois_visited": m.get("kpois_visited", 0),
                            "wall_time": time.time() - t0,
                        }
                    )
            if self.num_timesteps >= self.next_report:
                self.next_report += 50_000
                recent = curve[-20:]
                succ = sum(c["success"] for c in recent) / max(len(recent), 1)
                if self.num_timesteps % 100_000 < 50_000:  # checkpoint (overwritten) every ~100k steps
                    model.save(out / "model.zip")
                    venv.save(str(out / "vecnormalize.pkl"))
                print(
                    f"{self.num_timesteps} steps, {time.time() - t0:.0f} s, {len(curve)} episodes, "
                    f"success (last 20) {succ:.2f}",
                    flush=True,
                )
            return True

    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        n_epochs=args.n_epochs,
        learning_rate=args.learning_rate,
        gamma=args.gamma,
        gae_lambda=args.gae_lambda,
        ent_coef=args.ent_coef,
        seed=args.seed,
        device="cpu",
        verbose=0,
        policy_kwargs={"net_arch": [int(h) for h in args.net_arch.split(",")]},
        tensorboard_log=args.tensorboard or None,
    )
    t0 = time.time()
    model.learn(total_timesteps=args.total_timesteps, callback=Curve())
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    venv.close()
    write_curve(curve, out)
    return out


def write_curve(curve: list[dict], out: Path) -> None:
    if not curve:
        return
    with open(out / "curve.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(curve[0]))
        w.writeheader()
        w.writerows(curve)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    t = np.array([c["timesteps"] for c in curve])
    k = max(1, len(curve) // 50)
    smooth = lambda x: np.convolve(x, np.ones(k) / k, mode="valid")  # noqa: E731
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    ax[0].plot(t[k - 1 :], smooth(np.array([c["return"] for c in curve])))
    ax[0].set(xlabel="agent-steps", ylabel="episode return (per agent)")
    ax[1].plot(t[k - 1 :], smooth(np.array([c["success"] for c in curve])))
    ax[1].set(xlabel="agent-steps", ylabel="success rate", ylim=(-0.05, 1.05))
    fig.tight_layout()
    fig.savefig(out / "curve.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    a = parse_args()
    print(f"wrote {train(a)}")

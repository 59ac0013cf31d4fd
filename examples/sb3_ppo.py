"""Train SB3 PPO on parcover's VecEnv, evaluate it, save it as a ``ppo:`` policy (one readable file).

    python examples/sb3_ppo.py --scenario office --total-timesteps 200000 --out runs/sb3_ppo_office
    parcover bench office --policies expert,ppo:runs/sb3_ppo_office --seeds 20

Every robot is one slot of the VecEnv (parameter sharing: one network acts for every robot from its
own observation); ``n_envs`` worlds step together (``backend="batched"``: every world in one compiled
call per phase, the same transitions as separate envs). SB3's ``VecNormalize`` normalizes observations
and rewards; its statistics are saved beside the network: ``OUT/model.zip`` + ``OUT/vecnormalize.pkl``
is what ``ppo:OUT`` loads (:class:`parcover_env.policies.learned.PPOPolicy`), plus the sidecar
``OUT/model.json`` (command, git commit, versions, steps, evaluation). The evaluation loads the saved
policy as ``parcover bench`` does and runs it on seeds ``eval_seed0 ..``, disjoint from the training
seeds (world k of the VecEnv resets with ``seed + k``, then draws its next seeds from its generator).

The shipped ``ppo_*`` checkpoints come from the longer recipes ``baselines/train_ppo.py`` (BC
initialization, BC regularizer, curriculum) and ``baselines/dagger.py``; TorchRL IPPO/MAPPO is
``parcover train``. torch and stable-baselines3 come with the ``train`` extra.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "office"
    """Scenario name or YAML path (one scenario: its team size fixes the VecEnv's slots)."""
    preset: str = "realistic"
    """``realistic`` (default error models) or ``ideal`` (every error model off)."""
    seed: int = 0
    """Seeds torch, the PPO sampler and the training worlds (world k resets with seed + k)."""
    total_timesteps: int = 200_000
    """Agent-steps (one per robot per world step)."""
    n_envs: int = 4
    """Worlds stepped together; slots = n_envs x robots."""
    backend: str = "batched"
    """The VecEnv's backend (``parcover_env.envs.vec_env.BACKENDS``): ``batched``, ``inprocess`` or ``process``."""
    n_steps: int = 256
    """Rollout length per slot between updates."""
    batch_size: int = 1024
    n_epochs: int = 5
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    net_arch: str = "128,128"
    """Hidden layer widths of the actor and of the critic."""
    max_steps: int = 0
    """Override episode.max_steps (0 = the scenario's)."""
    eval_episodes: int = 5
    """Evaluation episodes of the saved policy after training (0 = none)."""
    eval_seed0: int = 500
    """First evaluation seed."""
    out: str = "runs/sb3_ppo"
    threads: int = 1
    """torch CPU threads."""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    return tyro.cli(Args, args=argv, description=__doc__)


def overrides(args: Args) -> dict | None:
    """The scenario overrides of training and evaluation (the episode length)."""
    return {"episode": {"max_steps": args.max_steps}} if args.max_steps else None


def make_env(args: Args):
    """The VecEnv (one slot per robot, ``VecMonitor``) under ``VecNormalize`` (observations and rewards)."""
    from stable_baselines3.common.vec_env import VecNormalize

    from parcover_env.envs.vec_env import make_vec_env

    venv = make_vec_env(args.scenario, args.n_envs, overrides(args), backend=args.backend, preset=args.preset)
    venv.seed(args.seed)
    return VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=args.gamma)


def train(args: Args, argv: list[str] | None = None) -> Path:
    """Train, save ``OUT/model.zip`` + ``OUT/vecnormalize.pkl`` + ``OUT/model.json``; returns ``OUT``."""
    import torch
    from stable_baselines3 import PPO

    from parcover_env.harness.training import RunRecord

    record = RunRecord.start(__file__, list(sys.argv[1:] if argv is None else argv))
    torch.set_num_threads(args.threads)
    venv = make_env(args)
    model = PPO("MlpPolicy", venv, n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.n_epochs,
                learning_rate=args.learning_rate, gamma=args.gamma, gae_lambda=args.gae_lambda, seed=args.seed,
                policy_kwargs={"net_arch": [int(w) for w in args.net_arch.split(",")]}, device="cpu", verbose=0)
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.total_timesteps)
    wall = time.perf_counter() - t0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    venv.close()
    rows = evaluate(args, out)
    record.write_sidecar(out / "model.json", {
        "algorithm": "sb3_ppo", "scenario": args.scenario, "preset": args.preset, "seed": args.seed,
        "timesteps": int(model.num_timesteps), "wall_time_s": wall, "args": asdict(args), "evaluation": rows})
    print(f"{model.num_timesteps} agent-steps in {wall:.0f} s; saved ppo:{out}")
    return out


def evaluate(args: Args, out: Path) -> list[dict]:
    """The saved policy ``ppo:OUT`` (deterministic) on seeds ``eval_seed0 ..``: one row per episode, printed."""
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy

    env = ParallelCoverageEnv(args.scenario, overrides=overrides(args), preset=args.preset)
    policy = make_policy(f"ppo:{out}", env, None)
    rows = []
    for seed in range(args.eval_seed0, args.eval_seed0 + args.eval_episodes):
        m = run_episode(env, policy, seed)
        rows.append({"seed": seed, "success": bool(m["success"]), "kpoi_fraction": m["kpois_visited"] / m["n_kpois"],
                     "makespan_ratio": m["makespan_ratio"], "collisions": int(m["collisions"])})
    env.close()
    print("| seed | success | KPOI fraction | makespan ratio | collisions |\n|---|---|---|---|---|")
    for r in rows:
        ratio = "-" if r["makespan_ratio"] is None else f"{r['makespan_ratio']:.2f}"
        print(f"| {r['seed']} | {r['success']} | {r['kpoi_fraction']:.2f} | {ratio} | {r['collisions']} |")
    return rows


def main(argv: list[str] | None = None) -> int:
    train(parse_args(argv), argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

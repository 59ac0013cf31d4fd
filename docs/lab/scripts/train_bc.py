"""Behaviour cloning from expert demonstrations (parameter sharing: one MLP for every robot).

    python docs/lab/scripts/train_bc.py --scenario office --episodes 40 --epochs 30 --out runs/bc_office
    python docs/lab/scripts/train_bc.py --dataset-id parcover/office-expert-v0 --dataset-root runs/datasets
    python docs/lab/scripts/train_bc.py --dataset-id 'parcover/generated-*-expert-v0' --out runs/bc_generated

Demonstrations come from a Minari dataset written by ``parcover collect`` (``--dataset-id``) or,
without one, are recorded on the fly from the scripted expert. The network regresses the expert's
action (mean squared error, tanh output) from one robot's normalized observation. Writes
``OUT/bc.pt`` (read by ``parcover_env.policies.learned.BCPolicy``) and ``OUT/bc_loss.csv``.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "office"
    episodes: int = 40
    """Expert missions to record when no dataset is given (seeds 1000..)."""
    dataset_id: str = ""
    """Minari dataset id(s) written by ``parcover collect``: comma-separated, ``*`` wildcards allowed."""
    dataset_root: str = "runs/datasets"
    """Root directory of the datasets (MINARI_DATASETS_PATH)."""
    epochs: int = 30
    batch_size: int = 512
    learning_rate: float = 1e-3
    hidden: str = "256,256"
    seed: int = 0
    out: str = "runs/bc"
    threads: int = 1


def parse_args(argv=None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    return tyro.cli(Args, args=argv, description=__doc__)


def load_demos(args: Args):
    """(observations, actions) arrays of every recorded robot step."""
    import numpy as np

    from parcover_env.harness import datasets

    if args.dataset_id:
        eps = datasets.load_minari_many(args.dataset_id, args.dataset_root)
    else:  # seeds far from the benchmark's 0..N-1, so BC is not evaluated on its training episodes
        eps = datasets.record_episodes(args.scenario, args.episodes, seed=1000 + args.seed)
    obs = np.concatenate([e["observations"][:-1] for e in eps])
    act = np.concatenate([e["actions"] for e in eps])
    return obs, act


def train(args: Args) -> Path:
    import numpy as np
    import torch

    from parcover_env.policies.learned import make_mlp

    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    obs, act = load_demos(args)
    mean, std = obs.mean(axis=0), obs.std(axis=0) + 1e-6
    x = torch.as_tensor((obs - mean) / std, dtype=torch.float32).clamp(-10, 10)
    y = torch.as_tensor(np.clip(act, -1, 1), dtype=torch.float32)
    hidden = tuple(int(h) for h in args.hidden.split(","))
    net = make_mlp(x.shape[1], y.shape[1], hidden)
    opt = torch.optim.Adam(net.parameters(), lr=args.learning_rate)
    gen = torch.Generator().manual_seed(args.seed)
    losses = []
    for epoch in range(args.epochs):
        perm, total = torch.randperm(len(x), generator=gen), 0.0
        for i in range(0, len(x), args.batch_size):
            idx = perm[i : i + args.batch_size]
            loss = torch.nn.functional.mse_loss(net(x[idx]), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append({"epoch": epoch + 1, "mse": total / len(x)})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "state_dict": net.state_dict(),
            "n_in": x.shape[1],
            "n_out": y.shape[1],
            "hidden": hidden,
            "obs_mean": mean,
            "obs_std": std,
            "scenario": args.scenario,
            "samples": len(x),
        },
        out / "bc.pt",
    )
    with open(out / "bc_loss.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["epoch", "mse"])
        w.writeheader()
        w.writerows(losses)
    print(f"{len(x)} samples, final MSE {losses[-1]['mse']:.4f}")
    return out


if __name__ == "__main__":
    print(f"wrote {train(parse_args())}")

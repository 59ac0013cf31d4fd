"""Baseline scripts with tiny budgets: PPO trains and saves, BC trains, evaluate/bench load both."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

ROOT = Path(__file__).resolve().parents[1] / "baselines"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"baseline_{name}", ROOT / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def ppo_dir(tmp_path_factory):
    train_ppo = _load("train_ppo")
    out = tmp_path_factory.mktemp("ppo")
    args = train_ppo.parse_args(
        [
            "--total-timesteps",
            "2000",
            "--n-envs",
            "2",
            "--n-steps",
            "256",
            "--batch-size",
            "256",
            "--n-epochs",
            "1",
            "--max-steps",
            "100",
            "--net-arch",
            "32",
            "--out",
            str(out),
        ]
    )
    train_ppo.train(args)
    return out


def test_ppo_saves_model_stats_and_curve(ppo_dir):
    assert {"model.zip", "vecnormalize.pkl", "curve.csv", "curve.png"} <= {p.name for p in ppo_dir.iterdir()}
    rows = (ppo_dir / "curve.csv").read_text().splitlines()
    assert rows[0].startswith("timesteps,return") and len(rows) > 1


def test_ppo_policy_acts_in_the_box(ppo_dir):
    from parcover_env import parallel_env
    from parcover_env.policies.learned import PPOPolicy

    env = parallel_env("office")
    obs, _ = env.reset(seed=0)
    acts = PPOPolicy(ppo_dir).act(obs)
    assert set(acts) == set(obs)
    assert all(a.shape == (2,) and np.all(np.abs(a) <= 1) for a in acts.values())


def test_bc_one_epoch_then_evaluate(tmp_path):
    train_bc = _load("train_bc")
    evaluate = _load("evaluate")
    out = tmp_path / "bc"
    train_bc.train(
        train_bc.parse_args(["--episodes", "1", "--epochs", "1", "--hidden", "32", "--out", str(out)])
    )
    assert (out / "bc.pt").is_file()
    rows = evaluate.evaluate(
        evaluate.parse_args(["--policy", f"bc:{out}", "--seeds", "1", "--max-steps", "30"])
    )
    assert len(rows) == 1 and rows[0]["steps"] == 30 and rows[0]["policy"] == f"bc:{out}"


def test_bc_imitates_a_known_linear_expert():
    """BC regression itself: recovers a fixed action map from synthetic demonstrations."""
    import torch

    from parcover_env.policies.learned import make_mlp

    g = torch.Generator().manual_seed(0)
    x = torch.randn(2000, 4, generator=g)
    y = torch.tanh(x[:, :2] * 0.8)
    torch.manual_seed(0)
    net = make_mlp(4, 2, (32,))
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    for _ in range(300):
        loss = torch.nn.functional.mse_loss(net(x), y)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.01


def test_evaluate_random_runs(capsys):
    evaluate = _load("evaluate")
    assert evaluate.main(["--policy", "random", "--seeds", "2", "--max-steps", "20"]) == 0
    out = capsys.readouterr().out
    assert "random on office (realistic), 2 episodes" in out and "| office | random | 2 | 0.00 [" in out

"""MarlConfig.lr_end (linear step-size decay) and critic_warmup (only the critic learns at first)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from parcover_env.harness.marl_config import MarlConfig, load_marl_config, scheduled_lr

LAB_CONFIGS = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"
"""Training configs of staged runs that are no README row (moved out of configs/train/)."""



def test_scheduled_lr_is_constant_without_lr_end():
    cfg = MarlConfig(learning_rate=3e-4, wall_time=100.0)
    assert scheduled_lr(cfg, 0, 1000, 0.0) == 3e-4
    assert scheduled_lr(cfg, 900, 1000, 99.0) == 3e-4


def test_scheduled_lr_decays_linearly_by_the_larger_used_fraction():
    cfg = MarlConfig(learning_rate=4e-4, lr_end=0.0, wall_time=100.0)
    assert scheduled_lr(cfg, 0, 1000, 0.0) == pytest.approx(4e-4)
    assert scheduled_lr(cfg, 250, 1000, 10.0) == pytest.approx(3e-4)  # steps: 1/4 used
    assert scheduled_lr(cfg, 100, 1000, 50.0) == pytest.approx(2e-4)  # wall time: 1/2 used
    assert scheduled_lr(cfg, 2000, 1000, 10.0) == pytest.approx(0.0)  # at most the whole budget
    untimed = dataclasses.replace(cfg, lr_end=1e-4, wall_time=0.0)
    assert scheduled_lr(untimed, 500, 1000, 1e6) == pytest.approx(2.5e-4)  # no wall_time: steps only


def test_the_stage5_config_loads_with_its_stated_changes():
    cfg = load_marl_config("mappo", LAB_CONFIGS / "mappo_generated_attention.yaml")
    stage4 = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_shaped_mask.yaml")
    assert (cfg.critic, cfg.lr_end, cfg.critic_warmup) == ("attention", 3e-5, 300000)
    same = {f.name for f in dataclasses.fields(MarlConfig)} - {"critic", "lr_end", "critic_warmup", "wall_time"}
    assert {k: getattr(cfg, k) for k in same} == {k: getattr(stage4, k) for k in same}


def _weights(path):
    import torch

    return torch.load(path)["state_dict"]


def _same(a, b) -> bool:
    import torch

    return all(torch.allclose(a[k], b[k], atol=1e-9) for k in a)


def test_critic_warmup_and_the_schedule_drive_the_training_loop(tmp_path, monkeypatch):
    pytest.importorskip("torchrl")
    from parcover_env.harness import marl
    from parcover_env.harness.marl import TrainRequest, train

    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=64, epochs=1,
                              hidden=(8,), episode_steps=30)
    train(TrainRequest("ippo", "office", 64, tmp_path / "a", cfg, "x", seed=1))
    a = str(tmp_path / "a")
    warm = dataclasses.replace(cfg, critic_warmup=10**9, learning_rate=1e-2)
    train(TrainRequest("ippo", "office", 128, tmp_path / "w", warm, "x", seed=2, init=a))
    assert _same(_weights(tmp_path / "a" / "policy.pt"), _weights(tmp_path / "w" / "policy.pt"))  # actor kept
    assert not _same(_weights(tmp_path / "a" / "critic.pt"), _weights(tmp_path / "w" / "critic.pt"))  # critic learnt
    moving = dataclasses.replace(warm, critic_warmup=0)
    train(TrainRequest("ippo", "office", 128, tmp_path / "m", moving, "x", seed=2, init=a))
    assert not _same(_weights(tmp_path / "a" / "policy.pt"), _weights(tmp_path / "m" / "policy.pt"))
    seen = []

    def zero(cfg_, agent_steps, steps, elapsed):  # the loop sets the optimizer's step size from it
        seen.append((agent_steps, steps))
        return 0.0

    monkeypatch.setattr(marl, "scheduled_lr", zero)
    train(TrainRequest("ippo", "office", 256, tmp_path / "z", moving, "x", seed=2, init=a))
    assert seen == [(128, 256), (256, 256)]  # office: 2 robots, 128 agent-steps per batch
    assert _same(_weights(tmp_path / "a" / "policy.pt"), _weights(tmp_path / "z" / "policy.pt"))
    assert _same(_weights(tmp_path / "a" / "critic.pt"), _weights(tmp_path / "z" / "critic.pt"))


def test_the_shipped_mappo_checkpoint_names_its_five_stage_chain():
    import json

    import parcover_env
    from parcover_env.policies.torchrl_policy import TorchRLPolicy

    root = Path(parcover_env.__file__).resolve().parent.parent / "baselines" / "checkpoints"
    if not (root / "mappo_generated_attention").is_dir():
        pytest.skip("source checkout only")
    run = json.loads((root / "mappo_generated_attention" / "run.json").read_text())
    stage4 = json.loads((root / "ippo_generated_shaped" / "run.json").read_text())
    assert run["policy"] == "torchrl:baselines/checkpoints/mappo_generated_attention/policy.pt"
    assert (run["algo"], run["config"]["critic"], run["config"]["lr_end"]) == ("mappo", "attention", 3e-5)
    assert run["init"]["path"] == "baselines/checkpoints/ippo_generated_shaped" and run["init"]["critic"] is False
    assert run["init"]["init"] == stage4["init"] and run["init_run"] == stage4  # stages 1-4 as shipped
    assert run["agent_steps"] + 10_509_297 == 12_770_434 <= 20_000_000
    TorchRLPolicy(root / "mappo_generated_attention" / "policy.pt")  # loads


def test_the_shipped_stage_7_names_its_chain_its_budget_and_its_sampled_spec():
    import json

    import parcover_env
    from parcover_env.policies.torchrl_policy import TorchRLPolicy

    root = Path(parcover_env.__file__).resolve().parent.parent / "baselines" / "checkpoints"
    if not (root / "mappo_generated_scan_sigma").is_dir():
        pytest.skip("source checkout only")
    run = json.loads((root / "mappo_generated_scan_sigma" / "run.json").read_text())
    stage5 = json.loads((root / "mappo_generated_attention" / "run.json").read_text())
    assert run["policy"] == "torchrl_sampled:baselines/checkpoints/mappo_generated_scan_sigma/policy.pt"
    assert run["config"]["env"]["rewards"]["uncertainty"] == -1.0 and run["env_overrides"]["observation"]["scan"]
    assert run["init"]["path"] == "docs/learned/mappo_generated_scan_s6" and run["init"]["critic"] is True
    stage6 = run["init_run"]
    assert stage6["init"]["path"] == "baselines/checkpoints/mappo_generated_attention" and stage6["init_run"] == stage5
    assert stage6["init"]["grown"] == {"observation": ["scanning", "scan_result"], "actions": ["scan"]}
    total = stage5["agent_steps"] + 10_509_297 + stage6["agent_steps"] + run["agent_steps"]
    assert total == 16_395_528 <= 20_000_000
    assert TorchRLPolicy(root / "mappo_generated_scan_sigma" / "policy.pt", sample_seed=0).act_dim == 3

"""The shipped checkpoints (baselines/checkpoints/): small, documented, loadable, reproducible."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

CKPT = Path(__file__).resolve().parents[2] / "baselines" / "checkpoints"
NAMES = ("ppo_office", "ppo_tree", "ppo_generated", "ppo_office_ideal")


@pytest.mark.parametrize("name", NAMES)
def test_checkpoint_is_small_and_has_a_sidecar(name):
    model, stats, side = CKPT / f"{name}.zip", CKPT / f"{name}_vecnormalize.pkl", CKPT / f"{name}.json"
    assert model.is_file() and stats.is_file() and side.is_file()
    assert model.stat().st_size + stats.stat().st_size < 1_100_000
    rec = json.loads(side.read_text())
    first = rec["sidecars"][0]
    for key in ("command", "git_commit", "timesteps", "wall_time_s", "preset", "versions"):
        assert key in first, key
    if first["command"].startswith("python baselines/dagger.py"):  # a DAgger round (no PPO steps)
        assert first["timesteps"] == 0 and first["args"]["seed"] == 0
        seeds = first["episode_seeds"] + [r["seed"] for r in first["validation"]]
        maps = first["train_maps"] + [int(r["scenario"].split(":")[1]) for r in first["validation"]]
    else:
        assert first["command"].startswith("python baselines/train_ppo.py")
        for key in ("seed", "train_seeds", "eval_seeds"):
            assert key in first, key
        seeds, maps = first["eval_seeds"], []
    # the evaluation maps and seeds of the benchmark (>= 1000) were never used in training or validation
    assert seeds and all(s < 1000 for s in seeds) and all(m < 1000 for m in maps)


@pytest.mark.parametrize("name", NAMES)
def test_checkpoint_acts_as_recorded(name):
    from parcover_env.policies.learned import PPOPolicy
    from parcover_env.policies.registry import check_policy_spec

    check_policy_spec(f"ppo:{CKPT / f'{name}.zip'}")
    check = json.loads((CKPT / f"{name}.json").read_text())["check"]
    obs = {a: np.asarray(o, dtype=np.float32) for a, o in check["observations"].items()}
    pol = PPOPolicy(CKPT / f"{name}.zip")
    act = pol.act(obs)
    for a, expected in check["actions"].items():  # deterministic: the action recorded at shipping time
        np.testing.assert_allclose(act[a], expected, atol=1e-5)
    assert all(np.all(np.abs(v) <= 1.0) for v in act.values())
    # the statistics are applied: without them the network sees raw metres and acts differently
    raw = pol.model.predict(np.stack([obs[a] for a in sorted(obs)]), deterministic=True)[0]
    assert not np.allclose(np.clip(raw, -1, 1), np.stack([act[a] for a in sorted(act)]), atol=1e-3)


def test_office_checkpoint_runs_in_the_env():
    from parcover_env import parallel_env
    from parcover_env.policies.registry import make_policy

    env = parallel_env("office")
    obs, _ = env.reset(seed=1000)
    check = json.loads((CKPT / "ppo_office.json").read_text())["check"]
    assert check["scenario"] == "office" and check["seed"] == 1000
    np.testing.assert_allclose(obs["robot_0"], check["observations"]["robot_0"], atol=1e-6)
    pol = make_policy(f"ppo:{CKPT / 'ppo_office.zip'}", env, 1000)
    for _ in range(5):
        obs, *_ = env.step(pol.act(obs))
    assert set(obs) == set(env.possible_agents)

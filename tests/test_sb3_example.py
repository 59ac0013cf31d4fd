"""examples/sb3_ppo.py: SB3 PPO on the VecEnv, saved in the format ``ppo:`` loads, evaluated through it."""

from __future__ import annotations

import importlib.util
import json
import pickle
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sb3_ppo.py"
TINY = ["--total-timesteps", "512", "--n-envs", "2", "--n-steps", "128", "--batch-size", "128", "--n-epochs", "1",
        "--max-steps", "40", "--net-arch", "16", "--eval-episodes", "2"]


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("example_sb3_ppo", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def runs(example, tmp_path_factory):
    """The same seed trained through the batched worlds and through separate in-process envs."""
    root = tmp_path_factory.mktemp("sb3")
    out = {}
    for backend in ("batched", "inprocess"):
        argv = [*TINY, "--backend", backend, "--out", str(root / backend)]
        out[backend] = example.train(example.parse_args(argv), argv)
    return out


def _weights(out: Path) -> dict:
    from stable_baselines3 import PPO

    return PPO.load(out / "model.zip", device="cpu").policy.state_dict()


def test_batched_and_separate_worlds_train_the_same_network(runs):
    """The batched VecEnv gives the transitions of separate envs, so the same seed gives the same weights
    and the same normalization statistics, bit for bit."""
    a, b = _weights(runs["batched"]), _weights(runs["inprocess"])
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    sa, sb = (pickle.loads((runs[k] / "vecnormalize.pkl").read_bytes()) for k in ("batched", "inprocess"))
    assert np.array_equal(sa.obs_rms.mean, sb.obs_rms.mean) and np.array_equal(sa.obs_rms.var, sb.obs_rms.var)
    assert sa.obs_rms.count == pytest.approx(512 + 4 + 1e-4)  # every agent-step, the 4 first observations, SB3's eps


def test_the_saved_files_are_a_ppo_policy_that_acts_as_trained(runs):
    """``ppo:OUT`` normalizes with the saved statistics and acts with the saved network's mean action."""
    from stable_baselines3 import PPO

    from parcover_env import parallel_env
    from parcover_env.policies.registry import make_policy

    out = runs["batched"]
    env = parallel_env("office")
    obs, _ = env.reset(seed=3)
    acts = make_policy(f"ppo:{out}", env, 0).act(obs)
    stats = pickle.loads((out / "vecnormalize.pkl").read_bytes())
    model = PPO.load(out / "model.zip", device="cpu")
    for agent, o in obs.items():
        x = np.clip((o - stats.obs_rms.mean) / np.sqrt(stats.obs_rms.var + stats.epsilon), -10, 10)
        with torch.no_grad():
            mean = model.policy.get_distribution(torch.as_tensor(x, dtype=torch.float32)[None]).distribution.mean
        np.testing.assert_allclose(acts[agent], np.clip(mean.numpy()[0], -1, 1), rtol=1e-5, atol=1e-6)


def test_sidecar_records_the_run_and_the_evaluation_of_the_saved_policy(runs):
    from parcover_env import parallel_env
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy

    out = runs["inprocess"]
    side = json.loads((out / "model.json").read_text())
    assert side["command"].split()[1].endswith("examples/sb3_ppo.py") and "--backend inprocess" in side["command"]
    assert side["timesteps"] == 512 and side["args"]["n_envs"] == 2 and side["seed"] == 0
    env = parallel_env("office", overrides={"episode": {"max_steps": 40}})
    policy = make_policy(f"ppo:{out}", env, None)
    assert [r["seed"] for r in side["evaluation"]] == [500, 501]
    for row in side["evaluation"]:
        m = run_episode(env, policy, row["seed"])
        assert row["kpoi_fraction"] == m["kpois_visited"] / m["n_kpois"] and row["success"] == bool(m["success"])
        assert row["collisions"] == m["collisions"]

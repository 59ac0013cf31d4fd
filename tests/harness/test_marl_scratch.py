"""parcover train's env plumbing for from-scratch runs: the YAML's ``env`` overrides reach the env and
the sidecar, a map pool trains with its padding left out of the agent-steps, and a run stops
early (``wall_time``, SIGTERM) with its policy saved."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import threading
from pathlib import Path

import pytest

pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.errors import ConfigError  # noqa: E402
from parcover_env.harness.marl import EnvMaker, TrainRequest, train  # noqa: E402
from parcover_env.harness.marl_config import load_marl_config  # noqa: E402

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}


def test_shipped_scratch_configs_train_env_v2(tmp_path):
    from parcover_env.scenarios.registry import configs_dir

    lab = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"
    for path in (configs_dir() / "train" / "ippo_office_scratch.yaml", lab / "ippo_generated_scratch.yaml",
                 configs_dir() / "train" / "ippo_tree_scratch.yaml"):
        cfg = load_marl_config("ippo", path)
        assert cfg.env == V2 and cfg.preset == "realistic" and cfg.wall_time > 0
    (tmp_path / "bad.yaml").write_text("env: [1, 2]\n")
    with pytest.raises(ConfigError, match="mapping") as err:
        load_marl_config("ippo", tmp_path / "bad.yaml")
    assert err.value.key == "env"
    (tmp_path / "bad.yaml").write_text("max_robots: 0\n")
    with pytest.raises(ConfigError, match="> 0"):
        load_marl_config("ippo", tmp_path / "bad.yaml")


def test_env_overrides_reach_the_env():
    v1 = EnvMaker("office", "realistic", episode_steps=3).parallel()
    v2 = EnvMaker("office", "realistic", episode_steps=3, overrides=V2).parallel()
    assert v1.version == 1 and v2.version == 2 and v2.scenario.rewards.own_kpoi == 10.0
    assert v2.state_space.shape == (322,) and v1.state_space.shape != (322,)
    pool = EnvMaker("generated:3-4", "realistic", episode_steps=3, overrides=V2, max_robots=5).parallel()
    assert pool.n_robots == 5 and pool.scenario.observation.version == 2


def _cfg(**kw):
    return dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=32, epochs=1,
                               hidden=(8,), episode_steps=40, env=V2, **kw)


def test_pool_run_counts_real_robots_only_and_records_its_overrides(tmp_path):
    from parcover_env.policies.registry import policy_overrides

    out = tmp_path / "pool"
    record = train(TrainRequest("ippo", "generated:3-4", 100, out, _cfg(max_robots=5), "x", seed=2))
    # maps 3 and 4 have 3 robots each, padded to 5 agents: 64 env steps x 3 real robots per batch;
    # 100 agent-steps: the first batch (64 x 3 real) reaches them
    assert record["agent_steps"] == 64 * 3 and record["n_robots"] == 5
    assert record["env_overrides"] == V2 and json.loads((out / "run.json").read_text())["env_overrides"] == V2
    assert policy_overrides(record["policy"]) == V2


def test_steps_count_real_robots_so_a_pool_run_collects_them_all(tmp_path):
    # one agent-step more than a batch of 64 env steps x 3 real robots: a second batch, although
    # 193 < 64 x 5 padded agents (the old plan collected one batch only)
    record = train(TrainRequest("ippo", "generated:3-4", 64 * 3 + 1, tmp_path / "more", _cfg(max_robots=5), "x"))
    assert record["agent_steps"] == 64 * 3 * 2


def test_wall_time_and_sigterm_stop_after_a_batch_and_save(tmp_path):
    record = train(TrainRequest("ippo", "office", 10**6, tmp_path / "wall", _cfg(wall_time=1e-3), "x"))
    assert record["agent_steps"] == 64 * 2 and (tmp_path / "wall" / "policy.pt").is_file()
    before = signal.getsignal(signal.SIGTERM)
    timer = threading.Timer(2.0, os.kill, (os.getpid(), signal.SIGTERM))
    timer.start()
    try:
        record = train(TrainRequest("ippo", "office", 10**6, tmp_path / "term", _cfg(), "x"))
    finally:
        timer.cancel()
    assert 0 < record["agent_steps"] < 10**6 and (tmp_path / "term" / "policy.pt").is_file()
    assert signal.getsignal(signal.SIGTERM) is before  # the trainer's handler is gone

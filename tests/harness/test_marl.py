"""parcover train's TorchRL wiring: value targets (truncation bootstraps, termination does not), the
saved policy, the sidecar and the curve of a short run, on both collector backends."""

from __future__ import annotations

import csv
import dataclasses
import importlib.metadata as md
import json

import numpy as np
import pytest
from gymnasium import spaces

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from tensordict import TensorDict  # noqa: E402

from parcover_env.harness.marl import (  # noqa: E402
    GROUP,
    EnvMaker,
    TrainRequest,
    build_actor,
    build_critic,
    build_loss,
    save_policy,
    train,
)
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402

T, N, OBS, STATE = 3, 2, 4, 5
GAMMA, LAMBDA, V = 0.9, 0.95, 10.0


def _box(n: int) -> spaces.Box:
    return spaces.Box(-np.ones(n, np.float32), np.ones(n, np.float32))


def _constant_critic(algo: str):
    """The trainer's critic with its last layer set to output ``V`` everywhere."""
    critic = build_critic(algo, _box(OBS), _box(STATE), MarlConfig(hidden=(8,)))
    last = [m for m in critic.module.modules() if isinstance(m, torch.nn.Linear)][-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.fill_(V)
    return critic


def _batch(terminated_last: bool) -> TensorDict:
    """Three steps of two robots, reward 1 each step; the episode ends at the last step, terminated or truncated."""
    end = torch.zeros(T, N, 1, dtype=torch.bool)
    end[-1] = True
    nxt = {GROUP: {"observation": torch.zeros(T, N, OBS), "reward": torch.ones(T, N, 1), "done": end.clone(),
                   "terminated": end.clone() if terminated_last else torch.zeros_like(end),
                   "truncated": torch.zeros_like(end) if terminated_last else end.clone()},
           "state": torch.zeros(T, STATE)}
    return TensorDict({GROUP: {"observation": torch.zeros(T, N, OBS), "action": torch.zeros(T, N, 2)},
                       "state": torch.zeros(T, STATE), "next": nxt}, batch_size=[T])


@pytest.mark.parametrize("algo", ["ippo", "mappo"])
def test_value_target_bootstraps_at_truncation_not_at_termination(algo):
    cfg = MarlConfig(gamma=GAMMA, gae_lambda=LAMBDA, hidden=(8,))
    actor = build_actor(np.full(OBS, -1.0), np.full(OBS, 1.0), 2, (8,))
    loss = build_loss(algo, cfg, actor, _constant_critic(algo))
    targets = {}
    for terminated in (True, False):
        td = _batch(terminated)
        loss.value_estimator(td, params=loss.critic_network_params, target_params=loss.target_critic_network_params)
        targets[terminated] = td[GROUP, "value_target"][..., 0]
        assert td[GROUP, "value_target"].shape == (T, N, 1)
    # truncated: every step bootstraps, r + gamma V = 1 + 0.9 * 10 = 10 = V, so each target is V
    assert torch.allclose(targets[False], torch.full((T, N), V))
    # terminated: the last target is the reward alone; GAE carries its advantage (1 - V) back by gamma * lambda
    a2 = 1.0 - V
    a1 = (1.0 + GAMMA * V - V) + GAMMA * LAMBDA * a2
    a0 = (1.0 + GAMMA * V - V) + GAMMA * LAMBDA * a1
    expected = torch.tensor([a0 + V, a1 + V, a2 + V]).unsqueeze(-1).expand(T, N)
    assert torch.allclose(targets[True], expected, atol=1e-5)
    assert targets[True][-1, 0].item() == pytest.approx(1.0)


def test_env_marks_the_step_limit_truncated_not_terminated():
    env = EnvMaker("office", "realistic", episode_steps=4)()
    td = env.rollout(10, break_when_any_done=True)
    assert td.batch_size == (4,)
    nxt = td["next", GROUP]
    assert nxt["truncated"][-1].all() and not nxt["terminated"].any()
    assert not nxt["truncated"][:-1].any() and nxt["done"][-1].all()
    assert td["next", "state"].shape == (4, *env.base_env.observation_spec["state"].shape)


def test_saved_policy_acts_as_the_actors_deterministic_mode(tmp_path):
    from tensordict.nn import InteractionType, set_interaction_type

    from parcover_env.policies.torchrl_policy import TorchRLPolicy

    torch.manual_seed(3)
    low, high = np.array([-2.0, 0.0, -1.0]), np.array([2.0, 10.0, 3.0])
    actor = build_actor(low, high, 2, (16, 16))
    obs = torch.tensor([[1.5, 7.0, 0.2], [-1.0, 2.0, 2.9]])
    with set_interaction_type(InteractionType.DETERMINISTIC), torch.no_grad():
        expected = actor(TensorDict({GROUP: {"observation": obs}}, batch_size=[]))[GROUP, "action"].numpy()
    save_policy(actor, tmp_path / "policy.pt")
    policy = TorchRLPolicy(tmp_path)
    got = policy.act({"robot_1": obs[1].numpy(), "robot_0": obs[0].numpy()})
    assert policy.obs_shape == (3,)
    np.testing.assert_allclose(np.stack([got["robot_0"], got["robot_1"]]), expected, atol=1e-6)
    assert np.abs(expected).max() < 1.0 and np.abs(expected).max() > 0.0


def _short(backend: str, tmp_path) -> tuple[dict, list[dict]]:
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=128, minibatch_size=64, epochs=1,
                              hidden=(16,), episode_steps=50, ray_collectors=2)
    out = tmp_path / backend
    record = train(TrainRequest("ippo", "office", 500, out, cfg, "configs/train/ippo.yaml", backend=backend,
                                seed=1, command="parcover train ippo office --steps 500"))
    assert json.loads((out / "run.json").read_text()) == json.loads(json.dumps(record))
    with open(out / "curve.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return record, rows


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_short_run_writes_policy_sidecar_and_curve(backend, tmp_path):
    if backend == "ray":
        pytest.importorskip("ray")
    record, rows = _short(backend, tmp_path)
    # 500 agent-steps on 2 robots in batches of 128 env steps: 2 batches = 256 env steps = 512 agent-steps
    assert record["agent_steps"] == 512
    assert record["algo"] == "ippo" and record["scenario"] == "office" and record["init"] is None
    assert record["library"] == {"name": "torchrl", "version": md.version("torchrl")}
    assert record["backend"] == backend and record["wall_time"] > 0 and record["commit"]
    assert record["command"] == "parcover train ippo office --steps 500"
    assert record["policy"] == f"torchrl:{tmp_path / backend / 'policy.pt'}"
    # 50-step episodes. Local: one env, 2 end in the first batch (steps 50, 100), 3 in the second (150, 200,
    # 250). Ray: two collectors of 64 steps per batch, each ends one episode per batch (its steps 50 and 100)
    expected = [256, 256, 512, 512, 512] if backend == "local" else [256, 256, 512, 512]
    assert [int(r["agent_steps"]) for r in rows] == expected
    assert list(rows[0]) == ["agent_steps", "wall_time", "episode_return", "kpoi_fraction", "success"]
    assert (tmp_path / backend / "curve.png").stat().st_size > 0  # viz.curves drew the CSV
    assert all(0.0 <= float(r["kpoi_fraction"]) <= 1.0 for r in rows)

    from parcover_env import parallel_env
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy

    env = parallel_env("office", overrides=record["env_overrides"])  # the defaults train on env v2
    assert record["env_overrides"] == {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}
    metrics = run_episode(env, make_policy(record["policy"], env, 0), seed=0, max_steps=20)
    assert metrics["steps"] == 20


def test_ray_collectors_each_step_several_worlds(tmp_path):
    pytest.importorskip("ray")
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=128, minibatch_size=64, epochs=1,
                              hidden=(16,), episode_steps=50, ray_collectors=2, worlds=2)
    record = train(TrainRequest("ippo", "office", 500, tmp_path / "rw", cfg, "x", backend="ray", seed=1))
    assert record["agent_steps"] == 512 and record["backend"] == "ray"
    with open(tmp_path / "rw" / "curve.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    # 2 collectors x 2 worlds, 32 env steps of each world per batch of 128: no 50-step episode ends in the
    # first batch; in the second, each of the 4 worlds ends one (its step 50)
    assert [int(r["agent_steps"]) for r in rows] == [512] * 4


def test_mappo_critic_reads_the_state_ippo_critic_does_not():
    torch.manual_seed(0)
    obs, state = torch.randn(N, OBS), torch.randn(STATE)
    for algo, reads_state in (("mappo", True), ("ippo", False)):
        critic = build_critic(algo, _box(OBS), _box(STATE), MarlConfig(hidden=(8,)))
        values = [critic(TensorDict({GROUP: {"observation": obs}, "state": s}, batch_size=[]))[GROUP, "state_value"]
                  for s in (state, state + 1.0)]
        assert values[0].shape == (N, 1)
        assert (not torch.allclose(values[0], values[1])) == reads_state
        assert ("state" in critic.in_keys) == reads_state


def test_same_seed_same_policy_local(tmp_path):
    cfg = dataclasses.replace(load_marl_config("mappo"), frames_per_batch=64, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=30)
    weights = []
    for seed in (5, 5, 6):
        out = tmp_path / f"s{seed}_{len(weights)}"
        train(TrainRequest("mappo", "office", 256, out, cfg, "x", seed=seed))
        weights.append(torch.load(out / "policy.pt")["state_dict"])
    same = [all(torch.equal(weights[0][k], w[k]) for k in w) for w in weights[1:]]
    assert same == [True, False]

"""``obs_scale: rollout`` by value: the fitted centre and half-width of hand-built observations, the
padding left out, the box kept where nothing varies, the floor, and a training run whose first batch
sets the actor's and IPPO critic's scale (and is not learned from)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.harness import marl  # noqa: E402
from parcover_env.harness.marl import TrainRequest, build_critic, critic_scale, train  # noqa: E402
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.harness.marl_init import critic_spec  # noqa: E402
from parcover_env.harness.marl_scale import fit_scale, observation_stats  # noqa: E402
from parcover_env.policies.torchrl_policy import TorchRLPolicy, box_scale  # noqa: E402

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}
LAB_CONFIGS = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"
"""Training configs of staged runs that are no README row (moved out of configs/train/)."""



def _obs():
    """2 steps x 3 agents x 3 entries; agent 2 is padding (wild values that must not count)."""
    obs = torch.tensor([[[1.0, 5.0, 0.3], [3.0, 5.0, 0.1], [100.0, -100.0, 50.0]],
                        [[1.0, 5.0, 0.3], [3.0, 5.0, 0.1], [100.0, -100.0, 50.0]]])
    real = torch.tensor([[[True], [True], [False]], [[True], [True], [False]]])
    return obs, real


def test_observation_stats_over_the_real_robots_only():
    obs, real = _obs()
    mean, std = observation_stats(obs, real)
    assert torch.allclose(mean, torch.tensor([2.0, 5.0, 0.2], dtype=torch.float64))
    assert torch.allclose(std, torch.tensor([1.0, 0.0, 0.1], dtype=torch.float64))
    mean_all, _ = observation_stats(obs)  # no mask: the padding counts
    assert mean_all[0] == pytest.approx(104.0 / 3)
    with pytest.raises(ValueError, match="^no real robot.s observation to fit the scale to$"):
        observation_stats(obs, torch.zeros_like(real))


def test_fit_scale_sets_mean_and_std_keeps_the_box_where_nothing_varies_and_floors_small_spreads():
    obs, real = _obs()
    scale = box_scale(np.array([-10.0, 0.0, -50.0]), np.array([10.0, 20.0, 50.0]))  # centre (0, 10, 0), hw (10, 10, 50)
    fit_scale(scale, obs, real, floor=0.01)
    assert torch.allclose(scale.centre, torch.tensor([2.0, 10.0, 0.2]))  # entry 1 constant: the box centre
    # entry 0: its std 1; entry 1: the box's 10; entry 2: std 0.1 < 0.01 x 50 -> the floor 0.5
    assert torch.allclose(scale.half_width, torch.tensor([1.0, 10.0, 0.5]))
    assert torch.allclose(scale(torch.tensor([3.0, 5.0, 0.7])), torch.tensor([1.0, -0.5, 1.0]))


def test_ippo_critic_gets_an_input_scale_only_when_asked():
    box = spaces.Box(np.array([-4.0, 0.0], np.float32), np.array([4.0, 2.0], np.float32))
    plain = build_critic("ippo", box, box, MarlConfig(hidden=(4,)))
    scaled = build_critic("ippo", box, box, MarlConfig(hidden=(4,), obs_scale="rollout"))
    assert critic_scale(plain) is None
    assert torch.allclose(critic_scale(scaled).half_width, torch.tensor([4.0, 1.0]))
    assert critic_scale(build_critic("mappo", box, box, MarlConfig(hidden=(4,), obs_scale="rollout"))) is None
    # the critic spec tells a scaled IPPO critic from a box one (--init loads only the same kind)
    assert critic_spec("ippo", MarlConfig(obs_scale="rollout"), 2, 0)["obs_scale"] == "rollout"
    assert "obs_scale" not in critic_spec("ippo", MarlConfig(), 2, 0)
    assert "obs_scale" not in critic_spec("mappo", MarlConfig(obs_scale="rollout"), 2, 3)


def test_training_fits_the_scale_to_the_first_batch_and_learns_from_the_later_ones(tmp_path, monkeypatch):
    seen = {}
    original = marl.fit_scale

    def recording(scale, obs, real=None, floor=0.01):
        seen.setdefault("obs", []).append(obs.clone())
        seen["real"] = real
        original(scale, obs, real, floor)

    steps = []
    original_opt = torch.optim.Adam.step

    def counting(self, *a, **k):
        steps.append(1)
        return original_opt(self, *a, **k)

    monkeypatch.setattr(marl, "fit_scale", recording)
    monkeypatch.setattr(torch.optim.Adam, "step", counting)
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=32, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=20, env=V2, obs_scale="rollout")
    train(TrainRequest("ippo", "office", 3 * 32 * 2, tmp_path, cfg, "x"))
    assert len(seen["obs"]) == 2  # the actor's scale and the critic's, from the same (first) batch
    obs = seen["obs"][0]
    mean, std = observation_stats(obs, seen["real"])
    policy = TorchRLPolicy(tmp_path / "policy.pt").net[0]  # saved with the weights
    box = marl.EnvMaker("office", "realistic", 20, overrides=V2).parallel().observation_space("robot_0")
    box_hw = (box.high - box.low) / 2
    varies = std.numpy() > 0
    assert varies.sum() > 10
    expect = np.where(varies, np.maximum(std.numpy(), 0.01 * box_hw), np.maximum(box_hw, 1e-6))
    assert np.allclose(policy.half_width.numpy(), expect, rtol=1e-5)
    assert np.allclose(policy.centre.numpy()[varies], mean.numpy()[varies], atol=1e-5)
    assert len(steps) == 2  # three batches: the first only sets the scale, each later one one update


def test_box_scale_is_the_default_and_untouched(tmp_path):
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=32, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=20, env=V2)
    assert cfg.obs_scale == "box"
    train(TrainRequest("ippo", "office", 32 * 2, tmp_path, cfg, "x"))
    net = TorchRLPolicy(tmp_path / "policy.pt").net
    box = marl.EnvMaker("office", "realistic", 20, overrides=V2).parallel().observation_space("robot_0")
    assert np.allclose(net[0].centre.numpy(), (box.low + box.high) / 2)


def test_the_generated_scaled_config_loads_with_its_stated_changes():
    base = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_worlds.yaml")
    cfg = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_scaled.yaml")
    assert (cfg.obs_scale, cfg.episode_steps) == ("rollout", 0)  # the two changes its comments give
    same = {f.name for f in dataclasses.fields(MarlConfig)} - {"obs_scale", "episode_steps", "wall_time"}
    assert all(getattr(cfg, k) == getattr(base, k) for k in same)


def test_shipped_scaled_checkpoint_loads_with_its_fitted_input_scale():
    import json

    import parcover_env
    from parcover_env.harness.map_pool import MapPoolEnv

    root = Path(parcover_env.__file__).resolve().parent.parent / "baselines" / "checkpoints" / "ippo_generated_scaled"
    if not root.is_dir():
        pytest.skip("source checkout only")
    run = json.loads((root / "run.json").read_text())
    assert run["policy"] == "torchrl:baselines/checkpoints/ippo_generated_scaled/policy.pt"
    assert run["config"]["obs_scale"] == "rollout" and run["init"]["init"] is None  # from scratch, curriculum
    assert run["init_run"]["init"] is None and run["init_run"]["config"]["entropy_coeff"] == 0.005
    scale = TorchRLPolicy(root / "policy.pt").net[0]
    pool = MapPoolEnv("generated:3-4", overrides=run["env_overrides"])
    box = pool.observation_space("robot_0")
    goal = pool.env.layout.slices["goal_dx"]
    assert (box.high - box.low)[goal][0] / 2 == pytest.approx(21.8, abs=0.1)  # the box's half-width
    assert 0.1 < scale.half_width[goal].item() < 1.0  # fitted: the goal's spread, well under the box's

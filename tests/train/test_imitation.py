"""``parcover train bc``: the imitation loss by value, the fit, the sidecar, ``--init`` into PPO, bad input."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env.cli.main import main  # noqa: E402
from parcover_env.errors import ArgumentError, ConfigError  # noqa: E402
from parcover_env.harness.marl import TrainRequest, build_actor, policy_net, train  # noqa: E402
from parcover_env.harness.marl_config import load_marl_config  # noqa: E402
from parcover_env.policies.registry import make_policy  # noqa: E402
from parcover_env.policies.torchrl_policy import TorchRLPolicy  # noqa: E402
from parcover_env.train.imitation import (  # noqa: E402
    Demonstrations,
    ImitationRequest,
    episode_maps,
    fit,
    imitate,
    imitation_loss,
    record,
)

LOW, HIGH = np.full(4, -2.0), np.full(4, 2.0)


def fixed_actor(head: str, act_dim: int, bias: list[float]):
    """An actor whose output is ``bias`` whatever the observation (last layer's weights zero)."""
    torch.manual_seed(0)
    actor = build_actor(LOW, HIGH, act_dim, (5,), head)
    last = policy_net(actor)[-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.copy_(torch.tensor(bias))
    return actor


def test_bernoulli_head_loss_is_the_drive_squared_error_plus_the_scan_label_nll():
    # loc (0.2, -0.3), pre-scale 0, scan logit 1.5: tanh(loc) = (0.19738, -0.29131)
    actor = fixed_actor("bernoulli", 3, [0.2, -0.3, 0.0, 0.0, 1.5])
    obs = torch.zeros(2, 4)
    actions = torch.tensor([[0.5, -0.5, 1.0], [1.0, 0.0, -1.0]])  # a scan, then none
    parts = {k: float(v.detach()) for k, v in imitation_loss(actor, obs, actions).items()}
    scan = (math.log1p(math.exp(-1.5)) + math.log1p(math.exp(1.5))) / 2  # softplus(-l) for 1, softplus(l) for 0
    assert parts["scan"] == pytest.approx(scan, rel=1e-6)
    assert scan == pytest.approx((0.201413 + 1.701413) / 2, abs=1e-6)
    v, w = math.tanh(0.2), math.tanh(-0.3)
    drive = ((0.5 - v) ** 2 + (-0.5 - w) ** 2 + (1.0 - v) ** 2 + (0.0 - w) ** 2) / 2
    assert parts["drive"] == pytest.approx(drive, rel=1e-5)
    assert drive == pytest.approx(0.43210, abs=1e-4)  # 0.09158 + 0.04355 + 0.64420 + 0.08486, halved
    assert parts["loss"] == pytest.approx(drive + scan, rel=1e-5)
    only_scans = imitation_loss(actor, obs, torch.tensor([[0.5, -0.5, 1.0], [0.5, -0.5, 1.0]]))
    assert float(only_scans["scan"].detach()) == pytest.approx(math.log1p(math.exp(-1.5)), rel=1e-6)  # 0.2014
    no_scans = imitation_loss(actor, obs, torch.tensor([[0.5, -0.5, 0.0], [0.5, -0.5, -1.0]]))
    assert float(no_scans["scan"].detach()) == pytest.approx(math.log1p(math.exp(1.5)), rel=1e-6)  # label is scan > 0


def test_continuous_head_loss_covers_every_component_and_has_no_scan_term():
    actor = fixed_actor("continuous", 2, [0.4, -1.0, 3.0, 0.0])  # loc (0.4, -1.0); the scales do not enter
    parts = imitation_loss(actor, torch.zeros(1, 4), torch.tensor([[0.3, -1.0]]))
    assert float(parts["scan"].detach()) == 0.0
    assert float(parts["drive"].detach()) == pytest.approx((0.3 - math.tanh(0.4)) ** 2 + (-1.0 - math.tanh(-1.0)) ** 2,
                                                  rel=1e-5)


def test_a_few_hundred_steps_make_the_deterministic_action_the_label():
    rng = np.random.default_rng(3)
    obs = rng.uniform(-2, 2, (8, 4)).astype(np.float32)
    drive = rng.uniform(-0.8, 0.8, (8, 2)).astype(np.float32)
    scan = np.array([1, -1, -1, 1, -1, 1, 1, -1], np.float32)[:, None]
    data = Demonstrations(obs, np.concatenate([drive, scan], axis=1))
    torch.manual_seed(1)
    actor = build_actor(LOW, HIGH, 3, (64,), "bernoulli")
    before = TorchRLPolicy.from_net(policy_net(actor), 3, "bernoulli").act({f"r{i}": o for i, o in enumerate(obs)})
    losses, _ = fit(actor, data, 600, 1e-2, 8, torch.Generator().manual_seed(0))
    assert losses[-1] < losses[0] / 100
    policy = TorchRLPolicy.from_net(policy_net(actor), 3, "bernoulli")  # what torchrl:DIR runs
    acts = policy.act({f"r{i}": o for i, o in enumerate(obs)})
    got = np.stack([acts[f"r{i}"] for i in range(8)])
    np.testing.assert_allclose(got[:, :2], drive, atol=0.05)
    np.testing.assert_array_equal(got[:, 2], scan[:, 0])  # the scan mode, exactly the labels
    assert not np.array_equal(np.stack([before[f"r{i}"] for i in range(8)])[:, 2], scan[:, 0])


def test_pool_episodes_take_the_maps_in_turn_and_a_scenario_stays_itself():
    assert episode_maps("generated:3-5", 2, 4) == ["generated:5", "generated:3", "generated:4", "generated:5"]
    assert episode_maps("office", 0, 2) == ["office", "office"]


@pytest.fixture(scope="module")
def small_config():
    return dataclasses.replace(load_marl_config("ippo"), hidden=(8,), minibatch_size=16, frames_per_batch=32,
                               epochs=1)


@pytest.fixture(scope="module")
def dagger_run(tmp_path_factory, small_config):
    out = tmp_path_factory.mktemp("bc") / "run"
    req = ImitationRequest("office", 20, out, small_config, "cfg.yaml", episodes=1, dagger_rounds=1, seed=4,
                           max_steps=6)
    return req, imitate(req, log=lambda line: None)


def test_the_sidecar_says_imitation_and_the_data(dagger_run):
    req, record = dagger_run
    on_disk = json.loads((req.out / "run.json").read_text())
    assert on_disk == record
    assert record["algo"] == "dagger" and "imitation" in record["made_by"] and "expert" in record["made_by"]
    data = record["data"]
    assert (data["scenario"], data["episodes"], data["rounds"], data["seeds"]) == ("office", 2, 1, [4, 5])
    rounds = record["fit"]["rounds"]
    assert [r["driver"] for r in rounds] == ["expert", "learner"]
    assert data["samples"] == rounds[0]["new_samples"] + rounds[1]["new_samples"] == rounds[1]["samples"]
    from parcover_env import parallel_env

    robots = len(parallel_env("office").possible_agents)
    assert rounds[0]["new_samples"] == rounds[1]["new_samples"] == 6 * robots  # 6 steps of every robot
    assert record["policy"] == f"torchrl:{req.out / 'policy.pt'}" and record["env_overrides"] == req.config.env
    assert record["config"]["hidden"] == [8] and record["fit"]["steps_per_round"] == 20
    assert data["episodes_per_round"] == 1 and data["labeller"] == "expert" and data["preset"] == "realistic"
    fitted = record["fit"]
    assert (fitted["batch_size"], fitted["learning_rate"], fitted["max_grad_norm"]) == (16, 3e-4, 0.5)
    assert fitted["drive_loss"].startswith("squared error of tanh(loc)") and fitted["scan_loss"] is None
    assert [r["round"] for r in rounds] == [0, 1] and all(r["final_loss"] >= 0 for r in rounds)
    assert record["made_by"].startswith("imitation: DAgger, 1 round(s) after behaviour cloning")
    assert record["library"]["name"] == "torchrl" and record["library"]["version"]
    assert (record["agent_steps"], record["episodes"], record["init"]) == (0, 2, None)
    assert record["scan_head"] == "continuous"
    assert record["wall_time"] > 0 and record["config_file"] == "cfg.yaml" and "commit" in record
    assert (record["scenario"], record["seed"], record["command"]) == ("office", 4, "")


def test_bc_without_rounds_is_bc_and_its_samples_are_the_expert_steps(tmp_path, small_config):
    from parcover_env.harness.datasets import record_episodes

    req = ImitationRequest("office", 5, tmp_path / "bc", small_config, "cfg.yaml", episodes=2, seed=7, max_steps=4)
    record = imitate(req, log=lambda line: None)
    expert = record_episodes("office", 1, seed=7, max_steps=4, overrides=small_config.env)
    expert += record_episodes("office", 1, seed=8, max_steps=4, overrides=small_config.env)
    assert record["algo"] == "bc" and record["data"]["rounds"] == 0 and record["data"]["seeds"] == [7, 8]
    assert record["made_by"].startswith("imitation: behaviour cloning of the scripted expert")
    assert record["data"]["samples"] == sum(len(e["actions"]) for e in expert)
    again = imitate(dataclasses.replace(req, out=tmp_path / "again"), log=lambda line: None)
    a, b = (torch.load(d / "policy.pt", weights_only=True)["state_dict"] for d in (tmp_path / "bc", tmp_path / "again"))
    assert all(torch.equal(a[k], b[k]) for k in a) and again["data"] == record["data"]  # same seed, same fit


def test_record_takes_seed_plus_index_and_a_driver_drives_while_the_expert_labels(small_config):
    from parcover_env.harness.datasets import record_episodes

    req = ImitationRequest("office", 1, None, small_config, "x", episodes=1, seed=4, max_steps=5)
    expert = record(req, 1, None)  # episode 1: seed 5
    same = record_episodes("office", 1, seed=5, max_steps=5, overrides=small_config.env)
    np.testing.assert_array_equal(expert.observations, np.concatenate([e["observations"][:-1] for e in same]))
    np.testing.assert_array_equal(expert.actions, np.concatenate([e["actions"] for e in same]))
    driven = record(req, 1, "random")
    labels = record_episodes("office", 1, seed=5, max_steps=5, overrides=small_config.env, driver="random")
    np.testing.assert_array_equal(driven.actions, np.concatenate([e["actions"] for e in labels]))
    assert not np.array_equal(driven.observations, expert.observations)  # the random team went elsewhere


def test_dagger_rounds_record_new_seeds_driven_by_the_saved_actor(tmp_path, small_config, monkeypatch):
    from parcover_env.train import imitation

    calls = []

    def spy(req, first, driver):
        calls.append((first, driver, (req.out / "policy.pt").is_file()))
        return record(req, first, None)

    monkeypatch.setattr(imitation, "record", spy)
    req = ImitationRequest("office", 2, tmp_path / "d", small_config, "x", episodes=2, dagger_rounds=2, max_steps=3)
    imitate(req, log=lambda line: None)
    driver = f"torchrl:{tmp_path / 'd' / 'policy.pt'}"
    assert calls == [(0, None, False), (2, driver, True), (4, driver, True)]


def test_rollout_obs_scale_is_fitted_on_the_expert_observations(tmp_path, small_config):
    cfg = dataclasses.replace(small_config, obs_scale="rollout")
    req = ImitationRequest("office", 1, tmp_path / "r", cfg, "x", episodes=1, seed=2, max_steps=4)
    imitate(req, log=lambda line: None)
    centre = torch.load(tmp_path / "r" / "policy.pt", weights_only=True)["state_dict"]["0.centre"]
    data = record(req, 0, None)
    box = imitate(dataclasses.replace(req, config=small_config, out=tmp_path / "b"), log=lambda line: None)
    kept = torch.load(tmp_path / "b" / "policy.pt", weights_only=True)["state_dict"]["0.centre"]
    from parcover_env import parallel_env

    space = parallel_env("office", overrides=small_config.env).observation_space("robot_0")
    np.testing.assert_allclose(kept.numpy(), (space.low + space.high) / 2, rtol=1e-6)  # obs_scale box: the box's
    assert box["config"]["obs_scale"] == "box"
    varies = data.observations.astype(np.float64).std(axis=0) > 0  # a constant entry keeps its box centre
    assert varies.sum() > 40
    np.testing.assert_allclose(centre.numpy()[varies], data.observations.mean(axis=0)[varies], rtol=1e-5, atol=1e-6)


def test_the_policy_evaluates_as_torchrl_spec(dagger_run):
    from parcover_env import parallel_env

    req, record = dagger_run
    env = parallel_env("office", overrides=req.config.env)
    obs, _ = env.reset(seed=1000)
    policy = make_policy(record["policy"], env, 1000)
    actions = policy.act(obs)
    assert set(actions) == set(obs) and all(a.shape == (2,) and np.all(np.abs(a) <= 1) for a in actions.values())


def test_ppo_init_from_bc_loads_and_its_first_batch_is_the_bc_actor(dagger_run, tmp_path):
    req, _ = dagger_run
    cfg = dataclasses.replace(req.config, episode_steps=8)
    seen = []
    record = train(TrainRequest("ippo", "office", 32, tmp_path / "ppo", cfg, "x", seed=2, init=str(req.out)),
                   on_batch=lambda batch, c, u: seen.append(batch) or True)
    assert record["init"] == {"path": str(req.out), "algo": "dagger", "init": None, "critic": False}
    bc = TorchRLPolicy(req.out / "policy.pt")
    batch = seen[0]
    with torch.no_grad():
        out = bc.net(batch.get(("robot", "observation")))
    torch.testing.assert_close(batch.get(("robot", "loc")), out[..., :2], rtol=0, atol=0)


def test_the_init_line_says_an_imitation_run_has_no_critic():
    from parcover_env.cli.train import init_line

    record = {"path": "runs/bc", "algo": "dagger", "init": None, "critic": False}
    assert init_line(record) == "started from runs/bc (a dagger run: the critic from scratch)"
    assert init_line({**record, "algo": "ippo"}) == "started from runs/bc (critic from scratch: another kind or size)"


def test_bad_requests_are_one_error():
    cfg = load_marl_config("ippo")
    with pytest.raises(ArgumentError, match="--episodes must be >= 1, got 0"):
        ImitationRequest("office", 1, None, cfg, "x", episodes=0).check()
    with pytest.raises(ArgumentError, match="--dagger-rounds must be >= 0, got -1"):
        ImitationRequest("office", 1, None, cfg, "x", dagger_rounds=-1).check()
    with pytest.raises(ArgumentError, match="--steps must be >= 1, got 0"):
        ImitationRequest("office", 0, None, cfg, "x").check()
    with pytest.raises(ArgumentError, match=r"--seed 995 with 5 episodes x 3 round\(s\) records seeds up to 1009"):
        ImitationRequest("office", 1, None, cfg, "x", seed=995, episodes=5, dagger_rounds=2).check()
    with pytest.raises(ConfigError, match="evaluation maps"):
        ImitationRequest("generated:990-1005", 1, None, cfg, "x").check()


@pytest.mark.parametrize(("extra", "words"), [
    (["--episodes", "0"], "--episodes must be >= 1"),
    (["--dagger-rounds", "-2"], "--dagger-rounds must be >= 0"),
    (["--seed", "999", "--episodes", "2"], "evaluation seeds"),
    (["--init", "somewhere"], "--init is for parcover train ippo|mappo"),
])
def test_cli_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, extra, words):
    out = tmp_path / "out"
    assert main(["train", "bc", "office", "--steps", "10", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_cli_evaluation_pool_and_ppo_with_episodes_exit_2(tmp_path, capsys):
    assert main(["train", "bc", "generated:990-1001", "--steps", "10", "--out", str(tmp_path / "o")]) == 2
    assert "evaluation maps" in capsys.readouterr().err
    assert main(["train", "ippo", "office", "--steps", "10", "--out", str(tmp_path / "p"), "--episodes", "3"]) == 2
    assert "--episodes is for parcover train bc, not ippo" in capsys.readouterr().err

"""Baseline scripts with tiny budgets: PPO trains and saves (BC init, curriculum, resume, init), evaluate runs."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

@pytest.fixture(scope="module")
def ppo_dir(tmp_path_factory, load_baseline):
    train_ppo = load_baseline("train_ppo")
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
    assert rows[0].startswith("timesteps,wall_time,stage,return") and len(rows) > 1


def test_ppo_policy_acts_in_the_box(ppo_dir):
    from parcover_env import parallel_env
    from parcover_env.policies.learned import PPOPolicy

    env = parallel_env("office")
    obs, _ = env.reset(seed=0)
    acts = PPOPolicy(ppo_dir).act(obs)
    assert set(acts) == set(obs)
    assert all(a.shape == (2,) and np.all(np.abs(a) <= 1) for a in acts.values())


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


def test_evaluate_random_runs(capsys, load_baseline):
    evaluate = load_baseline("evaluate")
    assert evaluate.main(["--policy", "random", "--seeds", "2", "--max-steps", "20"]) == 0
    out = capsys.readouterr().out
    assert "random on office (realistic), 2 episodes" in out and "| office | random | 2 | 0.00 [" in out


@pytest.fixture(scope="module")
def curriculum_dir(tmp_path_factory, load_baseline):
    """Two stages with different team sizes (office: 2 robots, generated:3: 3 robots), BC init."""
    train_ppo = load_baseline("train_ppo")
    out = tmp_path_factory.mktemp("cur")
    cfg = out / "cur.yaml"
    cfg.write_text("stages:\n  - {scenario: office, steps: 600, n_envs: 1}\n"
                   "  - {scenario: 'generated:3', steps: 600, n_envs: 1}\n")
    args = train_ppo.parse_args(["--curriculum", str(cfg), "--n-steps", "128", "--batch-size", "128",
                                 "--n-epochs", "1", "--max-steps", "60", "--net-arch", "32",
                                 "--eval-freq", "500", "--eval-episodes", "1", "--checkpoint-freq", "500",
                                 "--bc-episodes", "1", "--bc-epochs", "3", "--out", str(out / "run")])
    train_ppo.train(args)
    return out / "run", train_ppo


def test_curriculum_switches_team_size_and_writes_sidecar(curriculum_dir):
    import json

    out, _ = curriculum_dir
    side = json.loads((out / "model.json").read_text())
    assert side["command"].startswith("python ") and "--curriculum" in side["command"]
    assert len(side["git_commit"]) >= 40 and side["preset"] == "realistic"
    assert [s["scenarios"] for s in side["train_seeds"]] == [["office"], ["generated:3"]]
    # stage 0: 1 env x 2 robots x 128 steps per rollout until >= 600 agent-steps (3 rollouts = 768);
    # stage 1: 3 robots x 128 = 384 per rollout, two rollouts to reach 600 more -> 768 + 768
    assert side["timesteps"] == 768 + 768
    assert side["versions"]["stable-baselines3"] != "not installed"
    assert side["bc_missions"] == 1 and side["bc_samples"] > 0
    ev = (out / "eval.csv").read_text().splitlines()
    seeds = {int(line.split(",")[4]) for line in ev[1:]}
    assert seeds == {500}  # validation seeds: neither training (< 100) nor benchmark (>= 1000)
    # checkpoints every 500 agent-steps, named by the step count at which they were taken
    # (stage 0 counts in 2s, stage 1 from 768 in 3s)
    assert {p.name for p in (out / "checkpoints").glob("*.zip")} == {"step_500.zip", "step_1002.zip", "step_1500.zip"}
    assert (out / "checkpoints" / "step_500_vecnormalize.pkl").is_file()
    assert (out / "bc_init" / "model.zip").is_file() and (out / "curve.png").stat().st_size > 1000


def test_resume_continues_the_step_count(curriculum_dir, tmp_path):
    import json

    out, train_ppo = curriculum_dir
    args = train_ppo.parse_args(["--scenario", "office", "--n-envs", "1", "--total-timesteps", "1000",
                                 "--n-steps", "128", "--batch-size", "128", "--n-epochs", "1", "--max-steps", "60",
                                 "--eval-freq", "0", "--checkpoint-freq", "0",
                                 "--resume", str(out / "checkpoints" / "step_500.zip"), "--out", str(tmp_path)])
    train_ppo.train(args)
    side = json.loads((tmp_path / "model.json").read_text())
    # 500 done of 1000: two more rollouts of 2 x 128 = 256 agent-steps -> 1012
    assert side["resumed_from"]["num_timesteps"] == 500 and side["timesteps"] == 1012


@pytest.fixture(scope="module")
def tiny_datasets(tmp_path_factory):
    """Two Minari datasets of one short expert mission on office (as ``parcover collect`` writes)."""
    pytest.importorskip("minari")
    pytest.importorskip("h5py")
    from parcover_env.harness.datasets import record_episodes, save_minari

    root = tmp_path_factory.mktemp("datasets")
    eps = record_episodes("office", 2, seed=7, max_steps=40)
    save_minari(eps[:2], "parcover/tiny-a-expert-v0", root, "office")
    save_minari(eps[2:], "parcover/tiny-b-expert-v0", root, "office")
    obs = np.concatenate([e["observations"][:-1] for e in eps])
    act = np.clip(np.concatenate([e["actions"] for e in eps]), -1, 1)
    return root, obs, act


def _policy_mse(policy, obs, act) -> float:
    pred = policy.act({f"r{i:04d}": o for i, o in enumerate(obs)})
    return float(np.mean((np.stack([pred[f"r{i:04d}"] for i in range(len(obs))]) - act) ** 2))


def test_ppo_bc_init_from_minari_datasets_imitates_the_expert(tiny_datasets, tmp_path, load_baseline):
    import json

    from stable_baselines3 import PPO

    from parcover_env.policies.learned import PPOPolicy

    root, obs, act = tiny_datasets
    train_ppo = load_baseline("train_ppo")
    args = train_ppo.parse_args(["--scenario", "office", "--n-envs", "1", "--total-timesteps", "256",
                                 "--n-steps", "128", "--batch-size", "128", "--n-epochs", "1", "--max-steps", "40",
                                 "--net-arch", "64,64", "--bc-datasets", "parcover/tiny-*-expert-v0",
                                 "--bc-dataset-root", str(root), "--bc-epochs", "60", "--bc-coef", "1.0",
                                 "--bc-batches", "2", "--eval-freq", "128", "--eval-episodes", "1",
                                 "--eval-scenarios", "office", "--checkpoint-freq", "0", "--out", str(tmp_path)])
    train_ppo.train(args)
    side = json.loads((tmp_path / "model.json").read_text())
    assert side["bc_datasets"] == ["parcover/tiny-a-expert-v0", "parcover/tiny-b-expert-v0"]
    assert side["bc_robot_episodes"] == 4 and side["bc_samples"] == len(obs) == 160  # 2 missions x 2 robots x 40
    cloned = PPOPolicy(tmp_path / "bc_init")
    untrained = PPOPolicy(tmp_path / "bc_init")
    fresh = PPO("MlpPolicy", untrained.model.env or train_ppo.make_venv(args, ["office"], 0), seed=1,
                policy_kwargs={"net_arch": [64, 64]})
    untrained.model.policy.load_state_dict(fresh.policy.state_dict())
    mse_bc, mse_raw = _policy_mse(cloned, obs, act), _policy_mse(untrained, obs, act)
    assert mse_bc < 0.3 * mse_raw and mse_bc < 0.05, (mse_bc, mse_raw)
    # the kept network is the one with the best validation score (ties: the earlier one)
    rows = [line.split(",") for line in (tmp_path / "eval.csv").read_text().splitlines()]
    head = rows[0]
    by_step: dict[int, list[float]] = {}
    for r in rows[1:]:
        by_step.setdefault(int(r[head.index("timesteps")]), []).append(float(r[head.index("kpoi_fraction")]))
    assert min(by_step) == 0  # the BC start was evaluated too
    best = json.loads((tmp_path / "best" / "model.json").read_text())
    top = max(np.mean(v) for v in by_step.values())
    assert best["timesteps"] == min(s for s, v in by_step.items() if np.mean(v) == top)
    assert (tmp_path / "best" / "model.zip").is_file() and best["selected_by"] == "validation"


def test_bc_regularizer_pulls_the_actor_to_the_expert(tiny_datasets, load_baseline):
    import torch
    from stable_baselines3 import PPO

    root, obs, act = tiny_datasets
    train_ppo = load_baseline("train_ppo")
    args = train_ppo.parse_args(["--n-envs", "1", "--max-steps", "40"])
    venv = train_ppo.make_venv(args, ["office"], 0)
    venv.obs_rms.mean, venv.obs_rms.var = obs.mean(0), obs.var(0)
    model = PPO("MlpPolicy", venv, learning_rate=1e-3, seed=0, policy_kwargs={"net_arch": [64, 64]})
    reg = train_ppo.BCRegularizer([{"observations": np.vstack([obs, obs[:1]]), "actions": act}], coef=1.0,
                                  batches=100, batch_size=64, seed=0)

    def mse() -> float:
        with torch.no_grad():
            x = torch.as_tensor(venv.normalize_obs(obs.astype(np.float32)))
            return float(torch.mean((model.policy.get_distribution(x).distribution.mean - torch.as_tensor(act)) ** 2))

    before = mse()
    reg.step(model, venv)
    assert mse() < 0.2 * before
    reg.coef = 0.0  # a zero weight leaves the network alone
    after = mse()
    reg.step(model, venv)
    assert mse() == pytest.approx(after)
    venv.close()


def test_init_fine_tunes_a_network_with_this_runs_settings_and_a_value_warm_up(ppo_dir, tmp_path, load_baseline):
    """--init starts from a network (steps from 0, this run's learning rate and clipping); during
    --vf-warmup only the critic learns, afterwards the actor too."""
    import json

    import torch
    from stable_baselines3 import PPO

    train_ppo = load_baseline("train_ppo")
    start = PPO.load(str(ppo_dir / "model.zip"))
    base = ["--scenario", "office", "--n-envs", "1", "--n-steps", "128", "--batch-size", "128", "--n-epochs", "2",
            "--max-steps", "60", "--learning-rate", "1e-3", "--clip-range", "0.15", "--vf-warmup", "500",
            "--eval-freq", "0", "--checkpoint-freq", "0", "--init", str(ppo_dir / "model.zip")]

    def run(steps: str, name: str):
        out = train_ppo.train(train_ppo.parse_args([*base, "--total-timesteps", steps, "--out", str(tmp_path / name)]))
        return out, PPO.load(str(out / "model.zip"))

    def same(a, b) -> bool:
        return all(torch.equal(x, y) for x, y in zip(a.parameters(), b.parameters(), strict=True))

    out, tuned = run("1000", "warm")
    side = json.loads((out / "model.json").read_text())
    assert side["init_from"] == str(ppo_dir / "model.zip") and side["timesteps"] == 1024  # 4 rollouts x 2 x 128
    assert tuned.learning_rate == 1e-3 and tuned.clip_range(1.0) == 0.15
    assert not same(start.policy.action_net, tuned.policy.action_net)  # the actor learned after the warm-up
    _, cold = run("500", "cold")  # the whole run inside the warm-up
    assert same(start.policy.action_net, cold.policy.action_net)  # the actor did not move ...
    assert same(start.policy.mlp_extractor.policy_net, cold.policy.mlp_extractor.policy_net)
    assert not same(start.policy.value_net, cold.policy.value_net)  # ... the critic did
    with pytest.raises(SystemExit, match="exclude each other"):
        train_ppo.train(train_ppo.parse_args(["--init", "a.zip", "--resume", "b.zip", "--out", str(tmp_path / "x")]))

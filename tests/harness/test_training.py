"""The trainers' shared pieces live in the package: no trainer imports another; values of the helpers."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from parcover_env.harness import sb3_training, training

BASELINES = Path(__file__).resolve().parents[2] / "baselines"


def test_no_trainer_imports_another():
    scripts = {p.stem for p in BASELINES.glob("*.py")}
    found = []
    for path in BASELINES.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            found += [f"{path.name} imports {n}" for n in names if n.split(".")[0] in scripts]
    assert found == []


def test_discounted_returns_by_hand():
    to_go, running = sb3_training._discounted([1.0, 0.0, 2.0], 0.5)
    np.testing.assert_allclose(to_go, [1.0 + 0.5 * 1.0, 0.0 + 0.5 * 2.0, 2.0])  # g_t = r_t + gamma g_{t+1}
    np.testing.assert_allclose(running, [1.0, 0.5, 0.25 + 2.0])  # acc_t = gamma acc_{t-1} + r_t


def test_run_record_sidecar_and_csv(tmp_path):
    rec = training.RunRecord(Path("baselines/train_x.py"), ["--out", "runs/a b"], "abc123")
    rec.write_sidecar(tmp_path / "model.json", {"seed": 3})
    side = json.loads((tmp_path / "model.json").read_text())
    assert side["command"] == "python baselines/train_x.py --out 'runs/a b'" and side["git_commit"] == "abc123"
    assert side["seed"] == 3 and side["versions"]["numpy"] == np.__version__
    training.write_csv(tmp_path / "c.csv", [{"a": 1, "b": 2}, {"a": 3, "b": 4}])
    assert (tmp_path / "c.csv").read_text().splitlines() == ["a,b", "1,2", "3,4"]
    training.write_csv(tmp_path / "none.csv", [])
    assert not (tmp_path / "none.csv").exists()


def test_bc_initialize_sets_the_statistics_from_the_demonstrations_and_fits_them():
    """The VecNormalize statistics become the demonstrations' (observations without the last of each
    episode; the running discounted return's variance), the log-std is set, and the cloned mean action
    approaches the demonstrated one (actions clipped to the box first)."""
    pytest.importorskip("stable_baselines3")
    torch = pytest.importorskip("torch")
    from stable_baselines3 import PPO

    venv = sb3_training.make_sb3_venv(["office"], 0, preset="realistic", gamma=0.5)
    dim = venv.observation_space.shape[0]
    rng = np.random.default_rng(0)
    eps = []
    for n in (30, 20):
        obs = rng.normal(2.0, 3.0, size=(n + 1, dim)).astype(np.float32)
        act = np.stack([np.tanh(obs[:-1, 0]), np.full(n, 1.5)], axis=1)  # the second clipped to 1
        eps.append({"observations": obs, "actions": act, "rewards": np.ones(n)})
    torch.manual_seed(0)
    model = PPO("MlpPolicy", venv, policy_kwargs={"net_arch": [32]}, device="cpu", seed=0)
    fit = sb3_training.bc_initialize(model, venv, eps, gamma=0.5, seed=0, epochs=200, log_std=-1.5)
    seen = np.concatenate([e["observations"][:-1] for e in eps]).astype(np.float64)
    np.testing.assert_allclose(venv.obs_rms.mean, seen.mean(0))
    np.testing.assert_allclose(venv.obs_rms.var, seen.var(0))
    assert venv.obs_rms.count == 50.0 and fit["bc_samples"] == 50 and fit["bc_robot_episodes"] == 2
    running = np.concatenate([sb3_training._discounted(np.ones(n), 0.5)[1] for n in (30, 20)])
    assert venv.ret_rms.mean == 0.0 and venv.ret_rms.var == pytest.approx(running.var())
    assert torch.all(model.policy.log_std == -1.5)
    x = torch.as_tensor(venv.normalize_obs(seen.astype(np.float32)))
    with torch.no_grad():
        mean = model.policy.get_distribution(x).distribution.mean.numpy()
    assert np.abs(mean[:, 1] - 1.0).max() < 0.05  # fitted onto the clipped action, not 1.5
    assert fit["bc_action_mse"] < 0.01
    venv.close()

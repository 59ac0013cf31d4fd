"""``torchrl:`` / ``torchrl_sampled:`` with the ``bernoulli`` scan head, pinned by value on hand-built
networks (mode, seeded samples, copies), what the env does with the +1 / -1 it maps to, and the shipped
``continuous`` checkpoints acting as before."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import parcover_env  # noqa: E402
from parcover_env.errors import ParcoverError  # noqa: E402
from parcover_env.policies.registry import make_policy  # noqa: E402
from parcover_env.policies.torchrl_policy import SCAN_OFF, SCAN_ON, TorchRLPolicy, actor_net, actor_scale  # noqa: E402

LOC = np.array([0.2, -0.5])
PRE = np.array([0.0, -2.0])  # pre-softplus scales: 1.0 and 0.216
SCAN_ENV = {"observation": {"scan": {"enabled": True}}}
ROOT = Path(parcover_env.__file__).resolve().parent.parent


def _save(root: Path, obs_dim: int, p_scan: float, head: str = "bernoulli") -> Path:
    """A bernoulli-head policy.pt whose network ignores its input: loc ``LOC``, pre-scale ``PRE`` and the
    scan logit of probability ``p_scan`` on every observation; with run.json of the scan env."""
    net = actor_net(np.full(obs_dim, -1.0), np.ones(obs_dim), (4,), 3, "bernoulli")
    with torch.no_grad():
        for p in net.parameters():
            p.zero_()
        logit = math.log(p_scan / (1 - p_scan))
        net[-1].bias.copy_(torch.as_tensor(np.concatenate([LOC, PRE, [logit]]), dtype=torch.float32))
    root.mkdir(exist_ok=True, parents=True)
    torch.save({"state_dict": net.state_dict(), "obs_dim": obs_dim, "hidden": [4], "act_dim": 3, "scan_head": head},
               root / "policy.pt")
    (root / "run.json").write_text(json.dumps({"env_overrides": SCAN_ENV}))
    return root


def _obs(n_agents: int, obs_dim: int) -> dict:
    return {f"robot_{i}": np.full(obs_dim, 0.1 * i, np.float32) for i in range(n_agents)}


@pytest.mark.parametrize(("p_scan", "scan"), [(0.7, SCAN_ON), (0.3, SCAN_OFF), (0.51, SCAN_ON), (0.49, SCAN_OFF),
                                             (0.5, SCAN_OFF)])  # logit 0: p = 0.5 is not above one half
def test_deterministic_scans_where_the_probability_is_above_one_half(tmp_path, p_scan, scan):
    policy = TorchRLPolicy(_save(tmp_path, 5, p_scan))
    assert (policy.scan_head, policy.act_dim, policy.drive_dim) == ("bernoulli", 3, 2)
    got = policy.act(_obs(3, 5))
    for a in got:
        np.testing.assert_allclose(got[a][:2], np.tanh(LOC), rtol=1e-6)
        assert got[a][2] == scan and got[a].dtype == np.float32 and got[a].shape == (3,)


def test_sampled_is_the_tanh_normal_then_a_seeded_uniform_against_the_scan_probability(tmp_path):
    policy = TorchRLPolicy(_save(tmp_path, 5, 0.7), sample_seed=7)
    obs = _obs(3, 5)
    rng = np.random.default_rng(7)  # per step: the drive's normals (robots in sorted order), then one uniform each
    scale = actor_scale(torch.as_tensor(PRE, dtype=torch.float32)).double().numpy()
    for _ in range(3):
        eps, u = rng.standard_normal((3, 2)), rng.random(3)
        got = policy.act(obs)
        for i, a in enumerate(sorted(obs)):
            np.testing.assert_allclose(got[a][:2], np.tanh(LOC + scale * eps[i]), rtol=1e-5)
            assert got[a][2] == (SCAN_ON if u[i] < 0.7 else SCAN_OFF)


def test_sampled_scan_frequency_under_the_episode_seed(tmp_path):
    n = 4000
    policy = TorchRLPolicy(_save(tmp_path, 2, 0.7), sample_seed=11)
    got = policy.act(_obs(n, 2))
    scans = np.array([got[a][2] for a in sorted(got)])
    assert set(scans.tolist()) == {SCAN_ON, SCAN_OFF}
    rng = np.random.default_rng(11)
    rng.standard_normal((n, 2))
    want = rng.random(n) < 0.7
    assert np.array_equal(scans > 0, want)
    assert abs((scans > 0).mean() - 0.7) < 4 * math.sqrt(0.21 / n)  # 4 sigma: 0.029
    assert int(want.sum()) == int((scans > 0).sum())


def test_sampled_is_the_same_per_seed_and_after_a_deepcopy(tmp_path):
    _save(tmp_path, 4, 0.5)
    obs = _obs(6, 4)
    a, b = TorchRLPolicy(tmp_path, sample_seed=3), TorchRLPolicy(tmp_path, sample_seed=3)
    first = [a.act(obs) for _ in range(4)]
    assert all(np.array_equal(x[k], y[k]) for x, y in zip(first, [b.act(obs) for _ in range(4)]) for k in obs)
    assert len({tuple(step[k][2] for k in sorted(obs)) for step in first}) > 1  # new scan draws each step
    twin = copy.deepcopy(a)
    nxt, copied = a.act(obs), twin.act(obs)
    assert all(np.array_equal(copied[k], nxt[k]) for k in obs)
    other = TorchRLPolicy(tmp_path, sample_seed=4).act(obs)
    assert any(not np.array_equal(other[k], first[0][k]) for k in obs)


def test_the_env_holds_and_scans_a_robot_whose_head_says_scan_and_drives_the_other(tmp_path):
    env = parcover_env.parallel_env("office", overrides=SCAN_ENV)
    obs, _ = env.reset(seed=0)
    dim = env.observation_space("robot_0").shape[0]
    scan_pol = make_policy(f"torchrl:{_save(tmp_path / 'yes', dim, 0.7)}", env, 0)
    drive_pol = make_policy(f"torchrl:{_save(tmp_path / 'no', dim, 0.3)}", env, 0)
    start = env.true_poses().copy()
    acts = {a: np.array([0.0, 0.0, -1.0], np.float32) for a in env.agents}
    acts.update(robot_0=scan_pol.act(obs)["robot_0"], robot_1=drive_pol.act(obs)["robot_1"])
    assert acts["robot_0"][2] == 1.0 and acts["robot_1"][2] == -1.0 and acts["robot_0"][0] > 0.19
    steps = env.scanner.duration_steps
    fixes = []
    for k in range(steps):
        obs, _, _, _, infos = env.step(acts)
        fixes.append(infos["robot_0"]["sonar_fix"])
        assert env.layout.get(obs["robot_1"], "scanning")[0] == 0.0
        assert env.layout.get(obs["robot_0"], "scanning")[0] == (1.0 if k < steps - 1 else 0.0)
        acts["robot_0"] = scan_pol.act(obs)["robot_0"]  # still +1: ignored while the scan runs
    poses = env.true_poses()
    np.testing.assert_allclose(poses[0], start[0], atol=1e-9)  # held still through the scan, v = tanh(0.2) ignored
    # the robot told -1 drove on: its turn command tanh(-0.5) x max_turn_rate over the scan's steps (less the
    # wheels' lag from rest)
    s = env.scenario
    commanded = math.tanh(0.5) * s.robot.max_turn_rate * steps * s.physics.control_dt
    assert 0.5 * commanded < start[1, 2] - poses[1, 2] <= commanded
    assert not np.allclose(poses[1, :2], start[1, :2], atol=1e-3)
    assert fixes[:-1] == [0.0] * (steps - 1) and fixes[-1] != 0.0  # the scan's outcome at its last step


def test_registry_seeds_the_sampled_scan_head_with_the_episode_seed(tmp_path):
    env = parcover_env.parallel_env("office", overrides=SCAN_ENV)
    obs, _ = env.reset(seed=0)
    _save(tmp_path, env.observation_space("robot_0").shape[0], 0.5)
    x, y = make_policy(f"torchrl_sampled:{tmp_path}", env, 11).act(obs), TorchRLPolicy(tmp_path, 11).act(obs)
    assert all(np.array_equal(x[k], y[k]) for k in obs)


def test_an_unknown_head_in_a_file_or_a_misfit_net_is_one_clear_error(tmp_path):
    _save(tmp_path, 3, 0.5, head="gaussian")
    with pytest.raises(ParcoverError, match=r"^cannot load TorchRL policy .*policy.pt: ValueError: scan head "
                                            r"'gaussian' with 3 action components"):
        TorchRLPolicy(tmp_path)
    net = actor_net(np.zeros(3), np.ones(3), (4,), 3)  # continuous: 6 outputs
    with pytest.raises(ParcoverError, match="the bernoulli scan head has 5 outputs, not 6"):
        TorchRLPolicy.from_net(net, 3, "bernoulli")
    with pytest.raises(ParcoverError, match="scan head 'nope'"):
        TorchRLPolicy.from_net(net, 3, "nope")
    assert TorchRLPolicy.from_net(net, 3).scan_head == "continuous"
    deep = actor_net(np.zeros(3), np.ones(3), (4, 5), 3)  # the last layer is the one that counts
    with pytest.raises(ParcoverError, match="the continuous scan head has 4 outputs, not 6"):
        TorchRLPolicy.from_net(deep, 2)


def test_from_net_is_the_loaded_policy_sampled_and_deterministic(tmp_path):
    _save(tmp_path, 4, 0.6)
    obs = _obs(5, 4)
    for seed in (None, 9):
        loaded = TorchRLPolicy(tmp_path, sample_seed=seed)
        made = TorchRLPolicy.from_net(copy.deepcopy(loaded.net), 3, "bernoulli", sample_seed=seed)
        assert made.obs_shape == (4,) and (made.rng is None) == (seed is None)
        for _ in range(2):
            x, y = loaded.act(obs), made.act(obs)
            assert all(np.array_equal(x[k], y[k]) for k in obs)


SHIPPED = sorted(str(p.parent.relative_to(ROOT)) for p in [*ROOT.glob("baselines/checkpoints/*/policy.pt"),
                                                           *ROOT.glob("docs/learned/*/policy.pt")])


@pytest.mark.parametrize("where", SHIPPED)
def test_shipped_checkpoints_keep_the_continuous_head_and_act_as_before(where):
    """Old files have no ``scan_head``: the TanhNormal over every component, deterministic ``tanh(loc)``
    and sampled ``tanh(loc + scale * eps)`` with the episode's generator, bit for bit."""
    det, sam = TorchRLPolicy(ROOT / where), TorchRLPolicy(ROOT / where, sample_seed=5)
    assert det.scan_head == "continuous" and det.drive_dim == det.act_dim
    n, k = det.obs_shape[0], det.act_dim
    obs = {f"robot_{i}": np.random.default_rng(i).normal(size=n).astype(np.float32) for i in range(3)}
    with torch.no_grad():
        out = det.net(torch.as_tensor(np.stack([obs[a] for a in sorted(obs)])))
    want = torch.tanh(out[:, :k]).numpy()
    eps = np.random.default_rng(5).standard_normal((3, k))
    sampled = np.tanh(out[:, :k].double().numpy() + actor_scale(out[:, k:]).double().numpy() * eps).astype(np.float32)
    got_det, got_sam = det.act(obs), sam.act(obs)
    for i, a in enumerate(sorted(obs)):
        assert np.array_equal(got_det[a], want[i]) and np.array_equal(got_sam[a], sampled[i])
    if k == 3:  # the shipped continuous-scan actors: the deterministic scan stays below 0 (docs/train_and_compare.md)
        assert all(got_det[a][2] < 0 for a in obs)
    # what the code before the bernoulli head gave on these observations (robot_0 deterministic, robot_2 sampled)
    np.testing.assert_allclose(got_det["robot_0"], BEFORE[where][0], atol=2e-6)
    np.testing.assert_allclose(got_sam["robot_2"], BEFORE[where][1], atol=2e-6)


BEFORE = {  # TorchRLPolicy at commit 44e748a, the observations of the test above
    "baselines/checkpoints/ippo_generated_scaled": ([-0.079696, 0.148935], [0.83796, -0.55026]),
    "baselines/checkpoints/ippo_generated_scratch": ([-0.082516, 0.394959], [0.996344, -0.806934]),
    "baselines/checkpoints/ippo_generated_shaped": ([-0.44971, 0.343453], [0.741509, -0.155223]),
    "baselines/checkpoints/ippo_office_scratch": ([-0.254042, -0.555756], [0.944969, 0.743937]),
    "baselines/checkpoints/ippo_tree_scratch": ([-0.606067, 0.937208], [-0.761367, 0.507209]),
    "baselines/checkpoints/mappo_generated_attention": ([-0.640154, 0.33953], [0.641233, -0.156114]),
    "baselines/checkpoints/mappo_generated_scan_sigma": ([0.020657, 0.242074, -0.896858],
                                                         [0.456781, -0.413058, -0.925747]),
    "docs/learned/mappo_generated_scan_s6": ([-0.105257, 0.444936, -0.891082], [0.457284, -0.399542, -0.830849]),
}

"""``torchrl:`` (deterministic) and ``torchrl_sampled:`` actors, pinned by value on a hand-built network."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import parcover_env  # noqa: E402
from parcover_env.policies.registry import make_policy  # noqa: E402
from parcover_env.policies.torchrl_policy import SCALE_MIN, TorchRLPolicy, actor_net, actor_scale  # noqa: E402

LOC = np.array([0.2, -0.5])
PRE = np.array([0.0, -2.0])  # pre-softplus scale outputs: scale 1.0 and softplus(-2 + b) + 0.01


def _save(root, obs_dim: int) -> None:
    """A policy.pt whose network ignores its input: loc ``LOC``, pre-scale ``PRE`` on every observation."""
    net = actor_net(np.full(obs_dim, -1.0), np.ones(obs_dim), (4,), 2)
    with torch.no_grad():
        for p in net.parameters():
            p.zero_()
        net[-1].bias.copy_(torch.as_tensor(np.concatenate([LOC, PRE]), dtype=torch.float32))
    root.mkdir(exist_ok=True)
    torch.save({"state_dict": net.state_dict(), "obs_dim": obs_dim, "hidden": [4], "act_dim": 2}, root / "policy.pt")


def _obs(n_agents: int, obs_dim: int) -> dict:
    return {f"robot_{i}": np.full(obs_dim, 0.1 * i, np.float32) for i in range(n_agents)}


def test_actor_scale_maps_zero_to_one_and_matches_torchrl():
    pre = torch.tensor([[-30.0, -2.0, 0.0, 3.0]])
    scale = actor_scale(pre)
    assert float(scale[0, 2]) == pytest.approx(1.0, abs=1e-6)
    assert float(scale[0, 0]) == pytest.approx(SCALE_MIN, abs=1e-6)  # the floor
    assert float(scale[0, 3]) == pytest.approx(np.log1p(np.exp(3.0 + np.log(np.expm1(0.99)))) + 0.01, rel=1e-6)
    extractor = pytest.importorskip("tensordict.nn").NormalParamExtractor()
    _, want = extractor(torch.cat([torch.zeros_like(pre), pre], dim=-1))
    torch.testing.assert_close(scale, want)


def test_deterministic_is_tanh_loc_and_sampled_is_tanh_of_loc_plus_scale_times_seeded_noise(tmp_path):
    _save(tmp_path, 5)
    obs = _obs(3, 5)
    det = TorchRLPolicy(tmp_path).act(obs)
    for a in obs:
        np.testing.assert_allclose(det[a], np.tanh(LOC), rtol=1e-6)
    policy = TorchRLPolicy(tmp_path, sample_seed=7)
    eps = np.random.default_rng(7).standard_normal((2, 3, 2))  # two steps, agents in sorted order
    scale = actor_scale(torch.as_tensor(PRE, dtype=torch.float32)).double().numpy()
    for step in range(2):
        got = policy.act(obs)
        for i, a in enumerate(sorted(obs)):
            np.testing.assert_allclose(got[a], np.tanh(LOC + scale * eps[step, i]), rtol=1e-5)
            assert got[a].dtype == np.float32 and np.all(np.abs(got[a]) <= 1.0)
    assert scale[0] == pytest.approx(1.0, abs=1e-6)
    assert scale[1] == pytest.approx(np.log1p(np.exp(-2.0 + np.log(np.expm1(0.99)))) + 0.01, rel=1e-6)  # 0.216


def test_sampled_is_the_same_per_seed_and_continues_identically_after_a_deepcopy(tmp_path):
    _save(tmp_path, 4)
    obs = _obs(2, 4)
    a, b = TorchRLPolicy(tmp_path, sample_seed=3), TorchRLPolicy(tmp_path, sample_seed=3)
    first = [a.act(obs) for _ in range(3)]
    assert all(np.array_equal(x[k], y[k]) for x, y in zip(first, [b.act(obs) for _ in range(3)]) for k in obs)
    assert not np.array_equal(first[0]["robot_0"], first[1]["robot_0"])  # a new draw each step
    other = TorchRLPolicy(tmp_path, sample_seed=4).act(obs)
    assert not np.array_equal(other["robot_0"], first[0]["robot_0"])
    twin = copy.deepcopy(a)  # mid-episode: the copy draws what the original draws next
    nxt, copied = a.act(obs), twin.act(obs)
    assert all(np.array_equal(copied[k], nxt[k]) for k in obs)


def test_registry_seeds_the_sampled_actor_with_the_episode_seed(tmp_path):
    env = parcover_env.parallel_env("office")
    obs, _ = env.reset(seed=0)
    dim = env.observation_space(env.possible_agents[0]).shape[0]
    _save(tmp_path, dim)
    (tmp_path / "run.json").write_text(json.dumps({"env_overrides": None}))
    spec = f"torchrl_sampled:{tmp_path}"
    x, y = make_policy(spec, env, 11).act(obs), TorchRLPolicy(tmp_path, sample_seed=11).act(obs)
    assert all(np.array_equal(x[k], y[k]) for k in obs)
    x, y = make_policy(spec, env, None).act(obs), TorchRLPolicy(tmp_path, sample_seed=0).act(obs)  # no seed: 0
    assert all(np.array_equal(x[k], y[k]) for k in obs)
    det = make_policy(f"torchrl:{tmp_path}", env, 11).act(obs)
    assert all(np.allclose(det[k], np.tanh(LOC)) for k in obs)


@pytest.mark.parametrize("name", ["torchrl", "torchrl_sampled"])
def test_a_checkpoint_of_another_observation_size_is_one_clear_error(tmp_path, name):
    from parcover_env.errors import ParcoverError

    env = parcover_env.parallel_env("office")
    env.reset(seed=0)
    dim = env.observation_space(env.possible_agents[0]).shape[0]
    _save(tmp_path, dim + 3)
    (tmp_path / "run.json").write_text(json.dumps({"env_overrides": None}))
    with pytest.raises(ParcoverError) as err:
        make_policy(f"{name}:{tmp_path}", env, 0)
    assert str(err.value) == (f"policy '{name}:{tmp_path}' was trained on observations of shape ({dim + 3},); "
                              f"scenario 'office' gives ({dim},)")


class _NotWeights:
    """Stands for code a checkpoint could carry: ``weights_only`` loading refuses it."""


def test_float64_observations_give_float32_actions(tmp_path):
    _save(tmp_path, 5)
    obs = {k: v.astype(np.float64) for k, v in _obs(2, 5).items()}
    for policy in (TorchRLPolicy(tmp_path), TorchRLPolicy(tmp_path, sample_seed=1)):
        got = policy.act(obs)
        assert all(a.dtype == np.float32 and a.shape == (2,) for a in got.values())
    assert TorchRLPolicy(tmp_path).act({}) == {}


def test_missing_corrupt_and_code_carrying_checkpoints_are_one_clear_error(tmp_path):
    from parcover_env.errors import ParcoverError

    with pytest.raises(ParcoverError, match="^TorchRL policy checkpoint not found: .*/nothing$"):
        TorchRLPolicy(tmp_path / "nothing")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "policy.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ParcoverError, match=r"^cannot load TorchRL policy .*policy.pt: not a torch checkpoint "
                       r"\(corrupt, truncated or another format; UnpicklingError: "):
        TorchRLPolicy(bad)
    _save(tmp_path / "code", 4)
    ckpt = torch.load(tmp_path / "code" / "policy.pt", weights_only=True)
    torch.save({**ckpt, "extra": _NotWeights()}, tmp_path / "code" / "policy.pt")
    with pytest.raises(ParcoverError, match=r"^cannot load TorchRL policy .*policy.pt: it holds Python objects "
                       r"other than tensors \(UnpicklingError: Unsupported global: .*_NotWeights"):
        TorchRLPolicy(tmp_path / "code")  # weights only: no object of a foreign class is rebuilt

"""MAPPO's attention critic on the version-2 state tokens: robot i's value follows robot i under any
order of the tokens, padded tokens change nothing, real tokens and masks do; a version-1 env is refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from gymnasium import spaces  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from parcover_env.envs.critic_state import STATE_SIZE, StateTokens, flat_state, state_tokens  # noqa: E402
from parcover_env.errors import ConfigError  # noqa: E402
from parcover_env.harness.marl import GROUP, TrainRequest, build_critic, train  # noqa: E402
from parcover_env.harness.marl_config import MarlConfig  # noqa: E402

N, KPOIS, OBS, T = 3, 5, 6, 2
CFG = MarlConfig(critic="attention", critic_embed=16, critic_heads=2, hidden=(16,))


def _box(n: int, bound: float) -> spaces.Box:
    return spaces.Box(np.full(n, -bound, np.float32), np.full(n, bound, np.float32))


def _critic():
    torch.manual_seed(0)
    return build_critic("mappo", _box(OBS, 2.0), _box(STATE_SIZE, 5.0), CFG)


def _tokens(rng: np.random.Generator) -> StateTokens:
    """T states of N robots and KPOIS KPOIs (random features in the box), the rest padding (zeros)."""
    tok = state_tokens(np.zeros((T, STATE_SIZE), np.float32))
    robots, kpois = tok.robots.copy(), tok.kpois.copy()
    robots[:, :N] = rng.uniform(-4, 4, robots[:, :N].shape)
    kpois[:, :KPOIS] = rng.uniform(-4, 4, kpois[:, :KPOIS].shape)
    robot_mask, kpoi_mask = np.zeros_like(tok.robot_mask), np.zeros_like(tok.kpoi_mask)
    robot_mask[:, :N], kpoi_mask[:, :KPOIS] = True, True
    return StateTokens(robots, robot_mask, kpois, kpoi_mask, rng.uniform(0, 1, tok.globals.shape))


def _values(critic, tokens: StateTokens, obs: np.ndarray) -> np.ndarray:
    td = TensorDict({"state": torch.as_tensor(flat_state(tokens)),
                     GROUP: {"observation": torch.as_tensor(obs, dtype=torch.float32)}}, batch_size=[T])
    with torch.no_grad():
        return critic(td)[GROUP, "state_value"].numpy()


def _setup():
    rng = np.random.default_rng(4)
    return _critic(), _tokens(rng), rng.uniform(-2, 2, (T, N, OBS)), rng


def test_value_per_robot_differs_and_reads_its_own_token_and_observation():
    critic, tok, obs, _ = _setup()
    v = _values(critic, tok, obs)
    assert v.shape == (T, N, 1)
    assert np.ptp(v[0, :, 0]) > 1e-3  # robots get different values: the order test below can fail
    obs2 = obs.copy()
    obs2[:, 1] += 1.0
    v2 = _values(critic, tok, obs2)
    assert np.abs(v2[:, 1] - v[:, 1]).max() > 1e-4  # robot 1's observation moves robot 1's value


def test_robot_i_value_follows_robot_i_when_tokens_are_reordered():
    critic, tok, obs, rng = _setup()
    v = _values(critic, tok, obs)
    perm = np.array([2, 0, 1])  # new robot row j is old robot perm[j]; agents reordered alike
    robots = tok.robots.copy()
    robots[:, :N] = tok.robots[:, perm]
    kperm = rng.permutation(32)  # KPOI tokens in any order, padding interleaved with real ones
    moved = StateTokens(robots, tok.robot_mask, tok.kpois[:, kperm], tok.kpoi_mask[:, kperm], tok.globals)
    got = _values(critic, moved, obs[:, perm])
    np.testing.assert_allclose(got, v[:, perm], atol=1e-5)
    # the padded robot rows in any order too (they are not agents)
    pad = np.concatenate([np.arange(N), N + rng.permutation(16 - N)])
    shuffled = StateTokens(tok.robots[:, pad], tok.robot_mask[:, pad], tok.kpois, tok.kpoi_mask, tok.globals)
    np.testing.assert_allclose(_values(critic, shuffled, obs), v, atol=1e-5)


def test_padded_tokens_contents_change_no_value_real_ones_and_masks_do():
    critic, tok, obs, rng = _setup()
    v = _values(critic, tok, obs)
    robots, kpois = tok.robots.copy(), tok.kpois.copy()
    robots[:, N:] = rng.uniform(-5, 5, robots[:, N:].shape)
    kpois[:, KPOIS:] = rng.uniform(-5, 5, kpois[:, KPOIS:].shape)
    noisy = StateTokens(robots, tok.robot_mask, kpois, tok.kpoi_mask, tok.globals)
    np.testing.assert_allclose(_values(critic, noisy, obs), v, atol=1e-6)
    # the same change counts once the mask says the token is real
    real_mask = tok.kpoi_mask.copy()
    real_mask[:, KPOIS] = True
    assert np.abs(_values(critic, noisy._replace(kpoi_mask=real_mask), obs) - v).max() > 1e-4
    robot_mask = tok.robot_mask.copy()
    robot_mask[:, N - 1] = False  # the robot mask is read: robot 2 counted as padding moves robot 0's value
    assert np.abs(_values(critic, tok._replace(robot_mask=robot_mask), obs)[:, 0] - v[:, 0]).max() > 1e-4
    # a real KPOI's position and a teammate's token move robot 0's value
    for field_name, row in (("kpois", 0), ("robots", 2)):
        changed = getattr(tok, field_name).copy()
        changed[:, row, :2] += 1.0
        v2 = _values(critic, tok._replace(**{field_name: changed}), obs)
        assert np.abs(v2[:, 0] - v[:, 0]).max() > 1e-4, field_name


def test_attention_critic_needs_mappo_and_a_version_2_env():
    CFG.check_critic("mappo", 2, "x.yaml")
    MarlConfig().check_critic("ippo", 1, "x.yaml")  # the MLP critic takes any version
    with pytest.raises(ConfigError, match=r"x.yaml.*critic.*observation version 1.*version: 2"):
        CFG.check_critic("mappo", 1, "x.yaml")
    with pytest.raises(ConfigError, match=r"critic.*ippo's critic sees only"):
        CFG.check_critic("ippo", 2, "x.yaml")


def test_mappo_on_a_map_pool_needs_the_version_2_state():
    mlp = MarlConfig()
    mlp.check_critic("mappo", 1, "x.yaml")  # one scenario: its state has one shape
    mlp.check_critic("mappo", 2, "x.yaml", pool=True)
    mlp.check_critic("ippo", 1, "x.yaml", pool=True)  # IPPO's critic reads no state
    with pytest.raises(ConfigError, match=r"x.yaml: env.observation.version: MAPPO's critic.*version 1 differs"):
        mlp.check_critic("mappo", 1, "x.yaml", pool=True)


def test_train_refuses_mappo_on_a_version_1_pool_before_writing(tmp_path):
    cfg = dataclasses.replace(MarlConfig(), frames_per_batch=64, minibatch_size=64, epochs=1, hidden=(8,),
                              episode_steps=20, env={"observation": {"version": 1}})
    with pytest.raises(ConfigError, match="env.observation.version"):
        train(TrainRequest("mappo", "generated:0-20", 2000, tmp_path / "run", cfg, "cfg.yaml"))
    assert not (tmp_path / "run").exists()


def test_train_refuses_attention_on_a_version_1_env(tmp_path):
    with pytest.raises(ConfigError, match="observation version 1"):
        train(TrainRequest("mappo", "office", 64, tmp_path / "run", CFG, "cfg.yaml"))
    assert not (tmp_path / "run").exists()


def test_short_mappo_run_with_the_attention_critic_on_env_v2(tmp_path):
    cfg = dataclasses.replace(CFG, frames_per_batch=64, minibatch_size=32, epochs=1, episode_steps=30,
                              env={"observation": {"version": 2}})
    record = train(TrainRequest("mappo", "office", 128, tmp_path / "run", cfg, "cfg.yaml", seed=1))
    assert record["agent_steps"] == 128 and record["config"]["critic"] == "attention"
    assert record["config"]["env"] == {"observation": {"version": 2}}
    saved = torch.load(tmp_path / "run" / "critic.pt", weights_only=True)
    assert saved["spec"]["critic"] == "attention" and saved["spec"]["state_dim"] == STATE_SIZE
    assert any(k.startswith("module.robot_attn.") for k in saved["state_dict"])


def test_one_attention_critic_moves_to_another_map_with_init(tmp_path):
    cfg = dataclasses.replace(CFG, frames_per_batch=64, minibatch_size=64, epochs=1, episode_steps=30,
                              env={"observation": {"version": 2}})
    train(TrainRequest("mappo", "office", 128, tmp_path / "office", cfg, "cfg.yaml", seed=1))
    record = train(TrainRequest("mappo", "generated:3", 192, tmp_path / "gen", cfg, "cfg.yaml", seed=1,
                                init=str(tmp_path / "office")))
    assert record["n_robots"] == 3 and record["init"]["critic"] is True and record["init"]["algo"] == "mappo"

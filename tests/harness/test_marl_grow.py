"""init_grow: an --init actor grown into an env with new observation entries and action components:
matched by name, the init's outputs unchanged on any observation, the new component at its documented
start; a misfit growth cannot explain is one error; the sidecar says what grew."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from parcover_env import parallel_env  # noqa: E402
from parcover_env.errors import ConfigError, ParcoverError  # noqa: E402
from parcover_env.harness.marl import TrainRequest, build_actor, policy_net, save_policy, train  # noqa: E402
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.harness.marl_grow import Growth, IoLayout, env_io, grow_actor, scale_bias  # noqa: E402
from parcover_env.harness.marl_init import apply_init, find_init, init_env_args  # noqa: E402
from parcover_env.policies.torchrl_policy import TorchRLPolicy  # noqa: E402

OLD = IoLayout({"a": slice(0, 2), "b": slice(2, 3), "c": slice(3, 5)}, ("v", "omega"))
# new entries before, between and after the old ones; "c" moved
NEW = IoLayout({"n0": slice(0, 1), "a": slice(1, 3), "b": slice(3, 4), "n1": slice(4, 6), "c": slice(6, 8),
                "n2": slice(8, 9)}, ("v", "omega", "scan"))
OLD_COLS, NEW_COLS = [0, 1, 2, 3, 4], [1, 2, 3, 6, 7]


def _actor(seed: int, n_obs: int, n_act: int, hidden=(8, 6), fitted: bool = True):
    torch.manual_seed(seed)
    actor = build_actor(np.full(n_obs, -2.0), np.full(n_obs, 3.0), n_act, hidden)
    if not fitted:  # the box scale: centre 0.5, half-width 2.5
        return actor
    with torch.no_grad():  # a fitted (rollout) input scale, not the box's
        scale = policy_net(actor)[0]
        scale.centre.copy_(torch.randn(n_obs))
        scale.half_width.copy_(torch.rand(n_obs) + 0.5)
    return actor


def _loc_scale(actor, obs):
    """(loc, scale) of the actor's TanhNormal: Sequential(actor_net, NormalParamExtractor)."""
    return actor.module[0].module(obs)


def test_grown_actor_keeps_the_init_outputs_and_starts_the_new_component_at_no_scan():
    init, grown = _actor(1, 5, 2), _actor(2, 9, 3, fitted=False)
    record = grow_actor("x", policy_net(init), policy_net(grown), Growth(OLD, NEW, loc=-1.5, std=0.5))
    assert record == {"observation": ["n0", "n1", "n2"], "actions": ["scan"]}
    obs = torch.randn(64, 9) * 10  # new entries far from zero: their columns have zero weight
    loc_old, scale_old = _loc_scale(init, obs[:, NEW_COLS])
    loc, scale = _loc_scale(grown, obs)
    torch.testing.assert_close(loc[:, :2], loc_old, rtol=0, atol=1e-6)
    torch.testing.assert_close(scale[:, :2], scale_old, rtol=0, atol=1e-6)
    assert torch.all(loc[:, 2] == -1.5)  # zero weights: the bias alone
    torch.testing.assert_close(scale[:, 2], torch.full((64,), 0.5), rtol=0, atol=1e-6)
    # the matching entries keep the init's fitted scale; the new ones this env's box (-2, 3)
    old_s, new_s = policy_net(init)[0], policy_net(grown)[0]
    assert torch.equal(new_s.centre[NEW_COLS], old_s.centre[OLD_COLS])
    assert torch.equal(new_s.half_width[NEW_COLS], old_s.half_width[OLD_COLS])
    assert torch.all(new_s.centre[[0, 4, 5, 8]] == 0.5) and torch.all(new_s.half_width[[0, 4, 5, 8]] == 2.5)
    # the deterministic action (tanh(loc), as evaluation takes it): scan = tanh(-1.5) = -0.905, "no scan"
    # (the env starts a scan when scan > 0)
    policy = TorchRLPolicy.from_net(policy_net(grown), 3)  # deterministic
    act = policy.act({"robot_0": obs[0].numpy(), "robot_1": obs[1].numpy()})
    assert act["robot_0"][2] == pytest.approx(math.tanh(-1.5)) and act["robot_1"][2] < 0


def test_growth_moves_an_old_action_component_to_its_new_position():
    init, grown = _actor(1, 5, 2), _actor(2, 9, 3)
    swapped = dataclasses.replace(NEW, actions=("scan", "omega", "v"))
    grow_actor("x", policy_net(init), policy_net(grown), Growth(OLD, swapped, loc=0.25, std=1.0))
    obs = torch.randn(8, 9)
    loc_old, scale_old = _loc_scale(init, obs[:, NEW_COLS])
    loc, scale = _loc_scale(grown, obs)
    torch.testing.assert_close(loc[:, [2, 1]], loc_old, rtol=0, atol=1e-6)
    torch.testing.assert_close(scale[:, [2, 1]], scale_old, rtol=0, atol=1e-6)
    assert torch.all(loc[:, 0] == 0.25)
    torch.testing.assert_close(scale[:, 0], torch.ones(8), rtol=0, atol=1e-6)


@pytest.mark.parametrize(("new", "hidden", "words"), [
    (NEW, (8, 8), "hidden widths [8, 6] differ from this run's [8, 8]"),
    (IoLayout({"a": slice(0, 2), "b": slice(2, 3), "n": slice(3, 5)}, NEW.actions), (8, 6),
     "observation entry 'c' is not in this run's observation"),
    (IoLayout({"a": slice(0, 2), "b": slice(2, 5), "c": slice(5, 7)}, NEW.actions), (8, 6),
     "observation entry 'b' has 1 columns there and 3 here"),
    (IoLayout(OLD.observation, ("v", "scan")), (8, 6), "action components ['omega'] are not in this run's"),
])
def test_a_misfit_growth_cannot_explain_is_one_error(new, hidden, words):
    init = _actor(1, 5, 2)
    n_obs = max(s.stop for s in new.observation.values())
    grown = _actor(2, n_obs, len(new.actions), hidden)
    with pytest.raises(ParcoverError) as info:
        grow_actor("runs/x", policy_net(init), policy_net(grown), Growth(OLD, new, loc=-1.5, std=0.5))
    assert "--init runs/x" in str(info.value) and words in str(info.value)


def test_an_init_actor_that_does_not_fit_its_own_sidecar_env_is_one_error():
    init, grown = _actor(1, 5, 3), _actor(2, 9, 3)  # 3 actions, but its env (OLD) has 2
    with pytest.raises(ParcoverError, match=r"its actor has 6 outputs, but its env .* has 2 action components "
                                            r"\(4 outputs with its continuous scan head\)"):
        grow_actor("x", policy_net(init), policy_net(grown), Growth(OLD, NEW, loc=-1.5, std=0.5))
    init = _actor(1, 6, 2)
    with pytest.raises(ParcoverError, match="its actor has 6 inputs, but its env's observation layout .* has 5"):
        grow_actor("x", policy_net(init), policy_net(grown), Growth(OLD, NEW, loc=-1.5, std=0.5))


def test_the_new_scale_bias_and_the_config_bounds():
    from tensordict.nn import NormalParamExtractor

    for std in (0.05, 0.5, 1.0, 3.0):
        out = NormalParamExtractor()(torch.tensor([0.0, scale_bias(std)]))[1]
        assert out.item() == pytest.approx(std, abs=1e-6)
    assert scale_bias(1.0) == pytest.approx(0.0, abs=1e-6)  # the extractor maps 0 to 1
    with pytest.raises(ConfigError, match="init_grow_std"):
        MarlConfig(init_grow_std=0.01).check("x.yaml")
    assert MarlConfig().init_grow is False


def test_the_env_layout_names_the_scan_entries_in_the_middle():
    plain, scan = parallel_env("office"), parallel_env("office", overrides={"observation": {"scan": {"enabled": True}}})
    old, new = env_io(plain), env_io(scan)
    assert old.actions == ("v", "omega") and new.actions == ("v", "omega", "scan")
    added = [n for n in new.observation if n not in old.observation]
    assert added == ["scanning", "scan_result"]
    names = list(new.observation)
    assert 0 < names.index("scanning") < names.index("goal_dx")  # not at the end: matched by name, not position
    assert new.observation["goal_dx"].start == old.observation["goal_dx"].start + 2


def test_train_grows_an_init_run_into_the_scan_env(tmp_path):
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=64, epochs=1,
                              hidden=(8,), episode_steps=30, env={})  # env v1: the scan env below is v1 + scan
    a = train(TrainRequest("ippo", "office", 64, tmp_path / "a", cfg, "x", seed=1))
    scan_env = {"observation": {"scan": {"enabled": True}}}
    plain = dataclasses.replace(cfg, env=scan_env, learning_rate=1e-12, scan_head="continuous")
    with pytest.raises(ParcoverError, match="does not fit this run's .*init_grow: true"):
        train(TrainRequest("ippo", "office", 64, tmp_path / "no", plain, "x", seed=2, init=str(tmp_path / "a")))
    grow = dataclasses.replace(plain, init_grow=True)
    b = train(TrainRequest("ippo", "office", 64, tmp_path / "b", grow, "x", seed=2, init=str(tmp_path / "a")))
    assert b["init"] == {"path": str(tmp_path / "a"), "algo": "ippo", "init": a["init"], "critic": False,
                         "grown": {"observation": ["scanning", "scan_result"], "actions": ["scan"]}}
    assert json.loads((tmp_path / "b" / "run.json").read_text())["init"]["grown"]["actions"] == ["scan"]
    # evaluation: the old components act as the init's, scan starts at "no scan" (lr 1e-12: nothing moved)
    pa, pb = TorchRLPolicy(tmp_path / "a"), TorchRLPolicy(tmp_path / "b")
    env_a, env_b = parallel_env("office"), parallel_env("office", overrides=scan_env)
    obs_a, _ = env_a.reset(seed=3)
    obs_b, _ = env_b.reset(seed=3)
    act_a, act_b = pa.act(obs_a), pb.act(obs_b)
    for agent in act_a:
        np.testing.assert_allclose(act_b[agent][:2], act_a[agent], atol=1e-5)
        assert act_b[agent][2] == pytest.approx(math.tanh(-1.5), abs=1e-5)
    # a growth with nothing to grow loads as before, without a "grown" record
    c = train(TrainRequest("ippo", "office", 64, tmp_path / "c", dataclasses.replace(cfg, init_grow=True), "x",
                           init=str(tmp_path / "a")))
    assert "grown" not in c["init"] and c["init"]["critic"] is True


def test_init_grow_needs_the_init_sidecar(tmp_path):
    actor = _actor(1, 5, 2)
    save_policy(actor, tmp_path / "policy.pt")
    with pytest.raises(ParcoverError, match="init_grow needs the init run's run.json"):
        init_env_args(find_init(tmp_path))
    (tmp_path / "run.json").write_text(json.dumps({"scenario": "office", "config": {"preset": "ideal"},
                                                   "env_overrides": {"observation": {"version": 2}}}))
    assert init_env_args(find_init(tmp_path)) == {"scenario": "office", "preset": "ideal",
                                                  "overrides": {"observation": {"version": 2}}, "max_robots": 12}
    # apply_init with a growth that changes nothing loads the actor as it is
    other = _actor(2, 5, 2)
    record = apply_init(find_init(tmp_path), policy_net(other), None, None, {},
                        Growth(OLD, OLD, loc=-1.5, std=0.5))
    assert "grown" not in record
    assert all(torch.equal(a, b) for a, b in zip(policy_net(other).state_dict().values(),
                                                 policy_net(actor).state_dict().values(), strict=True))


def test_the_stage_6_config_is_stage_5_with_the_scan_service_and_growth():
    here = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"  # staged history
    stage5 = load_marl_config("mappo", here / "mappo_generated_attention.yaml")
    stage6 = load_marl_config("mappo", here / "mappo_generated_scan.yaml")
    env = {**stage5.env, "observation": {**stage5.env["observation"], "scan": {"enabled": True}}}
    assert stage6 == dataclasses.replace(stage5, env=env, init_grow=True, init_grow_loc=-1.5, init_grow_std=0.5,
                                         wall_time=2400.0,  # the 40 min the first run had
                                         scan_head="continuous")  # the head it was trained with
    assert stage6.critic_warmup > 0

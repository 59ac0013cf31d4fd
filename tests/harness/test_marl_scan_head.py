"""The ``bernoulli`` scan head (:mod:`parcover_env.harness.marl_scan_head`), pinned by value on hand-built
logits: its mode, log-probability, entropy and sampling; the TorchRL actor around it; a grown head's start;
and PPO on the env with the scan service training it end to end with finite losses."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from tensordict import TensorDict  # noqa: E402
from tensordict.nn import InteractionType, set_interaction_type  # noqa: E402

from parcover_env.errors import ParcoverError  # noqa: E402
from parcover_env.harness.marl import GROUP, TrainRequest, build_actor, policy_net, save_policy, train  # noqa: E402
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.harness.marl_grow import Growth, IoLayout, grow_actor, output_rows  # noqa: E402
from parcover_env.harness.marl_init import apply_init, find_init  # noqa: E402
from parcover_env.harness.marl_scan_head import (  # noqa: E402
    ScanParamExtractor,
    TanhNormalScan,
    actor_head,
    grown_scan_logit,
)
from parcover_env.policies.torchrl_policy import (  # noqa: E402
    SCAN_OFF,
    SCAN_ON,
    TorchRLPolicy,
    head_act_dim,
    head_outputs,
)

LOC, SCALE = [0.2, -0.5], [1.0, 0.4]
P_SCAN, P_NO = 0.7, 0.3
LOGIT_SCAN, LOGIT_NO = math.log(0.7 / 0.3), math.log(0.3 / 0.7)  # +0.847, -0.847


def _dist(logits, n: int | None = None) -> TanhNormalScan:
    """Two robots (or ``n`` copies of the first logit): drive ``LOC``, ``SCALE``; the given scan logits."""
    f64 = torch.float64
    logits = torch.tensor(logits, dtype=f64) if n is None else torch.full((n,), logits[0], dtype=f64)
    m = logits.shape[0]
    loc = torch.tensor(LOC, dtype=torch.float64).expand(m, 2)
    scale = torch.tensor(SCALE, dtype=torch.float64).expand(m, 2)
    return TanhNormalScan(loc, scale, logits.unsqueeze(-1))


def _log_normal(u: float, loc: float, scale: float) -> float:
    return -0.5 * ((u - loc) / scale) ** 2 - math.log(scale) - 0.5 * math.log(2 * math.pi)


def _log_tanh_normal(a: list[float]) -> float:
    """log density of ``tanh(N(LOC, SCALE))`` at ``a``, by the change of variables: u = atanh(a)."""
    return sum(_log_normal(math.atanh(x), m, s) - math.log(1 - x * x) for x, m, s in zip(a, LOC, SCALE, strict=True))


def test_the_mode_scans_where_the_probability_is_above_one_half():
    dist = _dist([LOGIT_SCAN, LOGIT_NO])
    torch.testing.assert_close(dist.scan_probability, torch.tensor([P_SCAN, P_NO], dtype=torch.float64))
    det = dist.deterministic_sample
    assert det[:, 2].tolist() == [SCAN_ON, SCAN_OFF] == [1.0, -1.0]
    torch.testing.assert_close(det[:, :2], torch.tanh(torch.tensor([LOC, LOC], dtype=torch.float64)))
    assert _dist([0.0, 1e-6]).deterministic_sample[:, 2].tolist() == [-1.0, 1.0]  # p = 0.5 exactly: no scan


def test_shapes_and_a_scan_logit_that_does_not_fit():
    dist = _dist([LOGIT_SCAN, LOGIT_NO])
    assert dist.batch_shape == (2,) and dist.event_shape == (3,)
    assert dist.sample().dtype == torch.float64 and dist.deterministic_sample.dtype == torch.float64
    batch = TanhNormalScan(torch.zeros(4, 5, 2), torch.ones(4, 5, 2), torch.zeros(4, 5, 1))
    assert batch.batch_shape == (4, 5) and batch.event_shape == (3,) and batch.entropy().shape == (4, 5)
    assert batch.log_prob(batch.sample()).shape == (4, 5)
    one = TanhNormalScan(torch.zeros(2), torch.ones(2), torch.zeros(1))  # one robot, no batch
    assert one.batch_shape == () and one.sample().shape == (3,) and one.log_prob(one.sample()).shape == ()
    for loc, logit, words in (((4, 5, 2), (4, 5), "(4, 5) does not fit loc of shape (4, 5, 2): expected (4, 5, 1)"),
                              ((), (1,), "(1,) does not fit loc of shape (): expected (1,)")):
        with pytest.raises(ValueError) as err:
            TanhNormalScan(torch.zeros(loc), torch.ones(loc), torch.zeros(logit))
        assert str(err.value) == f"scan_logit of shape {words}"


def test_log_prob_is_the_tanh_normal_part_plus_the_bernoulli_part_by_hand():
    dist = _dist([LOGIT_SCAN, LOGIT_NO])
    drive = [0.3, -0.6]
    for scan, lp_scan in ((1.0, [math.log(P_SCAN), math.log(P_NO)]), (-1.0, [math.log(P_NO), math.log(P_SCAN)]),
                          (0.0, [math.log(P_NO), math.log(P_SCAN)])):  # 0 is "no scan" (the env scans when > 0)
        action = torch.tensor([[*drive, scan], [*drive, scan]], dtype=torch.float64)
        want = [_log_tanh_normal(drive) + lp for lp in lp_scan]
        got = dist.log_prob(action)
        assert got.shape == (2,)
        np.testing.assert_allclose(got.numpy(), want, rtol=1e-9)
    # the drive part alone, by hand: 0.3 = tanh(0.30952) at loc 0.2, scale 1: -0.924936 + 0.094311 = -0.830625;
    # -0.6 = tanh(-0.693147) at loc -0.5, scale 0.4: -0.116581 + 0.916291 - 0.918939 + 0.446287 = 0.327058
    assert _log_tanh_normal(drive) == pytest.approx(-0.503567, abs=1e-6)


def test_entropy_is_the_drive_estimate_plus_the_exact_bernoulli_entropy():
    dist = _dist([LOGIT_SCAN, LOGIT_NO])
    torch.manual_seed(5)
    got = dist.entropy()
    torch.manual_seed(5)
    eps = torch.randn(2, 2, dtype=torch.float64)  # the drive's reparameterized sample: tanh(loc + scale * eps)
    x = torch.tanh(torch.tensor(LOC, dtype=torch.float64) + torch.tensor(SCALE, dtype=torch.float64) * eps)
    bernoulli = -(0.7 * math.log(0.7) + 0.3 * math.log(0.3))
    assert bernoulli == pytest.approx(0.6108643, abs=1e-7)  # the same for p = 0.7 and p = 0.3
    want = [-_log_tanh_normal(x[i].tolist()) + bernoulli for i in range(2)]
    np.testing.assert_allclose(got.numpy(), want, rtol=1e-9)


def test_sampled_scans_follow_the_bernoulli_under_a_seeded_generator():
    n = 10_000
    dist = _dist([LOGIT_SCAN], n=n)
    torch.manual_seed(0)
    sample = dist.sample()
    assert sample.shape == (n, 3) and set(sample[:, 2].tolist()) == {1.0, -1.0}
    assert torch.all(sample[:, :2].abs() < 1)
    # the same generator by hand: the drive's normals first, then one Bernoulli draw per robot
    torch.manual_seed(0)
    eps = torch.randn(n, 2, dtype=torch.float64)
    bits = torch.bernoulli(torch.full((n,), P_SCAN, dtype=torch.float64))
    torch.testing.assert_close(sample[:, :2], torch.tanh(torch.tensor(LOC, dtype=torch.float64) +
                                                         torch.tensor(SCALE, dtype=torch.float64) * eps))
    assert torch.equal(sample[:, 2] > 0, bits > 0.5)
    freq = float((sample[:, 2] > 0).double().mean())
    assert abs(freq - P_SCAN) < 4 * math.sqrt(P_SCAN * P_NO / n)  # 4 sigma: 0.018
    torch.manual_seed(0)
    assert torch.equal(dist.sample(), sample)  # same seed, same sample
    assert dist.sample((3,)).shape == (3, n, 3)


def _hand_actor(n_obs: int, logit: float, pre=(0.0, 0.0)):
    """A scan actor whose network ignores its input: loc ``LOC``, pre-scale ``pre``, scan logit ``logit``."""
    actor = build_actor(np.full(n_obs, -1.0), np.ones(n_obs), 3, (4,), "bernoulli")
    with torch.no_grad():
        for p in policy_net(actor).parameters():
            p.zero_()
        policy_net(actor)[-1].bias.copy_(torch.tensor([*LOC, *pre, logit]))
    return actor


def test_the_actor_writes_the_env_action_and_its_log_prob():
    actor = _hand_actor(4, LOGIT_SCAN)
    assert actor_head(actor) == "bernoulli" and isinstance(actor.module[0].module[-1], ScanParamExtractor)
    assert actor_head(build_actor(np.zeros(4), np.ones(4), 3, (4,))) == "continuous"
    td = TensorDict({GROUP: TensorDict({"observation": torch.randn(2, 4)}, batch_size=[2])}, batch_size=[])
    with set_interaction_type(InteractionType.DETERMINISTIC), torch.no_grad():
        out = actor(td.clone())
    act = out[GROUP, "action"]
    torch.testing.assert_close(act, torch.tensor([[math.tanh(LOC[0]), math.tanh(LOC[1]), 1.0]] * 2))
    torch.testing.assert_close(out[GROUP, "scan_logit"], torch.full((2, 1), LOGIT_SCAN))
    torch.testing.assert_close(out[GROUP, "scale"], torch.ones(2, 2))  # pre-scale 0: scale 1
    torch.testing.assert_close(out[GROUP, "loc"], torch.tensor([LOC, LOC]))
    # its log-prob is the composite one: loc LOC, scale 1, p 0.7 at the mode
    lp = sum(_log_normal(math.atanh(math.tanh(m)), m, 1.0) - math.log(1 - math.tanh(m) ** 2) for m in LOC)
    torch.testing.assert_close(out[GROUP, "action_log_prob"], torch.full((2,), lp + math.log(P_SCAN)))
    with set_interaction_type(InteractionType.RANDOM), torch.no_grad():
        torch.manual_seed(1)
        sampled = actor(td.clone())[GROUP, "action"]
    assert sampled.shape == (2, 3) and set(sampled[:, 2].tolist()) <= {1.0, -1.0}


def test_a_saved_scan_head_round_trips_through_torchrl(tmp_path):
    torch.manual_seed(3)
    actor = build_actor(np.array([-2.0, 0.0, -1.0]), np.array([2.0, 10.0, 3.0]), 3, (16, 16), "bernoulli")
    net = policy_net(actor)
    with torch.no_grad():  # the logit follows the sign of the first observation entry (box centre 0)
        for layer, j in ((net[1], 0), (net[3], 0), (net[5], 4)):
            layer.weight[j].zero_()
            layer.weight[j, 0] = 2.0
            layer.bias[j] = 0.0
    obs = torch.tensor([[1.5, 7.0, 0.2], [-1.0, 2.0, 2.9], [-0.3, 5.0, 1.0], [1.9, 9.0, -0.9]])
    td = TensorDict({GROUP: {"observation": obs}}, batch_size=[])
    with set_interaction_type(InteractionType.DETERMINISTIC), torch.no_grad():
        expected = actor(td)[GROUP, "action"].numpy()
    assert expected[:, 2].tolist() == [1.0, -1.0, -1.0, 1.0]
    save_policy(actor, tmp_path / "policy.pt")
    ckpt = torch.load(tmp_path / "policy.pt", weights_only=True)
    assert ckpt["scan_head"] == "bernoulli" and ckpt["act_dim"] == 3 and ckpt["hidden"] == [16, 16]
    policy = TorchRLPolicy(tmp_path)
    assert (policy.scan_head, policy.act_dim, policy.drive_dim, policy.obs_shape) == ("bernoulli", 3, 2, (3,))
    got = policy.act({f"robot_{i}": obs[i].numpy() for i in range(4)})
    np.testing.assert_allclose(np.stack([got[f"robot_{i}"] for i in range(4)]), expected, atol=1e-6)
    # a continuous actor's file is as it was: no scan_head key
    save_policy(build_actor(np.zeros(3), np.ones(3), 3, (4,)), tmp_path / "old.pt")
    assert "scan_head" not in torch.load(tmp_path / "old.pt", weights_only=True)
    assert TorchRLPolicy(tmp_path / "old.pt").scan_head == "continuous"


def test_a_grown_scan_head_starts_with_the_continuous_heads_scan_probability():
    assert grown_scan_logit(-1.5, 0.5) == pytest.approx(math.log(0.0013498980316301) - math.log1p(-0.0013498980316301),
                                                        rel=1e-9)
    assert grown_scan_logit(-1.5, 0.5) == pytest.approx(-6.60638, abs=1e-5)
    assert grown_scan_logit(0.0, 0.7) == 0.0 and grown_scan_logit(0.3, 0.5) > 0
    assert math.isfinite(grown_scan_logit(-40.0, 0.02))  # far in the tail: still a finite logit
    assert head_outputs(3, "bernoulli") == 5 and head_outputs(3, "continuous") == 6 and head_outputs(2) == 4
    assert head_outputs(2, "bernoulli") == 3  # one drive component and the scan
    assert head_act_dim(5, "bernoulli") == 3 and head_act_dim(6) == 3 and head_act_dim(3, "bernoulli") == 2
    for outputs, head in ((5, "continuous"), (6, "bernoulli")):
        with pytest.raises(ValueError, match=f"^no actor with the {head} scan head has {outputs} outputs$"):
            head_act_dim(outputs, head)
    for act_dim, head in ((3, "nope"), (1, "bernoulli")):
        with pytest.raises(ValueError) as err:
            head_outputs(act_dim, head)
        assert str(err.value) == (f"scan head {head!r} with {act_dim} action components: expected one of "
                                  "('continuous', 'bernoulli'), bernoulli with at least one drive component and "
                                  "the scan component")


OLD = IoLayout({"a": slice(0, 2), "b": slice(2, 3)}, ("v", "omega"))
NEW = IoLayout({"n0": slice(0, 1), "a": slice(1, 3), "b": slice(3, 4)}, ("v", "omega", "scan"), "bernoulli")


def _random_actor(seed: int, n_obs: int, n_act: int, head: str = "continuous"):
    torch.manual_seed(seed)
    return build_actor(np.full(n_obs, -2.0), np.full(n_obs, 3.0), n_act, (8,), head)


def test_output_rows_of_each_head():
    assert output_rows(NEW) == {"v": (0, 2), "omega": (1, 3), "scan": (4,)}
    assert output_rows(dataclasses.replace(NEW, scan_head="continuous")) == {"v": (0, 3), "omega": (1, 4),
                                                                             "scan": (2, 5)}


@pytest.mark.parametrize("init_acts", [2, 3])
def test_growing_into_the_bernoulli_head_keeps_the_drive_and_starts_the_scan_rarely(init_acts):
    init_io = OLD if init_acts == 2 else dataclasses.replace(OLD, actions=("v", "omega", "scan"))
    init, grown = _random_actor(1, 3, init_acts), _random_actor(2, 4, 3, "bernoulli")
    record = grow_actor("x", policy_net(init), policy_net(grown), Growth(init_io, NEW, loc=-1.5, std=0.5))
    want = {"observation": ["n0"], "actions": ["scan"]}
    if init_acts == 3:  # the continuous scan's rows are not a logit: the scan starts afresh
        want["scan_head"] = "continuous -> bernoulli"
    assert record == want
    obs = torch.randn(32, 4) * 5
    old = policy_net(init)(obs[:, 1:])
    new = policy_net(grown)(obs)
    torch.testing.assert_close(new[:, :2], old[:, :2], rtol=0, atol=1e-6)  # drive loc
    torch.testing.assert_close(new[:, 2:4], old[:, init_acts:init_acts + 2], rtol=0, atol=1e-6)  # drive pre-scale
    torch.testing.assert_close(new[:, 4], torch.full((32,), grown_scan_logit(-1.5, 0.5)), rtol=0, atol=1e-6)
    act = TorchRLPolicy.from_net(policy_net(grown), 3, "bernoulli").act({"robot_0": obs[0].numpy()})
    assert act["robot_0"][2] == SCAN_OFF  # p = 0.00135: the mode does not scan


def test_init_from_a_bernoulli_or_continuous_file_into_a_bernoulli_run(tmp_path):
    src = _random_actor(1, 4, 3, "bernoulli")
    save_policy(src, tmp_path / "policy.pt")
    target = _random_actor(2, 4, 3, "bernoulli")
    record = apply_init(find_init(tmp_path), policy_net(target), None, None, {}, None, "bernoulli")
    assert "grown" not in record
    assert all(torch.equal(a, b) for a, b in zip(policy_net(target).state_dict().values(),
                                                 policy_net(src).state_dict().values(), strict=True))
    # a growth that changes nothing (same layout, same head) loads the file as it is, too
    same = IoLayout(NEW.observation, NEW.actions, "continuous")  # the file's head replaces the init layout's
    record = apply_init(find_init(tmp_path), policy_net(_random_actor(3, 4, 3, "bernoulli")), None, None, {},
                        Growth(same, NEW, -1.5, 0.5), "bernoulli")
    assert "grown" not in record
    # a continuous-scan file does not fit a bernoulli run without init_grow: one error naming both heads
    save_policy(_random_actor(4, 4, 3), tmp_path / "cont.pt")
    with pytest.raises(ParcoverError) as err:
        apply_init(find_init(tmp_path / "cont.pt"), policy_net(target), None, None, {}, None, "bernoulli")
    assert str(err.value) == (f"--init {tmp_path / 'cont.pt'}: its actor (observation 4, hidden [8], actions 3, "
                              "scan head continuous) does not fit this run's (observation 4, hidden [8], actions 3, "
                              "scan head bernoulli) (init_grow: true grows it into new observation entries/actions)")


def test_config_scan_head_and_the_shipped_continuous_scan_configs():
    from parcover_env.config import from_mapping
    from parcover_env.errors import ConfigError
    from parcover_env.harness.marl_config import default_config_path

    assert MarlConfig().scan_head == "bernoulli"
    lab = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"  # staged history
    for path in (lab / "mappo_generated_scan.yaml", lab / "mappo_generated_scan_cont.yaml",
                 default_config_path("mappo").with_name("mappo_generated_scan_sigma.yaml")):
        assert load_marl_config("mappo", path).scan_head == "continuous", path  # as shipped
    with pytest.raises(ConfigError, match="scan_head"):
        from_mapping(MarlConfig, {"scan_head": "gaussian"}, "x.yaml")


def _smoke(tmp_path, algo: str = "ippo", scenario: str = "office", backend: str = "local", version: int = 1,
           **cfg_kw):
    """A short PPO run with the scan service; the loss terms of every loss evaluation, recorded."""
    import parcover_env.harness.marl as marl

    seen: list[dict] = []
    build = marl.build_loss

    def recording_loss(*args, **kwargs):
        loss = build(*args, **kwargs)
        loss.register_forward_hook(lambda m, i, out: seen.append({k: v.detach().item() for k, v in out.items()
                                                                  if k.startswith("loss_")}))
        return loss

    cfg = dataclasses.replace(load_marl_config(algo), frames_per_batch=128, minibatch_size=64, epochs=1,
                              hidden=(16,), episode_steps=50, ray_collectors=2,
                              env={"observation": {"version": version, "scan": {"enabled": True}}}, **cfg_kw)
    marl.build_loss = recording_loss
    try:
        record = train(TrainRequest(algo, scenario, 500, tmp_path / backend, cfg, "x", backend=backend, seed=1))
    finally:
        marl.build_loss = build
    return record, seen


def test_ppo_trains_the_scan_head_on_office_with_finite_losses(tmp_path):
    record, seen = _smoke(tmp_path)
    # 500 agent-steps of 2 robots in batches of 128 env steps: 2 batches of 2 minibatches
    assert record["agent_steps"] == 512 and record["scan_head"] == "bernoulli" and len(seen) == 4
    assert all(set(s) >= {"loss_objective", "loss_critic", "loss_entropy"} for s in seen)
    assert all(math.isfinite(v) for s in seen for v in s.values())
    assert json.loads((tmp_path / "local" / "run.json").read_text())["config"]["scan_head"] == "bernoulli"
    assert record["env_overrides"] == {"observation": {"version": 1, "scan": {"enabled": True}}}
    policy = TorchRLPolicy(tmp_path / "local")
    assert policy.scan_head == "bernoulli" and policy.act_dim == 3


def test_mappo_on_a_map_pool_through_ray_trains_the_scan_head(tmp_path):
    pytest.importorskip("ray")
    record, seen = _smoke(tmp_path, "mappo", "generated:0-1", "ray", version=2)  # v2: one state size on every map
    assert record["scan_head"] == "bernoulli" and record["backend"] == "ray" and seen
    assert all(math.isfinite(v) for s in seen for v in s.values())
    assert TorchRLPolicy(tmp_path / "ray").scan_head == "bernoulli"


def test_the_ppo_loss_takes_the_composite_log_prob_and_the_bernoulli_entropy():
    """IPPO's loss on one step of two robots with the hand-built actor (scan logit l, p = 0.7): at ratio 1
    and advantage 1 the objective's gradient on the logit bias is -mean(d log p(a) / dl) =
    -((1 - p) + (0 - p)) / 2 = 0.2 for actions "scan" and "no scan"; the entropy term's is
    -c * dH/dl = c * l * p * (1 - p) (the drive's estimate does not depend on l)."""
    from gymnasium import spaces

    from parcover_env.harness.marl import build_critic
    from parcover_env.harness.marl_loss import build_loss

    actor = _hand_actor(3, LOGIT_SCAN)
    box = spaces.Box(-np.ones(3, np.float32), np.ones(3, np.float32))
    cfg = MarlConfig(entropy_coeff=0.5, value_norm="none", hidden=(4,))
    loss = build_loss("ippo", cfg, actor, build_critic("ippo", box, box, cfg))
    act = torch.tensor([[[0.1, -0.2, SCAN_ON], [0.3, 0.4, SCAN_OFF]]])
    dist = TanhNormalScan(torch.tensor([LOC, LOC]), torch.ones(2, 2), torch.full((2, 1), LOGIT_SCAN))
    td = TensorDict({GROUP: {"observation": torch.zeros(1, 2, 3), "action": act,
                             "action_log_prob": dist.log_prob(act[0]).unsqueeze(0),
                             "advantage": torch.ones(1, 2, 1), "value_target": torch.zeros(1, 2, 1)}},
                    batch_size=[1])
    bias = policy_net(actor)[-1].bias
    grads = {}
    for term in ("loss_objective", "loss_entropy"):
        loss.zero_grad()
        torch.manual_seed(0)
        parts = loss(td.clone())
        parts[term].backward()
        parts = parts.detach()
        grads[term] = float(bias.grad[4])
    assert parts["loss_objective"].item() == pytest.approx(-1.0, abs=1e-6)  # ratio 1, advantage 1
    assert grads["loss_objective"] == pytest.approx(-((1 - P_SCAN) + (0 - P_SCAN)) / 2, abs=1e-6)  # 0.2
    assert grads["loss_entropy"] == pytest.approx(0.5 * LOGIT_SCAN * P_SCAN * P_NO, abs=1e-6)  # 0.0889
    torch.manual_seed(0)
    assert float(loss(td.clone())["entropy"]) == pytest.approx(float(_entropy_at_seed(dist, 0).mean()), abs=1e-5)


def _entropy_at_seed(dist: TanhNormalScan, seed: int) -> torch.Tensor:
    torch.manual_seed(seed)
    return dist.entropy()


def test_train_grows_an_init_run_into_the_bernoulli_head(tmp_path):
    """``parcover train --init`` with ``init_grow`` from a run without the scan service: the drive is
    the init's, the scan starts at the logit of ``Phi(init_grow_loc / init_grow_std)`` (lr 1e-12: nothing
    moved); the sidecar says what grew and which head the actor has."""
    from parcover_env import parallel_env

    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=64, epochs=1,
                              hidden=(8,), episode_steps=30, env={})  # env v1: the scan env below is v1 + scan
    train(TrainRequest("ippo", "office", 64, tmp_path / "a", cfg, "x", seed=1))
    scan_env = {"observation": {"scan": {"enabled": True}}}
    grow = dataclasses.replace(cfg, env=scan_env, learning_rate=1e-12, init_grow=True)
    b = train(TrainRequest("ippo", "office", 64, tmp_path / "b", grow, "x", seed=2, init=str(tmp_path / "a")))
    assert b["init"]["grown"] == {"observation": ["scanning", "scan_result"], "actions": ["scan"]}
    assert b["scan_head"] == "bernoulli"
    pa, pb = TorchRLPolicy(tmp_path / "a"), TorchRLPolicy(tmp_path / "b")
    assert pa.scan_head == "continuous" and pb.scan_head == "bernoulli"
    obs_a, _ = parallel_env("office").reset(seed=3)
    obs_b, _ = parallel_env("office", overrides=scan_env).reset(seed=3)
    act_a, act_b = pa.act(obs_a), pb.act(obs_b)
    for agent in act_a:
        np.testing.assert_allclose(act_b[agent][:2], act_a[agent], atol=1e-5)
        assert act_b[agent][2] == SCAN_OFF
    with torch.no_grad():
        logit = pb.net(torch.as_tensor(np.stack([obs_b[a] for a in sorted(obs_b)])))[:, 4]
    torch.testing.assert_close(logit, torch.full_like(logit, grown_scan_logit(-1.5, 0.5)), rtol=0, atol=1e-4)
    # its run continued into the same env and head: the file loads as it is
    c = train(TrainRequest("ippo", "office", 64, tmp_path / "c", grow, "x", seed=3, init=str(tmp_path / "b")))
    assert "grown" not in c["init"] and c["init"]["critic"] is True and c["scan_head"] == "bernoulli"

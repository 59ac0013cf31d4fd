"""parcover train --init: the actor (and a fitting critic with its value statistics) start from a
previous run; the sidecar says where from, down the chain; a bad path or a misfit network is one error."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from gymnasium import spaces  # noqa: E402

from parcover_env.errors import ParcoverError  # noqa: E402
from parcover_env.harness.marl import (  # noqa: E402
    TrainRequest,
    build_actor,
    build_critic,
    build_loss,
    policy_net,
    save_policy,
    train,
)
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.harness.marl_init import apply_init, critic_spec, find_init, save_critic  # noqa: E402

OBS, STATE = 4, 5
CFG = MarlConfig(hidden=(8,))


def _box(n: int) -> spaces.Box:
    return spaces.Box(-np.ones(n, np.float32), np.ones(n, np.float32))


def _nets(seed: int, algo: str = "mappo", cfg: MarlConfig = CFG, obs: int = OBS):
    torch.manual_seed(seed)
    actor = build_actor(np.full(obs, -2.0), np.full(obs, 3.0), 2, cfg.hidden)
    critic = build_critic(algo, _box(obs), _box(STATE), cfg)
    return actor, critic, build_loss(algo, cfg, actor, critic)


def _state(module) -> dict:
    return {k: v.clone() for k, v in module.state_dict().items()}


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _saved_run(tmp_path, run: dict | None = None):
    """A run directory with policy.pt, critic.pt (PopArt statistics updated once) and run.json."""
    actor, critic, loss = _nets(1)
    loss.value_norm.update_real(torch.tensor([[5.0], [9.0]]), None)  # the trainer's update (marl_loss)
    out = tmp_path / "a"
    out.mkdir()
    save_policy(actor, out / "policy.pt")
    save_critic(out / "critic.pt", critic, loss.value_norm, critic_spec("mappo", CFG, OBS, STATE))
    if run is not None:
        (out / "run.json").write_text(json.dumps(run))
    return out, actor, critic, loss


def test_find_init_names_a_missing_checkpoint(tmp_path):
    with pytest.raises(ParcoverError, match=r"--init .*nowhere: no such file .*policy.pt"):
        find_init(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ParcoverError, match="empty/policy.pt"):
        find_init(tmp_path / "empty")
    out, *_ = _saved_run(tmp_path, {"algo": "mappo", "init": None})
    by_dir, by_file = find_init(out), find_init(out / "policy.pt")
    assert by_dir.policy == by_file.policy == out / "policy.pt" and by_dir.critic == out / "critic.pt"
    assert by_dir.run == {"algo": "mappo", "init": None} and by_file.path == str(out / "policy.pt")
    (out / "run.json").write_text("{not json")
    with pytest.raises(ParcoverError, match="cannot read .*run.json"):
        find_init(out)


def test_init_loads_actor_critic_and_value_statistics(tmp_path):
    earlier = {"path": "x", "algo": "ippo", "init": None, "critic": False}
    out, actor0, critic0, loss0 = _saved_run(tmp_path, {"algo": "mappo", "init": earlier})
    actor, critic, loss = _nets(2)
    assert not _equal(_state(critic), _state(critic0))
    record = apply_init(find_init(out), policy_net(actor), critic, loss.value_norm,
                        critic_spec("mappo", CFG, OBS, STATE))
    assert record == {"path": str(out), "algo": "mappo", "init": earlier, "critic": True}
    assert _equal(_state(policy_net(actor)), _state(policy_net(actor0)))  # weights and observation box
    assert _equal(_state(critic), _state(critic0))
    assert _equal(_state(loss.value_norm), _state(loss0.value_norm))
    assert loss.value_norm.running_mean.item() != 0.0
    # the loss trains the loaded weights (it shares the critic's parameters)
    for key, value in loss.critic_network_params.items(True, True):
        assert torch.equal(value, critic.state_dict()[".".join(key)])


def test_a_critic_of_another_kind_is_not_loaded_the_actor_is(tmp_path):
    out, actor0, critic0, _ = _saved_run(tmp_path)  # no run.json: a bare checkpoint
    actor, critic, loss = _nets(2, algo="ippo")
    before = _state(critic)
    record = apply_init(find_init(out / "policy.pt"), policy_net(actor), critic, loss.value_norm,
                        critic_spec("ippo", CFG, OBS, STATE))
    assert record == {"path": str(out / "policy.pt"), "algo": None, "init": None, "critic": False}
    assert _equal(_state(critic), before)
    assert _equal(_state(policy_net(actor)), _state(policy_net(actor0)))


@pytest.mark.parametrize(("obs", "hidden", "words"), [
    (OBS + 1, (8,), "its actor (observation 4, hidden [8], actions 2, scan head continuous) does not fit this run's "
              "(observation 5"),
    (OBS, (8, 8), "hidden [8, 8]"),
])
def test_an_actor_of_another_shape_is_one_error(tmp_path, obs, hidden, words):
    out, *_ = _saved_run(tmp_path)
    cfg = dataclasses.replace(CFG, hidden=hidden)
    actor, critic, loss = _nets(2, cfg=cfg, obs=obs)
    with pytest.raises(ParcoverError) as info:
        apply_init(find_init(out), policy_net(actor), critic, loss.value_norm, critic_spec("mappo", cfg, obs, STATE))
    assert words in str(info.value)


def test_a_corrupt_policy_file_is_one_error(tmp_path):
    (tmp_path / "policy.pt").write_text("not a checkpoint")
    actor, critic, loss = _nets(2)
    with pytest.raises(ParcoverError, match="cannot load TorchRL policy"):
        apply_init(find_init(tmp_path), policy_net(actor), critic, loss.value_norm,
                   critic_spec("mappo", CFG, OBS, STATE))


def test_runs_chain_their_init_records(tmp_path):
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=64, minibatch_size=64, epochs=1,
                              hidden=(8,), episode_steps=30)
    a = train(TrainRequest("ippo", "office", 64, tmp_path / "a", cfg, "x", seed=1))
    assert a["init"] is None
    still = dataclasses.replace(cfg, learning_rate=1e-12)  # one gradient step that moves nothing
    b = train(TrainRequest("ippo", "office", 64, tmp_path / "b", still, "x", seed=2, init=str(tmp_path / "a")))
    assert b["init"] == {"path": str(tmp_path / "a"), "algo": "ippo", "init": None, "critic": True}
    wa, wb = (torch.load(tmp_path / r / "policy.pt")["state_dict"] for r in "ab")
    assert all(torch.allclose(wa[k], wb[k], atol=1e-9) for k in wa)
    train(TrainRequest("ippo", "office", 64, tmp_path / "f", still, "x", seed=2))
    wf = torch.load(tmp_path / "f" / "policy.pt")["state_dict"]
    assert not all(torch.allclose(wa[k], wf[k], atol=1e-3) for k in wa)
    c = train(TrainRequest("ippo", "office", 64, tmp_path / "c", cfg, "x", init=str(tmp_path / "b" / "policy.pt")))
    assert c["init"] == {"path": str(tmp_path / "b" / "policy.pt"), "algo": "ippo", "init": b["init"],
                         "critic": True}
    assert json.loads((tmp_path / "c" / "run.json").read_text())["init"]["init"]["path"] == str(tmp_path / "a")


def test_a_critic_whose_weights_do_not_fit_its_spec_is_one_error(tmp_path):
    out, *_ = _saved_run(tmp_path)
    ckpt = torch.load(out / "critic.pt", weights_only=True)
    first = next(iter(ckpt["state_dict"]))
    ckpt["state_dict"][first] = torch.zeros(3, 3)  # same spec, weights of another shape
    torch.save(ckpt, out / "critic.pt")
    actor, critic, loss = _nets(2)
    with pytest.raises(ParcoverError, match=r"^cannot load critic .*critic.pt: its weights do not fit its spec "
                                            r"\(RuntimeError: Error\(s\) in loading state_dict"):
        apply_init(find_init(out), policy_net(actor), critic, loss.value_norm, critic_spec("mappo", CFG, OBS, STATE))

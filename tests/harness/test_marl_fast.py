"""The trainer's throughput parts, by value: the array-built TorchRL env (same observations, rewards
and flags as the ParallelEnv; the padding mask), several worlds side by side, a map pool's bounded
cache, padding agents left out of the PPO loss and of the advantage statistics, periodic saves."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from tensordict import TensorDict  # noqa: E402
from torchrl.objectives.multiagent import IPPOLoss, MAPPOLoss  # noqa: E402

from parcover_env.errors import ConfigError  # noqa: E402
from parcover_env.harness import marl  # noqa: E402
from parcover_env.harness.map_pool import MapPoolEnv  # noqa: E402
from parcover_env.harness.marl import (  # noqa: E402
    GROUP,
    REAL,
    EnvMaker,
    TrainRequest,
    build_actor,
    build_critic,
    build_loss,
    prepare_minibatch,
    standardize_advantage,
    train,
)
from parcover_env.harness.marl_config import MarlConfig, load_marl_config  # noqa: E402
from parcover_env.harness.marl_env import RobotsEnv  # noqa: E402

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}
LAB_CONFIGS = Path(__file__).resolve().parents[2] / "docs" / "lab" / "train_configs"
"""Training configs of staged runs that are no README row (moved out of configs/train/)."""


class _Scripted:
    """A 3-agent ParallelEnv whose last agent is padding; observation = [step, agent index], reward =
    agent index + step / 10, terminated at step 2."""

    possible_agents = ["robot_0", "robot_1", "robot_2"]

    def __init__(self):
        self.t = 0

    def observation_space(self, agent):
        return spaces.Box(-10.0, 10.0, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def _out(self):
        obs = {a: np.array([self.t, i], np.float32) for i, a in enumerate(self.possible_agents)}
        infos = {a: {"pad": float(i == 2), "metrics/kpois_visited": 1.0, "metrics/n_kpois": 4.0,
                     "metrics/success": 0.0, "reward_time": -0.01} for i, a in enumerate(self.possible_agents)}
        return obs, infos

    def reset(self, seed=None, options=None):
        self.t = 0
        return self._out()

    def step(self, actions):
        assert set(actions) == set(self.possible_agents) and actions["robot_1"].shape == (2,)
        self.t += 1
        obs, infos = self._out()
        rewards = {a: i + self.t / 10 for i, a in enumerate(self.possible_agents)}
        done = dict.fromkeys(self.possible_agents, self.t == 2)
        return obs, rewards, done, dict.fromkeys(self.possible_agents, False), infos


def test_robots_env_converts_the_parallel_envs_arrays():
    env = RobotsEnv(_Scripted())
    td = env.rollout(5, break_when_any_done=True)
    assert td.batch_size == (2,)
    expected_obs = [[[0, 0], [0, 1], [0, 2]], [[1, 0], [1, 1], [1, 2]]]  # [step, agent] at steps 0 and 1
    np.testing.assert_array_equal(td[GROUP, "observation"].numpy(), expected_obs)
    nxt = td["next", GROUP]
    np.testing.assert_allclose(nxt["reward"][..., 0].numpy(), [[0.1, 1.1, 2.1], [0.2, 1.2, 2.2]], rtol=1e-6)
    assert nxt["terminated"][..., 0].tolist() == [[False] * 3, [True] * 3] and not nxt["truncated"].any()
    assert td["next", "done"][:, 0].tolist() == [False, True]
    assert td[REAL][..., 0].tolist() == [[True, True, False]] * 2  # info["pad"] 1: padding
    assert nxt["info", "metrics/n_kpois"].tolist() == [[4.0] * 3] * 2
    assert set(nxt["info"].keys()) == {"pad", "metrics/kpois_visited", "metrics/n_kpois", "metrics/success"}
    assert "state" not in set(td.keys())


def test_env_maker_worlds_run_side_by_side_on_their_own_maps():
    maker = EnvMaker("generated:3-9", "realistic", episode_steps=5, seed=4, overrides=V2, max_robots=12,
                     worlds=3, state=False)
    assert [maker.world_seed(k) for k in range(2)][0] == 4 and maker.world_seed(1) != maker.world_seed(2)
    env = maker()
    td = env.rollout(5, break_when_any_done=False)
    assert td.batch_size == (3, 5) and td[GROUP, "observation"].shape[:3] == (3, 5, 12)
    obs = td[GROUP, "observation"][:, 0]
    assert not torch.equal(obs[0], obs[1]) and not torch.equal(obs[1], obs[2])  # three worlds, three draws
    # world 0 is the one-world env of the same seed, step for step at reset
    single = EnvMaker("generated:3-9", "realistic", episode_steps=5, seed=4, overrides=V2, state=False)().reset()
    assert torch.equal(single[GROUP, "observation"], obs[0])
    with pytest.raises(ConfigError, match="worlds"):
        MarlConfig(frames_per_batch=100, minibatch_size=10, worlds=3).check("x.yaml")


def test_map_pool_keeps_only_its_cache_of_built_maps():
    pool = MapPoolEnv("generated:3-9", max_robots=12, overrides=V2, max_cycles=5, cache=2)
    seen = []
    for seed in range(6):
        pool.reset(seed=seed)
        seen.append(pool.map_seed)
        assert len(pool.cached_seeds) <= 2 and pool.cached_seeds[-1] == pool.map_seed
    assert len(set(seen)) > 2  # more maps drawn than kept


def test_standardize_advantage_uses_the_real_robots_only():
    adv = torch.tensor([[[1.0], [3.0], [100.0]], [[5.0], [7.0], [-50.0]]])  # (time 2, robots 3, 1)
    real = torch.tensor([[[True], [True], [False]]] * 2)
    td = standardize_advantage(TensorDict({GROUP: {"advantage": adv.clone(), "real": real}}, batch_size=[2]))
    got = td[GROUP, "advantage"][..., 0]
    expected = (torch.tensor([1.0, 3.0, 5.0, 7.0]) - 4.0) / torch.tensor(5.0).sqrt()  # mean 4, variance 5
    assert torch.allclose(got[:, :2].reshape(-1), expected) and got[:, 2].tolist() == [0.0, 0.0]
    same = standardize_advantage(TensorDict({GROUP: {"advantage": adv.clone()}}, batch_size=[2]), enabled=False)
    assert torch.equal(same[GROUP, "advantage"], adv)


def test_standardize_advantage_on_small_spreads_and_a_single_real_robot():
    def standardized(values, real):
        td = TensorDict({GROUP: {"advantage": torch.tensor(values).view(1, -1, 1),
                                 "real": torch.tensor(real).view(1, -1, 1)}}, batch_size=[1])
        return standardize_advantage(td)[GROUP, "advantage"].view(-1).tolist()

    # a spread below 1 is scaled up: mean 0.2, standard deviation 0.1
    assert standardized([0.1, 0.3, 9.0], [True, True, False]) == pytest.approx([-1.0, 1.0, 0.0], rel=1e-5)
    # one real robot: its advantage minus its own mean, 0 (the deviation's floor keeps it finite)
    assert standardized([0.5, 9.0, 9.0], [True, False, False]) == [0.0, 0.0, 0.0]


def _minibatch(n_agents: int, pad_values: float) -> TensorDict:
    """A hand-built minibatch of 4 steps; agent 0 real, agents 1.. padding filled with ``pad_values``."""
    g = torch.Generator().manual_seed(0)
    b, obs = 4, 3
    real = torch.zeros(b, n_agents, 1, dtype=torch.bool)
    real[:, 0] = True

    def col(first, shape):
        x = torch.full((b, n_agents, *shape), pad_values)
        x[:, 0] = first
        return x

    return TensorDict({GROUP: {
        "observation": col(torch.randn(b, obs, generator=g), (obs,)),
        "action": col(torch.rand(b, 2, generator=g) * 1.6 - 0.8, (2,)).clamp(-0.9, 0.9),
        "action_log_prob": col(torch.randn(b, generator=g) - 1.0, ()),
        "advantage": col(torch.randn(b, 1, generator=g), (1,)),
        "value_target": col(torch.randn(b, 1, generator=g), (1,)),
        "real": real}}, batch_size=[b])


def test_padding_agents_add_nothing_to_the_loss_or_its_gradient():
    torch.manual_seed(1)
    box = spaces.Box(-np.ones(3, np.float32), np.ones(3, np.float32))
    actor = build_actor(box.low, box.high, 2, (8,))
    critic = build_critic("ippo", box, box, MarlConfig(hidden=(8,)))
    loss = build_loss("ippo", MarlConfig(entropy_coeff=0.01, value_norm="none"), actor, critic)

    def terms(td):
        torch.manual_seed(7)  # TanhNormal's entropy is a Monte Carlo estimate: the same draws for each call
        loss.zero_grad()
        parts = loss(td)
        total = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
        total.backward()
        grads = torch.cat([p.grad.flatten() for p in loss.parameters() if p.grad is not None])
        return [parts[k].item() for k in ("loss_objective", "loss_critic", "loss_entropy")], grads

    alone, _ = terms(_minibatch(1, 0.0))
    padded, g_padded = terms(_minibatch(3, 0.7))
    wild, g_wild = terms(_minibatch(3, -0.3))
    # objective and critic: the means over the real agent alone; every term and the gradient: the
    # same whatever the padding holds (observation, action, log-prob, advantage, value target)
    assert padded[:2] == pytest.approx(alone[:2], rel=1e-5)
    assert wild == pytest.approx(padded, rel=1e-5) and torch.allclose(g_wild, g_padded, atol=1e-7)
    assert alone[1] > 0.0 and padded[2] != 0.0  # the real agent's critic and entropy terms are there
    td = _minibatch(3, 0.7)
    del td[GROUP, "real"]  # without the mask every agent counts
    assert terms(td)[0][:2] != pytest.approx(alone[:2], rel=1e-3)


def _small_nets(seed: int = 1):
    torch.manual_seed(seed)
    box = spaces.Box(-np.ones(3, np.float32), np.ones(3, np.float32))
    return build_actor(box.low, box.high, 2, (8,)), build_critic("ippo", box, box, MarlConfig(hidden=(8,)))


def test_build_loss_uses_the_configured_clip_and_coefficients():
    actor, critic = _small_nets()
    assert type(build_loss("mappo", MarlConfig(), actor, critic)) is MAPPOLoss
    assert type(build_loss("ippo", MarlConfig(), actor, critic)) is IPPOLoss
    td = _minibatch(1, 0.0)
    td[GROUP, "advantage"][:, 0] = torch.tensor([[1.0], [2.0], [3.0], [4.0]])
    td[GROUP, "action_log_prob"][:, 0] = -50.0  # the old policy: ratio far above 1 + clip_epsilon

    def terms(**knobs):
        loss = build_loss("ippo", MarlConfig(value_norm="none", **knobs), actor, critic)
        torch.manual_seed(7)  # the same Monte Carlo entropy draws for each call
        parts = loss(td.clone())
        return [parts[k].item() for k in ("loss_objective", "loss_critic", "loss_entropy")]

    base = terms(clip_epsilon=0.3, entropy_coeff=0.01, critic_coeff=1.0)
    # every ratio clipped at 1.3; the advantages used as given (mean 2.5, not standardized again)
    assert base[0] == pytest.approx(-1.3 * 2.5, rel=1e-5)
    assert terms(clip_epsilon=0.1, entropy_coeff=0.01, critic_coeff=1.0)[0] == pytest.approx(-1.1 * 2.5, rel=1e-5)
    scaled = terms(clip_epsilon=0.3, entropy_coeff=0.03, critic_coeff=0.5)
    assert base[1] > 0.0 and scaled[1] == pytest.approx(0.5 * base[1], rel=1e-5)
    assert base[2] != 0.0 and scaled[2] == pytest.approx(3.0 * base[2], rel=1e-5)


def test_value_estimator_is_gae_over_each_robots_own_flags():
    actor, critic = _small_nets()
    loss = build_loss("ippo", MarlConfig(value_norm="none", gamma=0.5, gae_lambda=0.8), actor, critic)
    g = torch.Generator().manual_seed(0)
    steps, robots = 3, 2
    obs, next_obs = torch.randn(steps, robots, 3, generator=g), torch.randn(steps, robots, 3, generator=g)
    reward = torch.randn(steps, robots, 1, generator=g)
    # robot 0: truncated after step 1 (trace cut, next value kept), terminated at step 2; robot 1:
    # terminated after step 0 (trace cut, next value dropped)
    done = torch.tensor([[False, True], [True, False], [True, True]]).unsqueeze(-1)
    terminated = torch.tensor([[False, True], [False, False], [True, True]]).unsqueeze(-1)
    td = TensorDict({GROUP: {"observation": obs}, "next": {GROUP: {
        "observation": next_obs, "reward": reward, "done": done, "terminated": terminated}}}, batch_size=[steps])
    with torch.no_grad():
        loss.value_estimator(td, params=loss.critic_network_params,
                             target_params=loss.target_critic_network_params)
        value = critic(TensorDict({GROUP: {"observation": obs}}, [steps]))[GROUP, "state_value"]
        next_value = critic(TensorDict({GROUP: {"observation": next_obs}}, [steps]))[GROUP, "state_value"]
    delta = reward + 0.5 * next_value * ~terminated - value
    expected, trace = torch.zeros_like(delta), torch.zeros_like(delta[0])
    for t in reversed(range(steps)):
        trace = delta[t] + 0.5 * 0.8 * ~done[t] * trace
        expected[t] = trace
    assert torch.allclose(td[GROUP, "advantage"], expected, atol=1e-6)
    assert torch.allclose(td[GROUP, "value_target"], expected + value, atol=1e-6)


def test_prepare_minibatch_standardizes_the_advantages_only_when_asked():
    actor, critic = _small_nets()
    loss = build_loss("ippo", MarlConfig(value_norm="none"), actor, critic)
    td = _minibatch(1, 0.0)
    td[GROUP, "advantage"][:, 0] = torch.tensor([[1.0], [3.0], [5.0], [7.0]])
    kept = prepare_minibatch(loss, td.clone(), False)[GROUP, "advantage"][:, 0, 0]
    assert kept.tolist() == [1.0, 3.0, 5.0, 7.0]
    scaled = prepare_minibatch(loss, td.clone(), True)[GROUP, "advantage"][:, 0, 0]
    assert torch.allclose(scaled, (torch.tensor([1.0, 3.0, 5.0, 7.0]) - 4.0) / torch.tensor(5.0).sqrt())


def test_checkpoint_every_saves_after_each_batch_past_it(tmp_path, monkeypatch):
    saves = []
    original = marl.RunWriter.save

    def counting(run):
        saves.append(run.agent_steps)
        return original(run)

    monkeypatch.setattr(marl.RunWriter, "save", counting)
    cfg = dataclasses.replace(load_marl_config("ippo"), frames_per_batch=32, minibatch_size=32, epochs=1,
                              hidden=(8,), episode_steps=20, env=V2)
    train(TrainRequest("ippo", "office", 3 * 32 * 2, tmp_path / "a", cfg, "x"))
    assert saves == [3 * 64]  # checkpoint_every 0: once, at the end
    saves.clear()
    cfg = dataclasses.replace(cfg, checkpoint_every=1e-9)
    commits = iter(["at-start", "later", "later", "later", "later"])
    monkeypatch.setattr(marl, "git_commit", lambda where: next(commits))  # the checkout moves during the run
    record = train(TrainRequest("ippo", "office", 3 * 32 * 2, tmp_path / "b", cfg, "x"))
    assert saves == [64, 128, 192] and record["agent_steps"] == 192  # the last batch: the final save only
    assert record["commit"] == "at-start"  # the sidecar names the code the run started with
    assert (tmp_path / "b" / "policy.pt").is_file() and not list((tmp_path / "b").glob(".*.tmp"))


@pytest.mark.parametrize("kind", ["popart", "running"])
def test_value_normalizer_learns_from_the_real_robots_only(kind):
    box = spaces.Box(-np.ones(3, np.float32), np.ones(3, np.float32))
    cfg = MarlConfig(hidden=(8,), value_norm=kind)

    def norm_after(td):
        loss = build_loss("ippo", cfg, build_actor(box.low, box.high, 2, (8,)), build_critic("ippo", box, box, cfg))
        prepare_minibatch(loss, td, True)
        loss(td)  # the loss's own update call changes nothing
        return loss.value_norm.denormalize(torch.tensor([0.0, 1.0]).unsqueeze(-1))

    def batch(pad_target: float, n: int):
        td = _minibatch(n, pad_target)
        td[GROUP, "value_target"][:, 0] = torch.tensor([[2.0], [4.0], [6.0], [8.0]])
        return td

    alone, padded, wild = norm_after(batch(0.0, 1)), norm_after(batch(1000.0, 3)), norm_after(batch(-5.0, 3))
    assert torch.allclose(padded, alone) and torch.allclose(wild, alone)
    if kind == "popart":  # one update of a debiased EMA: the minibatch's mean 5 and variance 5 exactly
        assert torch.allclose(alone[:, 0], torch.tensor([5.0, 5.0 + 5.0 ** 0.5]), atol=1e-3)
    td = batch(1000.0, 3)
    del td[GROUP, "real"]  # without the mask the padding's targets move the statistics
    assert not torch.allclose(norm_after(td), alone)


def test_the_generated_worlds_config_loads_with_its_stated_changes():
    cfg = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_worlds.yaml")
    assert (cfg.worlds, cfg.frames_per_batch, cfg.minibatch_size, cfg.entropy_coeff) == (8, 4096, 512, 0.005)
    assert cfg.env == {**V2, "rewards": {**V2["rewards"], "collision": -0.25}} and cfg.preset == "realistic"
    assert cfg.checkpoint_every > 0 and cfg.wall_time > 0 and cfg.episode_steps == 800


def test_episode_steps_truncate_the_torchrl_env_not_the_env_whose_time_entry_keeps_its_own_limit():
    maker = EnvMaker("office", "realistic", episode_steps=4, seed=3, overrides=V2, state=False)
    env = maker.world(0)
    limit = env.parallel.max_cycles
    assert limit == maker.parallel().scenario.episode.max_steps and limit > 100  # the scenario's own, not 4
    td = env.rollout(10, break_when_any_done=True)
    assert td.batch_size == (4,)
    nxt = td["next", GROUP]
    assert nxt["truncated"][-1].all() and not nxt["truncated"][:-1].any() and not nxt["terminated"].any()
    t = env.parallel.layout.slices["time"]
    # the observation after step k: k / the env's step limit (an 800-step cut used to make it k / 800)
    np.testing.assert_allclose(nxt["observation"][:, 0, t].flatten().numpy(), np.arange(1, 5) / limit, rtol=1e-6)
    # the cut's episode metrics: the KPOIs visited so far (one of two marked by hand before the last step)
    from torchrl.envs.utils import step_mdp

    td = env.reset()
    for k in range(4):
        if k == 3:
            env.parallel.progress.visited[:1] = True
        td = env.rand_step(td)
        if k < 3:
            assert not td["next", "done"].any()
            td = step_mdp(td)
    info = td["next", GROUP, "info"]
    n_kpois = env.parallel.progress.visited.size
    assert n_kpois == 2 and td["next", GROUP, "truncated"].all()
    assert info["metrics/n_kpois"].tolist() == [float(n_kpois)] * env.parallel.n_robots
    assert info["metrics/kpois_visited"].tolist() == [1.0] * env.parallel.n_robots
    assert info["metrics/success"].sum().item() == 0.0


@pytest.mark.parametrize("mask_done", [False, True])
def test_mask_done_makes_a_robot_whose_route_is_done_not_real(mask_done):
    maker = EnvMaker("office", "ideal", episode_steps=4, seed=3, overrides=V2, state=False, mask_done=mask_done)
    env = maker.world(0)
    td = env.reset()
    assert td[GROUP, "real"].flatten().tolist() == [True, True]
    inner = env.parallel
    own0 = inner.plan.robots[0].kpois  # robot 0 on each of its own KPOIs in turn: its route is done
    for k in own0:
        inner.world.bodies[0].position = tuple(inner.scenario.kpois[k])
        td = env.step(td.set((GROUP, "action"), torch.zeros(2, 2)))["next"]
    assert td[GROUP, "real"].flatten().tolist() == [not mask_done, True]
    assert load_marl_config("ippo", None).mask_done is False  # default: every robot learned from


def test_the_shaped_configs_load_with_their_stated_changes():
    s3 = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_shaped.yaml")
    s4 = load_marl_config("ippo", LAB_CONFIGS / "ippo_generated_shaped_mask.yaml")
    rewards = {"own_kpoi": 10.0, "kpoi": 1.0, "collision": -0.25, "progress": 5.0, "contact": -0.1}
    assert s3.env["rewards"] == s4.env["rewards"] == rewards
    assert (s3.mask_done, s4.mask_done, s3.entropy_coeff, s4.entropy_coeff) == (False, True, 0.0, 0.0)
    assert dataclasses.replace(s3, mask_done=True, wall_time=s4.wall_time) == s4  # stage 4: only the mask


def test_the_shipped_shaped_checkpoint_names_its_four_stage_chain():
    import json

    import parcover_env
    from parcover_env.policies.torchrl_policy import TorchRLPolicy

    root = Path(parcover_env.__file__).resolve().parent.parent / "baselines" / "checkpoints" / "ippo_generated_shaped"
    if not root.is_dir():
        pytest.skip("source checkout only")
    run = json.loads((root / "run.json").read_text())
    assert run["policy"] == "torchrl:baselines/checkpoints/ippo_generated_shaped/policy.pt"
    assert run["init"]["init"]["init"]["init"] is None  # stage 4 <- 3 <- 2 <- 1 <- from scratch
    assert run["config"]["mask_done"] and run["init_run"]["config"]["env"]["rewards"]["contact"] == -0.1
    steps = [run["agent_steps"], run["init_run"]["agent_steps"], run["init_run"]["init_run"]["agent_steps"],
             run["init_run"]["init_run"]["init_run"]["agent_steps"]]
    assert sum(steps) == 10_509_297 <= 20_000_000
    TorchRLPolicy(root / "policy.pt")  # loads

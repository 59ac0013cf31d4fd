"""The batched TorchRL env (``parcover_env.train``): collection equals separate envs for a fixed policy.

A fixed deterministic policy (actions linear in the observation, through tanh) drives the batched
env the way TorchRL's collector does (``step_and_maybe_reset``); every episode of every world is
replayed on a separate ``parallel_env`` of the same map, reset with the same seed and given the
same actions: observations, rewards and ends are equal bit for bit, padding is zeros, idle steps
are padding, a group draws a new map only when all its worlds have ended.
"""

from __future__ import annotations

import copy
import dataclasses
import pickle

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

import parcover_env  # noqa: E402
from parcover_env.errors import ConfigError  # noqa: E402
from parcover_env.train.batched_env import BatchedRobotsEnv  # noqa: E402
from parcover_env.train.world_groups import WorldGroups, WorldsConfig  # noqa: E402

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}
POOL = WorldsConfig("generated:3-8", worlds=4, worlds_per_map=2, max_robots=6, overrides=V2, episode_steps=9,
                    state=True)


def policy(obs: np.ndarray, act_dim: int = 2) -> np.ndarray:
    """A fixed deterministic policy: ``tanh(obs W + c)`` with W, c from a fixed generator."""
    rng = np.random.default_rng(1234)
    w = rng.normal(0.0, 0.3, size=(obs.shape[-1], act_dim)).astype(np.float32)
    c = np.array([0.6, 0.0, -0.5][:act_dim], dtype=np.float32)
    return np.tanh(obs @ w + c).astype(np.float32)


def collect(env: BatchedRobotsEnv, steps: int, forced: dict[int, list[int]] | None = None,
            td=None) -> tuple[list[dict], object]:
    """Run ``steps`` steps as TorchRL's collector does; ``forced[t]``: worlds reset by hand after step t
    (abandoning their episodes). Returns one record per step (root, next, post-reset root, and the
    worlds' bookkeeping after the step and after the reset)."""
    forced = forced or {}
    td = env.reset() if td is None else td
    records = []
    for t in range(steps):
        obs = td["robot", "observation"].numpy()
        td["robot", "action"] = torch.from_numpy(policy(obs))
        td, nxt = env.step_and_maybe_reset(td)
        if t in forced:
            mask = torch.zeros(env.worlds.size, 1, dtype=torch.bool)
            mask[forced[t]] = True
            nxt.set("_reset", mask)
            nxt = env.reset(nxt)
        w = env.worlds
        records.append({"td": td.clone(), "after": nxt.clone(), "running": w.running.copy(),
                        "seed": w.episode_seed.copy(), "map": w.map_seed.copy(), "draws": w.draws.copy(),
                        "forced": forced.get(t, [])})
        td = nxt
    return records, td


def replay(env: BatchedRobotsEnv, first, records: list[dict], overrides) -> int:
    """Check every world's transitions in ``records`` against separate envs; returns the episodes checked."""
    w = env.worlds
    refs: dict[tuple[int, int], object] = {}
    episodes = 0

    def start(b: int, map_seed: int, seed: int, obs_b: torch.Tensor) -> object:
        nonlocal episodes
        scenario = w.cfg.scenario if map_seed < 0 else f"generated:{map_seed}"
        key = (b, map_seed)
        if key not in refs:
            refs[key] = parcover_env.parallel_env(scenario, overrides=overrides)
        ref = refs[key]
        ref_obs, _ = ref.reset(seed=int(seed))
        n = ref.n_robots
        np.testing.assert_array_equal(obs_b[:n].numpy(), np.stack([ref_obs[a] for a in ref.possible_agents]))
        assert not obs_b[n:].any()
        episodes += 1
        return ref

    cur = {b: start(b, int(first["map"][w.group_of(b)]), int(first["seed"][b]), first["td"]["robot", "observation"][b])
           for b in range(w.size)}
    for rec in records:
        td, after = rec["td"], rec["after"]
        for b in range(w.size):
            g = w.group_of(b)
            real, pad = td["robot", "real"][b, :, 0], td["robot", "info", "pad"][b]
            nxt = td["next"]
            ref = cur[b]
            if ref is None:  # idle: padding, not done, nothing counted
                assert not real.any() and (pad == 1).all() and not td["robot", "observation"][b].any()
                assert not nxt["robot", "reward"][b].any() and not nxt["done"][b].any()
            else:
                n = ref.n_robots
                assert real[:n].all() and not real[n:].any() and (pad[:n] == 0).all() and (pad[n:] == 1).all()
                act = td["robot", "action"][b].numpy()
                names = ref.possible_agents
                o, r, term, trunc, _ = ref.step(dict(zip(names, act[:n], strict=True)))
                np.testing.assert_array_equal(nxt["robot", "observation"][b, :n].numpy(),
                                              np.stack([o[a] for a in names]))
                np.testing.assert_array_equal(nxt["robot", "reward"][b, :n, 0].numpy(),
                                              np.array([r[a] for a in names], dtype=np.float32))
                assert not nxt["robot", "observation"][b, n:].any() and not nxt["robot", "reward"][b, n:].any()
                cut = bool(w.cfg.episode_steps) and ref.steps >= w.cfg.episode_steps
                want_done = term[names[0]] or trunc[names[0]] or cut
                assert bool(nxt["done"][b]) == want_done and bool(nxt["terminated"][b]) == term[names[0]]
                assert (nxt["robot", "done"][b] == want_done).all()
                if "state" in td:
                    np.testing.assert_array_equal(nxt["state"][b].numpy(), ref.state())
                if want_done:
                    visited = ref.progress.visited
                    assert float(nxt["robot", "info", "metrics/kpois_visited"][b, 0]) == float(visited.sum())
                    assert float(nxt["robot", "info", "metrics/n_kpois"][b, -1]) == float(visited.size)
                    cur[b] = None
            if b in rec["forced"]:
                cur[b] = None
            # a world whose next root observation starts an episode (after a draw or a reset)
            started = rec["running"][b] and cur[b] is None
            if started:
                cur[b] = start(b, int(rec["map"][g]), int(rec["seed"][b]), after["robot", "observation"][b])
            elif cur[b] is not None and b not in rec["forced"]:
                np.testing.assert_array_equal(after["robot", "observation"][b], nxt["robot", "observation"][b])
    return episodes


@pytest.fixture(scope="module")
def pool_run():
    env = BatchedRobotsEnv(POOL, seed=7)
    first = {"td": env.reset(), "map": env.worlds.map_seed.copy(), "seed": env.worlds.episode_seed.copy()}
    records, _ = collect(env, 30, forced={3: [0]}, td=first["td"])
    return env, first, records


def test_pool_collection_equals_separate_envs_step_for_step(pool_run):
    env, first, records = pool_run
    # 4 worlds, each cut at 9 steps: started at 0 and after steps 8, 17, 26 (world 0, reset by hand
    # after step 3, idles until its mate's cut at step 8)
    assert replay(env, first, records, V2) == 4 * 4


def test_a_group_draws_only_when_all_its_worlds_have_ended(pool_run):
    env, first, records = pool_run
    draws = np.stack([r["draws"] for r in records])  # (steps, groups)
    maps = np.stack([r["map"] for r in records])
    # cut every 9 steps; world 0 (group 0) reset by hand after step 3 idles until its mate's cut at step 8
    assert draws[:, 0].tolist() == [1] * 8 + [2] * 9 + [3] * 9 + [4] * 4
    assert draws[:, 1].tolist() == draws[:, 0].tolist()
    for t in range(1, len(records)):
        changed = draws[t] != draws[t - 1]
        assert (maps[t][~changed] == maps[t - 1][~changed]).all()  # the map changes only with a draw
    real = [r["td"]["robot", "real"][0].any().item() for r in records]
    assert real[4:9] == [False] * 5 and real[3] and real[9]  # world 0 idles from its reset to the draw
    assert not any(r["td"]["next", "done"][0].item() for r in records[4:9])  # idle steps never end
    assert records[8]["running"].tolist() == [True] * 4  # all started again at the draw


def test_padding_is_zero_and_its_actions_change_nothing():
    cfg = WorldsConfig("generated:3-8", worlds=2, worlds_per_map=1, max_robots=6, overrides=V2)
    a, b = WorldGroups(cfg, seed=1), WorldGroups(cfg, seed=1)
    ta, tb = a.reset(), b.reset()
    for _ in range(5):
        act = policy(ta.observation)
        wild = act.copy()
        for g in range(2):
            wild[g, a.n_robots[g]:] = [[-1.0, 1.0]]  # the padding agents' rows
        ta, tb = a.step(act), b.step(wild)
        for x, y in zip(ta[:5], tb[:5], strict=True):
            np.testing.assert_array_equal(x, y)
        for g in range(2):
            n = int(a.n_robots[g])
            assert n < 6 and not ta.observation[g, n:].any() and not ta.reward[g, n:].any()
            assert not ta.real[g, n:].any() and (ta.info["pad"][g, n:] == 1).all() and ta.real[g, :n].all()


def test_same_seed_same_collection_other_seed_other_maps():
    def run(seed):
        env = BatchedRobotsEnv(POOL, seed=seed)
        records, _ = collect(env, 12)
        return env, torch.stack([r["td"]["next", "robot", "observation"] for r in records])

    (e1, a), (_, b), (_, c) = run(5), run(5), run(6)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)
    e1.set_seed(6)  # re-seeded mid-run: the next full reset draws as a fresh env seeded 6
    fresh = BatchedRobotsEnv(POOL, seed=6)
    assert (e1.reset() == fresh.reset()).all()
    assert (e1.worlds.map_seed == fresh.worlds.map_seed).all()
    assert (e1.worlds.episode_seed == fresh.worlds.episode_seed).all()


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_mid_rollout_continues_bit_identically(how):
    env = BatchedRobotsEnv(POOL, seed=3)
    _, td = collect(env, 6, forced={2: [1]})
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    td_twin = td.clone()
    rest, _ = collect(env, 10, td=td)
    rest_twin, _ = collect(twin, 10, td=td_twin)
    for x, y in zip(rest, rest_twin, strict=True):
        assert (x["td"] == y["td"]).all() and (x["after"] == y["after"]).all()
        assert (x["map"] == y["map"]).all() and (x["seed"] == y["seed"]).all()


@pytest.mark.parametrize("episode_steps, overrides", [(4, None), (0, {"episode": {"max_steps": 4}})])
def test_a_scenario_restarts_each_world_at_once(episode_steps, overrides):
    """One map: no idling; an episode cut by ``episode_steps`` or ended by the env's own step limit."""
    cfg = WorldsConfig("office", worlds=2, worlds_per_map=2, episode_steps=episode_steps, overrides=overrides)
    env = BatchedRobotsEnv(cfg, seed=2)
    first = {"td": env.reset(), "map": env.worlds.map_seed.copy(), "seed": env.worlds.episode_seed.copy()}
    records, _ = collect(env, 10, forced={5: [1]}, td=first["td"])
    # ends every 4 steps (after steps 3 and 7; world 1, reset by hand after step 5, after step 9 too)
    assert replay(env, first, records, overrides) == 3 + 4
    ends = [r["td"]["next", "truncated"][:, 0].tolist() for r in records]
    assert ends[3] == [True, True] and ends[7] == [True, False] and ends[9] == [False, True]
    assert all(r["running"].all() for r in records)  # no idling on one map
    assert (first["td"]["robot", "info", "pad"] == 0).all()


@pytest.mark.parametrize("field, value, match", [
    ("worlds", 0, "worlds: must be an integer >= 1"),
    ("worlds_per_map", 3, "worlds_per_map: must divide worlds"),
    ("episode_steps", -1, "episode_steps: must be an integer >= 0"),
    ("max_robots", 2, "more than the pool's max_robots 2"),
])
def test_a_bad_config_is_one_config_error(field, value, match):
    cfg = WorldsConfig("generated:3-4", worlds=4, worlds_per_map=2, overrides=V2)
    with pytest.raises(ConfigError, match=match):
        WorldGroups(dataclasses.replace(cfg, **{field: value}))
    with pytest.raises(ConfigError, match="seed"):
        WorldGroups(cfg, seed=-1)
    with pytest.raises(ConfigError, match="evaluation maps"):
        WorldGroups(WorldsConfig("generated:998-1001"))


@pytest.mark.parametrize("mask_done", [False, True])
def test_mask_done_makes_a_robot_whose_route_is_done_not_real(mask_done):
    cfg = WorldsConfig("office", worlds=2, preset="ideal", overrides=V2, mask_done=mask_done)
    groups = WorldGroups(cfg, seed=3)
    t = groups.reset()
    assert t.real.tolist() == [[True, True], [True, True]]
    inner = groups.worlds[1]
    for k in inner.plan.robots[0].kpois:  # world 1's robot 0 on each of its own KPOIs in turn: its route is done
        inner.world.bodies[0].position = tuple(inner.scenario.kpois[k])
        t = groups.step(np.zeros((2, 2, 2), dtype=np.float32))
    assert t.real.tolist() == [[True, True], [not mask_done, True]]
    assert (t.info["pad"] == 0).all()

"""Determinism: reset/seed sequences, deepcopy and pickle of an env mid-episode, and the same run in
a spawned child process versus in-process."""

from __future__ import annotations

import copy
import multiprocessing
import pickle

import numpy as np
import pytest
from reliability_helpers import assert_same_records, assert_same_snapshot, continue_rollout, rollout, snapshot

import parcover_env as pe

SCENARIOS = pe.scenario_names()
STEPS = {"tree": 15}  # 15 robots and 4 Kinects: fewer steps keep CI fast; others use the default


@pytest.mark.parametrize("name", SCENARIOS)
def test_reset_seed_sequences_repeat(name):
    """reset(seed) -> steps -> reset() -> steps -> reset(seed') ... gives the same records in two
    independent envs, and reset(seed) on a used env equals reset(seed) on a fresh one."""
    def run(env):
        out = []
        for seed in (7, None, 7, 123, None):
            obs, _ = env.reset(seed=seed)
            out.append((np.stack([obs[a] for a in sorted(obs)]), np.zeros(0), (), ()))
            out += continue_rollout(env, action_seed=0 if seed is None else seed, steps=STEPS.get(name, 40))
        return out

    a, b = pe.parallel_env(name), pe.parallel_env(name)
    ra = run(a)
    b.reset(seed=999)  # some unrelated history first: reset(seed) must wipe it
    continue_rollout(b, 1, 30)
    assert_same_records(ra, run(b))


@pytest.mark.parametrize("name", SCENARIOS)
def test_different_seeds_differ(name):
    """The seed reaches the sensors: two seeds give different observations for the same actions."""
    env = pe.parallel_env(name)
    env.reset(seed=1)
    r1 = continue_rollout(env, 0, 20)
    env.reset(seed=2)
    r2 = continue_rollout(env, 0, 20)
    assert any(not np.array_equal(a[0], b[0]) for a, b in zip(r1, r2, strict=True))


@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_clone_mid_episode_continues_identically(name, how):
    env = pe.parallel_env(name)
    env.reset(seed=5)
    continue_rollout(env, 2, 2 * STEPS.get(name, 30))  # contacts, Kinect ticks, odometry drift happened
    clone = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert_same_snapshot(snapshot(env), snapshot(clone))
    # continue past the episode end (reset without seed inside the rollout) on both
    n = 3 * STEPS.get(name, 40)
    ra = continue_rollout(env, 3, n)
    rb = continue_rollout(clone, 3, n)
    assert_same_records(ra, rb)
    assert_same_snapshot(snapshot(env), snapshot(clone))
    np.testing.assert_array_equal(env.world.wall_contacts, clone.world.wall_contacts)
    np.testing.assert_array_equal(env.world.robot_contacts, clone.world.robot_contacts)


def test_clone_is_independent():
    """Stepping the clone never moves the original (no shared command array or pymunk state)."""
    env = pe.parallel_env("office")
    env.reset(seed=0)
    continue_rollout(env, 0, 10)
    before = snapshot(env)
    for clone in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        continue_rollout(clone, 9, 30)
        assert_same_snapshot(before, snapshot(env))


def test_pickle_before_reset_and_after_end():
    env = pe.parallel_env("t_room", overrides={"episode": {"max_steps": 5}})
    fresh = pickle.loads(pickle.dumps(env))
    assert_same_records(rollout_from(env), rollout_from(fresh))
    assert env.agents == []  # the episode ended: a finished env pickles too
    pickle.loads(pickle.dumps(env))


def rollout_from(env) -> list:
    env.reset(seed=4)
    return continue_rollout(env, 4, 5)


def test_spawned_process_matches_in_process():
    """The multi-process path: the same rollout in a ``spawn`` child equals the in-process one."""
    args = ("office", {"n_robots": 4}, (0, 3), 40)
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        child = pool.apply(rollout, args)
    assert_same_records(rollout(*args), child)


@pytest.mark.slow
def test_vec_env_single_vs_multi_process():
    """``make_vec_env`` in-process and with worker processes give identical runs (incl. auto-resets)."""
    pytest.importorskip("stable_baselines3")
    sb3 = pytest.importorskip("parcover_env.envs.vec_env")
    overrides = {"episode": {"max_steps": 25}}  # two auto-resets inside the run
    runs = []
    for multiprocess in (False, True):
        venv = sb3.make_vec_env("office", n_envs=2, overrides=overrides, multiprocess=multiprocess,
                                monitor=False)
        try:
            venv.seed(10)
            rec = [venv.reset()]
            rng = np.random.default_rng(0)
            for _ in range(60):
                obs, rew, done, infos = venv.step(rng.uniform(-1, 1, (venv.num_envs, 2)).astype(np.float32))
                rec += [obs, rew, done.astype(float)]
        finally:
            venv.close()
        runs.append(rec)
    for i, (a, b) in enumerate(zip(*runs, strict=True)):
        np.testing.assert_array_equal(a, b, err_msg=f"record {i}")

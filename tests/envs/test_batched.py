"""Batched worlds (``make_vec_env(..., backend="batched")``): world k is bit for bit the ParallelEnv
made with seed s + k, through auto-resets, under both presets; copies continue identically."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import parcover_env  # noqa: E402
from parcover_env.envs.batched import BatchedVecEnv  # noqa: E402
from parcover_env.envs.vec_env import ParallelVecEnv, make_vec_env  # noqa: E402
from parcover_env.errors import ActionError  # noqa: E402
from parcover_env.mission.metrics import episode_metrics  # noqa: E402


def _equal(a, b) -> bool:
    """Exact equality of nested infos (dicts, lists, floats, numpy arrays)."""
    if isinstance(a, dict) or isinstance(b, dict):
        return isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys() and all(
            _equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True  # e.g. metrics/makespan of an episode that did not finish
    return type(a) is type(b) and a == b


class Reference:
    """K separate ParallelEnvs driven by hand with the VecEnv conventions (seed s + k once, then
    ``reset()`` without a seed when an episode ends)."""

    def __init__(self, scenario, k, overrides, preset, seed):
        self.envs = [parcover_env.parallel_env(scenario, overrides=overrides, preset=preset) for _ in range(k)]
        self.obs = [e.reset(seed=seed + i)[0] for i, e in enumerate(self.envs)]

    def observations(self):
        return np.concatenate([np.stack([o[a] for a in e.possible_agents]) for e, o in zip(self.envs, self.obs)])

    def step(self, actions):
        n = self.envs[0].n_robots
        rewards, dones, infos = [], [], []
        for k, e in enumerate(self.envs):
            names = e.possible_agents
            obs, rew, term, trunc, inf = e.step({a: actions[k * n + i] for i, a in enumerate(names)})
            for a in names:
                info = dict(inf[a])
                m = episode_metrics(info)
                if m is not None:
                    info["metrics"] = m
                info["active"] = True
                if term[a] or trunc[a]:
                    info["terminal_observation"] = obs[a]
                    info["TimeLimit.truncated"] = trunc[a] and not term[a]
                infos.append(info)
                rewards.append(np.float32(rew[a]))
                dones.append(term[a] or trunc[a])
            self.obs[k] = e.reset()[0] if not e.agents else obs
        return self.observations(), np.array(rewards), np.array(dones), infos


FAST_SONAR = {"model": "fast", "dropout_prob": 0.1}


@pytest.mark.parametrize("scenario,preset,k,max_steps,steps,version,sonar", [
    ("office", "realistic", 3, 25, 60, 1, None),
    ("office", "ideal", 3, 25, 60, 1, None),
    ("tree", "realistic", 2, 20, 50, 1, None),
    ("tree", "ideal", 2, 20, 50, 1, None),
    ("tree", "realistic", 2, 20, 50, 2, None),  # observation version 2: route and teammate entries over (K, N)
    ("generated:7", "realistic", 3, 20, 45, 2, None),
    ("tree", "realistic", 3, 20, 50, 1, FAST_SONAR),
])
def test_batched_worlds_equal_separate_parallel_envs(scenario, preset, k, max_steps, steps, version, sonar):
    overrides = {"episode": {"max_steps": max_steps}, "observation": {"version": version},
                 "rewards": {"own_kpoi": 10.0 if version == 2 else 0.0}}
    if sonar:
        overrides["robot"] = {"sonar": sonar}
    venv = make_vec_env(scenario, n_envs=k, overrides=overrides, backend="batched", preset=preset, monitor=False)
    assert isinstance(venv, BatchedVecEnv)
    ref = Reference(scenario, k, overrides, preset, seed=11)
    n = ref.envs[0].n_robots
    assert venv.num_envs == k * n
    venv.seed(11)
    assert np.array_equal(venv.reset(), ref.observations())
    rng = np.random.default_rng(3)
    n_done = n_terminal = 0
    for _ in range(steps):
        acts = rng.uniform(-1, 1, (venv.num_envs, 2)).astype(np.float32)
        obs, rew, done, infos = venv.step(acts)
        r_obs, r_rew, r_done, r_infos = ref.step(acts)
        assert np.array_equal(obs, r_obs)
        assert np.array_equal(rew, r_rew) and rew.dtype == np.float32
        assert np.array_equal(done, r_done)
        assert all(_equal(a, b) for a, b in zip(infos, r_infos, strict=True))
        n_done += int(done.sum())
        n_terminal += sum("terminal_observation" in i for i in infos)
    assert n_done >= 2 * k * n  # every world auto-reset at least twice (truncated at max_steps)
    assert n_terminal == n_done


def test_seeds_per_world_differ_and_repeat():
    venv = make_vec_env("office", n_envs=2, backend="batched", monitor=False)
    assert venv.seed(5) == [5, 6]
    o1 = venv.reset()
    venv.seed(5)
    assert np.array_equal(venv.reset(), o1)
    n = venv.n_robots
    acts = np.full((venv.num_envs, 2), 0.5, np.float32)
    obs, *_ = venv.step(acts)
    assert not np.array_equal(obs[:n], obs[n:])  # worlds 0 and 1 draw different noise


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copy_mid_episode_continues_identically(how):
    venv = make_vec_env("office", n_envs=2, overrides={"episode": {"max_steps": 15}}, backend="batched",
                        monitor=False)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (30, venv.num_envs, 2)).astype(np.float32)
    for a in acts[:7]:
        venv.step(a)
    twin = copy.deepcopy(venv) if how == "deepcopy" else pickle.loads(pickle.dumps(venv))
    for a in acts[7:]:  # crosses the auto-reset at step 15
        o1, r1, d1, i1 = venv.step(a)
        o2, r2, d2, i2 = twin.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        assert all(_equal(x, y) for x, y in zip(i1, i2, strict=True))


def test_vec_env_api():
    venv = make_vec_env("office", n_envs=2, backend="batched", render_mode="rgb_array", monitor=False)
    n = venv.n_robots
    obs = venv.reset()
    assert obs.shape == (2 * n, *venv.observation_space.shape) and obs.dtype == venv.observation_space.dtype
    assert all(venv.observation_space.contains(o) for o in obs)
    obs, rew, done, infos = venv.step(np.zeros((2 * n, 2), np.float32))
    assert all(venv.observation_space.contains(o) for o in obs)
    assert len(infos) == 2 * n and all(i["active"] for i in infos)
    assert venv.get_attr("n_robots") == [n] * (2 * n)
    assert venv.get_attr("steps", indices=[0, n]) == [1, 1]
    venv.set_attr("max_cycles", 7, indices=[n])  # world 1 only
    assert venv.get_attr("max_cycles", indices=[0, n]) == [venv.worlds[0].scenario.episode.max_steps, 7]
    poses = venv.env_method("true_poses", indices=[n - 1, n])
    assert np.array_equal(poses[0], venv.worlds[0].true_poses())
    assert np.array_equal(poses[1], venv.worlds[1].true_poses())
    drive = np.zeros((2 * n, 2), np.float32)
    drive[:n, 0] = 1.0  # world 0 drives ahead, world 1 stands still
    for _ in range(10):
        venv.step(drive)
    frames = venv.get_images()
    assert len(frames) == 2 * n and frames[0] is frames[n - 1] and frames[0].ndim == 3
    assert frames[0].dtype == np.uint8 and not np.array_equal(frames[0], frames[n])
    with pytest.raises(ValueError, match="rows"):
        venv.step(np.zeros((2 * n + 1, 2), np.float32))
    bad = np.zeros((2 * n, 2), np.float32)
    bad[n + 1, 1] = np.nan  # world 1's second robot
    with pytest.raises(ActionError, match=f"{venv.agents_per_world[1]}: action contains NaN"):
        venv.step(bad)
    with pytest.raises(ActionError, match=r"must have shape \(2,\)"):
        venv.step(np.zeros((2 * n, 3), np.float32))
    assert venv.get_attr("steps", indices=[0, n]) == [11, 11]  # no world stepped
    venv.step(np.zeros((2 * n, 2), np.int64))  # integers: validated, then taken as they are
    assert venv.get_attr("steps", indices=[0, n]) == [12, 12]
    venv.close()


def test_backend_selection_and_multiprocess_alias():
    assert isinstance(make_vec_env("office", 1, backend="inprocess", monitor=False), ParallelVecEnv)
    v = make_vec_env("office", 1, multiprocess=False, monitor=False)
    assert isinstance(v, ParallelVecEnv) and not v.multiprocess
    with pytest.raises(ValueError, match="backend"):
        make_vec_env("office", 1, backend="gpu")
    with pytest.raises(ValueError, match="contradicts"):
        make_vec_env("office", 1, multiprocess=True, backend="batched")
    from parcover_env.envs import vec_env

    assert vec_env.BatchedVecEnv is BatchedVecEnv


def test_sonar_cast_is_batched_once_per_step(monkeypatch):
    """The step casts the rings of all robots of all worlds in one call, not one per world."""
    venv = make_vec_env("office", n_envs=3, backend="batched", monitor=False)
    venv.reset()
    sonar = venv.worlds[0].sonar
    calls = []
    orig = type(sonar).readings

    def spy(self, poses, *a, **kw):
        calls.append(np.shape(poses))
        return orig(self, poses, *a, **kw)

    monkeypatch.setattr(type(sonar), "readings", spy)
    venv.step(np.zeros((venv.num_envs, 2), np.float32))
    assert calls == [(3, venv.n_robots, 3)]

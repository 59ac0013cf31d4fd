"""The lidar as an observation option, in the ParallelEnv and in the batched worlds: hand-built
values (wall distances, a robot in the beam, max range), noise statistics, bit-identity."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from test_batched import Reference  # noqa: E402

import parcover_env  # noqa: E402
from parcover_env.envs.batched import BatchedVecEnv  # noqa: E402


def _lidar(n_rays=4, noise=0.0, range_max=3.0):
    return {"robot": {"lidar": {"enabled": True, "n_rays": n_rays, "noise_std": noise, "range_max": range_max}}}


def _rows(obs, layout, name="lidar"):
    return obs[..., layout.slices[name]]


T_ROOM = [3.0, 0.8, 0.5, 0.8]
"""t_room's robot at (2, 0.5) facing +y: ahead the far wall at 3.5 m is beyond 3 m (range_max);
left and right the walls x = 1.2 and 2.8 at 0.8 m; behind the wall y = 0 at 0.5 m."""
OFFICE_BEAM = 0.4 - 0.12
"""office's two robots start 0.4 m apart in a column facing -x (radius 0.12 m): the leader's
backward ray and the follower's forward ray hit the other's disc at 0.28 m."""


def test_off_by_default_and_absent_from_the_layout():
    env = parcover_env.parallel_env("t_room")
    assert "lidar" not in env.layout.slices and env.sensors["lidar"] is None


def test_parallel_env_reads_the_walls_and_max_range():
    env = parcover_env.parallel_env("t_room", overrides=_lidar())
    obs, _ = env.reset(seed=0)
    assert env.layout.names[-1] == "lidar" and env.observation_space("robot_0").shape == (env.layout.size,)
    np.testing.assert_allclose(_rows(obs["robot_0"], env.layout), T_ROOM, atol=1e-6)
    space = env.observation_space("robot_0")
    assert space.high[env.layout.slices["lidar"]].tolist() == [3.0] * 4 and space.contains(obs["robot_0"])


def test_parallel_env_sees_the_robot_in_the_beam():
    env = parcover_env.parallel_env("office", overrides=_lidar(n_rays=8))
    obs, _ = env.reset(seed=0)
    true = env.true_poses()
    assert np.allclose(true[:, 1], true[0, 1]) and np.allclose(true[:, 2], np.pi)  # the hand-built column
    assert _rows(obs["robot_0"], env.layout)[4] == pytest.approx(OFFICE_BEAM, abs=1e-6)  # behind: robot 1
    assert _rows(obs["robot_1"], env.layout)[0] == pytest.approx(OFFICE_BEAM, abs=1e-6)  # ahead: robot 0


def test_parallel_env_noise_statistics():
    sigma, got = 0.05, []
    env = parcover_env.parallel_env("t_room", overrides=_lidar(noise=sigma))
    for seed in range(150):
        obs, _ = env.reset(seed=seed)
        got.append(_rows(obs["robot_0"], env.layout))
    got = np.array(got, dtype=float)
    assert np.all(got[:, 0] == 3.0)  # no hit: exactly range_max, never noisy
    err = (got[:, 1:] - T_ROOM[1:]).ravel()
    assert abs(err.mean()) < 4 * sigma / np.sqrt(err.size)
    assert err.std() == pytest.approx(sigma, rel=0.15)


def test_noise_free_lidar_changes_no_other_entry():
    plain = parcover_env.parallel_env("office")
    lidar = parcover_env.parallel_env("office", overrides=_lidar(n_rays=8))
    o1, _ = plain.reset(seed=4)
    o2, _ = lidar.reset(seed=4)
    rng = np.random.default_rng(0)
    for _ in range(15):
        for a in o1:
            assert np.array_equal(o1[a], o2[a][: plain.layout.size])
        acts = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in plain.agents}
        o1, *_ = plain.step(acts)
        o2, *_ = lidar.step(acts)


def test_batched_worlds_read_the_hand_built_values():
    venv = BatchedVecEnv("t_room", 3, _lidar())
    venv.seed(0)
    obs = venv.reset()
    layout = venv.worlds[0].layout
    np.testing.assert_allclose(_rows(obs, layout), np.tile(T_ROOM, (3, 1)), atol=1e-6)
    office = BatchedVecEnv("office", 2, _lidar(n_rays=8))
    office.seed(0)
    obs = office.reset()
    lay = office.worlds[0].layout
    assert _rows(obs, lay)[[0, 2], 4] == pytest.approx([OFFICE_BEAM] * 2, abs=1e-6)  # each world's leader
    assert _rows(obs, lay)[[1, 3], 0] == pytest.approx([OFFICE_BEAM] * 2, abs=1e-6)  # each world's follower


def test_batched_worlds_noise_statistics_after_a_step():
    sigma, k = 0.05, 60
    venv = BatchedVecEnv("t_room", k, _lidar(noise=sigma))
    venv.seed(0)
    venv.reset()
    obs, *_ = venv.step(np.zeros((k, 2), np.float32))  # standing still: the same distances, new noise
    got = _rows(obs, venv.worlds[0].layout).astype(float)
    err = (got[:, 1:] - T_ROOM[1:]).ravel()
    assert np.all(got[:, 0] == 3.0)
    assert abs(err.mean()) < 4 * sigma / np.sqrt(err.size)
    assert err.std() == pytest.approx(sigma, rel=0.2)


@pytest.mark.parametrize("how", ["none", "deepcopy", "pickle"])
def test_batched_worlds_with_lidar_equal_separate_envs(how):
    overrides = {**_lidar(n_rays=12, noise=0.02), "episode": {"max_steps": 12}}
    venv = BatchedVecEnv("office", 2, overrides)
    ref = Reference("office", 2, overrides, "realistic", seed=21)
    venv.seed(21)
    assert np.array_equal(venv.reset(), ref.observations())
    rng = np.random.default_rng(1)
    acts = rng.uniform(-1, 1, (30, venv.num_envs, 2)).astype(np.float32)
    for t, a in enumerate(acts):
        if t == 5 and how != "none":
            venv = copy.deepcopy(venv) if how == "deepcopy" else pickle.loads(pickle.dumps(venv))
        obs, rew, done, _ = venv.step(a)
        r_obs, r_rew, r_done, _ = ref.step(a)
        assert np.array_equal(obs, r_obs) and np.array_equal(rew, r_rew) and np.array_equal(done, r_done)


def test_single_robot_env_reads_the_lidar():
    from parcover_env.envs.single_agent import SingleRobotCoverageEnv

    env = SingleRobotCoverageEnv("t_room", overrides=_lidar())
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    np.testing.assert_allclose(_rows(obs, env.par.layout), T_ROOM, atol=1e-6)

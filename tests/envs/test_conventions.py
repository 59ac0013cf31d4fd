"""Conventions the ecosystem's clients rely on: PettingZoo (human render, np_random, max_cycles,
finite state bounds, parcover_v0), flat infos with constant keys (TorchRL builds its info spec from
the reset infos), and Gymnasium/SB3 ids in worker processes without a module prefix."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import render_test

import parcover_env

ROOT = Path(__file__).resolve().parents[2]


def test_parcover_v1_module_follows_the_pettingzoo_convention():
    from parcover_env import parcover_v1

    assert parcover_v1.raw_env is parcover_env.ParallelCoverageEnv
    par = parcover_v1.parallel_env("t_room")
    assert isinstance(par, parcover_env.ParallelCoverageEnv) and par.metadata["name"] == "parcover_v1"
    aec = parcover_v1.env("t_room")
    assert aec.unwrapped.metadata["name"] == "parcover_v1"


def test_parcover_v0_module_is_the_ideal_preset_without_covariance_entries():
    from parcover_env import parcover_v0

    v0, v1 = parcover_v0.parallel_env("t_room"), parcover_env.parallel_env("t_room")
    assert v0.scenario == parcover_env.load_scenario("t_room", preset="ideal")
    assert "sigma_major" in v1.layout.slices and "sigma_major" not in v0.layout.slices
    assert v0.layout.size == v1.layout.size - 5
    assert parcover_v0.env("t_room").unwrapped.scenario == v0.scenario
    assert parcover_v0.raw_env("t_room").scenario == v0.scenario
    # each version reports its own name (v0 was reported as parcover_v1)
    assert v0.metadata["name"] == "parcover_v0" and v1.metadata["name"] == "parcover_v1"
    assert parcover_v0.env("t_room").unwrapped.metadata["name"] == "parcover_v0"
    assert parcover_env.ParallelCoverageEnv.metadata["name"] == "parcover_v1"


def test_human_render_mode_shows_a_window(monkeypatch):
    from parcover_env.viz import render

    shown = []
    monkeypatch.setattr(render, "_has_display", lambda: True)
    monkeypatch.setattr(render.cv2, "imshow", lambda name, img: shown.append((name, img.shape)))
    monkeypatch.setattr(render.cv2, "waitKey", lambda ms: -1)
    monkeypatch.setattr(render.cv2, "destroyWindow", lambda name: shown.append(("closed", name)))

    def make(render_mode=None):
        return parcover_env.env("office", render_mode=render_mode)

    render_test(make)  # PettingZoo's check over every mode in metadata, "human" included, via the AEC form
    assert len(shown) >= 5 and shown[0][0] == "parcover office" and shown[0][1][2] == 3
    assert ("closed", "parcover office") in shown


def test_human_render_without_a_display_warns_once_and_shows_nothing(monkeypatch):
    from parcover_env.viz import render

    monkeypatch.setattr(render, "_has_display", lambda: False)
    monkeypatch.setattr(render, "_WARNED", set())
    monkeypatch.setattr(render.cv2, "imshow", lambda *a: pytest.fail("no window may open without a display"))
    env = parcover_env.parallel_env("t_room", render_mode="human")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="shows nothing: no display") as caught:
        assert env.render() is None
        env.step({a: np.zeros(2, np.float32) for a in env.agents})
        assert env.render() is None
    assert len(caught) == 1
    env.close()


def test_human_render_without_opencv_gui_warns_once_and_shows_nothing(monkeypatch):
    from parcover_env.viz import render

    def no_gui(*args):
        raise render.cv2.error("The function is not implemented")

    monkeypatch.setattr(render, "_has_display", lambda: True)
    monkeypatch.setattr(render, "_WARNED", set())
    monkeypatch.setattr(render.cv2, "imshow", no_gui)
    env = parcover_env.parallel_env("t_room", render_mode="human")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="no GUI support") as caught:
        assert env.render() is None and env.render() is None
    assert len(caught) == 1


def test_pettingzoo_render_test_passes_headless(monkeypatch):
    from parcover_env.viz import render

    monkeypatch.setattr(render, "_has_display", lambda: False)
    monkeypatch.setattr(render, "_WARNED", set())
    with pytest.warns(UserWarning, match="shows nothing"):
        render_test(lambda render_mode=None: parcover_env.env("office", render_mode=render_mode))


def test_np_random_is_the_episode_generator():
    env = parcover_env.parallel_env("t_room")
    env.reset(seed=5)
    assert env.np_random is env._rng
    a = env.np_random.random()
    env.reset(seed=5)
    assert env.np_random.random() == a


def test_max_cycles_argument_and_attribute():
    env = parcover_env.parallel_env("t_room", max_cycles=3)
    assert env.max_cycles == 3 == env.scenario.episode.max_steps
    env.reset(seed=0)
    for _ in range(3):
        _, _, term, trunc, _ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(trunc.values()) and env.agents == []
    env.max_cycles = 2
    env.reset(seed=0)
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    _, _, _, trunc, _ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(trunc.values())
    assert parcover_env.env("t_room", max_cycles=4).unwrapped.max_cycles == 4


def test_state_space_is_finite_and_contains_the_state():
    env = parcover_env.parallel_env("office")
    assert np.all(np.isfinite(env.state_space.low)) and np.all(np.isfinite(env.state_space.high))
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(30):
        assert env.state_space.contains(env.state())
        env.step({a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents})
    x0, y0, x1, y1 = env.map.bounds
    assert env.state_space.low[0] == np.float32(x0) and env.state_space.high[1] == np.float32(y1)
    assert env.state_space.low[2] == -1 and env.state_space.high[4] == 1 and env.state_space.high[-1] == 1


def test_infos_are_flat_with_the_same_keys_at_reset_and_every_step():
    env = parcover_env.parallel_env("office", max_cycles=4)
    _, infos = env.reset(seed=0)
    keys = {a: set(i) for a, i in infos.items()}
    shapes = {k: np.shape(v) for k, v in infos["robot_0"].items()}
    while env.agents:
        _, _, _, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
        for a, info in infos.items():
            assert set(info) == keys[a]
            for k, v in info.items():
                assert isinstance(v, (int, float, np.ndarray)) and np.shape(v) == shapes[k], k
    assert "episode" not in infos["robot_0"] and infos["robot_0"]["metrics/ended"] == 1.0


def test_gymnasium_record_episode_statistics_keeps_its_episode_key():
    import gymnasium as gym

    env = gym.wrappers.RecordEpisodeStatistics(
        gym.make("parcover_env/SingleRobotCoverage-v0", scenario="t_room", overrides={"episode": {"max_steps": 3}}))
    env.reset(seed=0)
    for _ in range(3):
        _, _, term, trunc, info = env.step(np.zeros(2, np.float32))
    assert trunc and info["episode"]["l"] == 3 and info["metrics"]["steps"] == 3


def test_sb3_subproc_vec_env_finds_the_id_without_a_module_prefix():
    pytest.importorskip("stable_baselines3")
    code = (
        "import parcover_env\n"
        "from stable_baselines3.common.env_util import make_vec_env\n"
        "from stable_baselines3.common.vec_env import SubprocVecEnv\n"
        "v = make_vec_env('parcover_env/SingleRobotCoverage-v0', n_envs=2, vec_env_cls=SubprocVecEnv,\n"
        "                 env_kwargs={'scenario': 't_room'})\n"
        "print(v.reset().shape); v.close()\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert p.returncode == 0, p.stderr[-2000:]
    size = parcover_env.parallel_env("t_room").layout.size
    assert p.stdout.strip().endswith(f"(2, {size})")


def test_room_modules_import_as_names_next_to_the_aec_factory():
    """``parcover_env.env`` is the AEC factory, so the env room must not share its name."""
    import importlib

    module = importlib.import_module("parcover_env.envs.vec_env")
    assert callable(parcover_env.env)
    assert module.__name__ == "parcover_env.envs.vec_env"
    exec("import parcover_env.mission.metrics as m\nassert m.episode_metrics", {})

"""The first hour of a new user: every bad input gets one clear line on stderr and exit status 2,
never a traceback (each case runs ``parcover`` as a subprocess, as a user would)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _parcover(*args: str, pre: str = "", cwd: Path | None = None) -> subprocess.CompletedProcess:
    code = f"{pre}\nimport sys\nfrom parcover_env.cli import main\nsys.exit(main(sys.argv[1:]))"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd or ROOT,
                          env=env, timeout=300)


def _assert_one_line(p: subprocess.CompletedProcess, *words: str) -> None:
    err = p.stderr.strip().splitlines()
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert len(err) == 1 and "Traceback" not in p.stderr, p.stderr
    assert "error" in err[0]
    for w in words:
        assert w in err[0], (w, err[0])


@pytest.fixture(scope="module")
def blocked(tmp_path_factory) -> Path:
    """A path whose parent is a regular file: nothing can be written there."""
    f = tmp_path_factory.mktemp("blocked") / "file"
    f.write_text("x")
    return f


def test_negative_seed():
    _assert_one_line(_parcover("run", "office", "--seed", "-1", "--quiet"), "--seed", "must be >= 0")


def test_zero_robots():
    _assert_one_line(_parcover("plan", "office", "--n-robots", "0"), "--n-robots", "must be >= 1")


def test_not_an_integer():
    _assert_one_line(_parcover("bench", "--seeds", "three"), "--seeds", "expected an integer")


def test_unknown_scenario():
    _assert_one_line(_parcover("run", "offce", "--quiet"), "did you mean 'office'")


def test_unwritable_gif(blocked):
    p = _parcover("run", "office", "--quiet", "--gif", str(blocked / "x.gif"))
    _assert_one_line(p, "--gif", "does not exist")
    assert "scenario" not in p.stdout  # checked before the episode runs


@pytest.mark.parametrize("cmd", [["render", "office"], ["plan", "office"], ["sectors", "t_room"]])
def test_unwritable_png(blocked, cmd):
    p = _parcover(*cmd, "--png", str(blocked / "x.png"))
    _assert_one_line(p, "--png")
    assert "wrote" not in p.stdout


def test_png_with_unknown_extension_does_not_say_wrote(tmp_path):
    p = _parcover("render", "office", "--png", str(tmp_path / "frame.notanimage"))
    _assert_one_line(p, "--png")
    assert "wrote" not in p.stdout and not (tmp_path / "frame.notanimage").exists()


@pytest.mark.parametrize("cmd", [["bench", "office", "--seeds", "1"], ["kinect", "office"],
                                 ["collect", "office", "--episodes", "1"]])
def test_unwritable_out_dir(blocked, cmd):
    _assert_one_line(_parcover(*cmd, "--out", str(blocked / "sub")), "--out")


def test_collect_to_an_existing_dataset(tmp_path):
    (tmp_path / "parcover" / "office-expert-v0").mkdir(parents=True)
    _assert_one_line(_parcover("collect", "office", "--episodes", "1", "--out", str(tmp_path)), "already exists")


def test_missing_minari_for_collect(tmp_path):
    p = _parcover("collect", "office", "--episodes", "1", "--out", str(tmp_path),
                  pre="import sys; sys.modules['minari'] = None")
    _assert_one_line(p, "minari", "parcover_env[data]")


def test_missing_matplotlib_for_bench_plots(tmp_path):
    p = _parcover("bench", "office", "--seeds", "1", "--out", str(tmp_path),
                  pre="import sys; sys.modules['matplotlib'] = None")
    _assert_one_line(p, "matplotlib", "--no-plots")


def test_missing_torch_for_a_learned_policy(tmp_path):
    (tmp_path / "bc.pt").write_bytes(b"")
    p = _parcover("run", "office", "--quiet", "--policy", f"bc:{tmp_path / 'bc.pt'}",
                  pre="import sys; sys.modules['torch'] = None")
    _assert_one_line(p, "torch", "parcover_env[train]")


def test_ppo_checkpoint_missing(tmp_path):
    _assert_one_line(_parcover("run", "office", "--quiet", "--policy", f"ppo:{tmp_path / 'nope.zip'}"),
                     "does not exist")


def test_ppo_checkpoint_not_a_model(tmp_path):
    (tmp_path / "model.zip").write_bytes(b"not a zip")
    _assert_one_line(_parcover("run", "office", "--quiet", "--policy", f"ppo:{tmp_path / 'model.zip'}"),
                     "cannot load PPO checkpoint")


def test_ppo_observation_shape_mismatch(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    import numpy as np
    from stable_baselines3 import PPO

    class Tiny(gym.Env):
        observation_space = gym.spaces.Box(-1, 1, (5,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

    PPO("MlpPolicy", Tiny(), n_steps=8, batch_size=8, device="cpu").save(tmp_path / "model.zip")
    p = _parcover("run", "office", "--quiet", "--policy", f"ppo:{tmp_path / 'model.zip'}")
    _assert_one_line(p, "shape (5,)")


def test_bad_yaml_duplicate_key(tmp_path):
    y = tmp_path / "dup.yaml"
    y.write_text((ROOT / "configs" / "t_room.yaml").read_text() + "\nn_robots: 1\nn_robots: 2\n")
    _assert_one_line(_parcover("run", str(y), "--quiet"), "duplicate key")


def test_bad_expert_section_is_one_line_naming_file_and_key(tmp_path):
    """The expert owns its YAML section; a bad value there stops ``parcover run`` when the expert is built."""
    y = tmp_path / "bad_expert.yaml"
    y.write_text((ROOT / "configs" / "t_room.yaml").read_text() + "\nexpert:\n  leader_speed: 1.5\n")
    _assert_one_line(_parcover("run", str(y), "--quiet"), "bad_expert.yaml", "expert.leader_speed")


def test_unknown_policy():
    _assert_one_line(_parcover("run", "office", "--quiet", "--policy", "expret"), "unknown policy")


def test_version_and_plain_help():
    p = _parcover("--version")
    assert p.returncode == 0 and p.stdout.startswith("parcover ")
    h = _parcover("--help")
    assert h.returncode == 0 and "``" not in h.stdout and ":func:" not in h.stdout and "usage: parcover" in h.stdout

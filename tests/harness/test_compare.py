"""``parcover_env.compare``: a policy of your own beside the expert, from Python and from the CLI,
in this process and in worker processes (issue 42: "a policy defined outside the package is benched
beside the expert from Python and from the CLI with ``--workers 2``")."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import parcover_env
from parcover_env.errors import ParcoverError
from parcover_env.expert import expert_for
from parcover_env.harness.bench import EPISODE_FIELDS
from parcover_env.policies import Policy
from parcover_env.policies.registry import policy_overrides

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"
SAME = [f for f in EPISODE_FIELDS if f not in ("policy", "wall_time")]
"""What two policies that drive alike must agree on, episode by episode (not the label or the clock)."""


class Still(Policy):
    def act(self, observations):
        return {a: np.zeros(2, dtype=np.float32) for a in observations}


def _by_policy(result) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    for r in result.episodes:
        out.setdefault(r["policy"], []).append(r)
    return out


def _same(a: list[dict], b: list[dict]) -> None:
    """Equal, field for field (NaN equal to NaN: an episode without makespan)."""
    def key(r):
        return {k: "nan" if isinstance(r[k], float) and math.isnan(r[k]) else r[k] for k in SAME}

    assert [key(r) for r in a] == [key(r) for r in b]


def test_the_expert_as_your_own_policy_is_the_expert_row():
    """Same seeds, same env, same driver: every episode's metrics are the expert row's, bit for bit,
    and so is every summary value but the wall time."""
    result = parcover_env.compare(lambda env: expert_for(env), "office", [0, 1], name="mine",
                                  env_overrides=policy_overrides("expert", "office"))
    rows = _by_policy(result)
    assert list(rows) == ["expert", "mine"] and [r["seed"] for r in rows["mine"]] == [0, 1]
    _same(rows["mine"], rows["expert"])
    assert [r["success"] for r in rows["mine"]] == [1.0, 1.0]  # the expert finishes office on both seeds
    expert, mine = result.row("expert"), result.row("mine")
    assert {k: v for k, v in mine.items() if not k.startswith(("policy", "wall_time"))} == {
        k: v for k, v in expert.items() if not k.startswith(("policy", "wall_time"))}
    assert mine["success"] == 1.0 and mine["kpoi_fraction"] == 1.0
    assert mine["makespan_ratio"] == pytest.approx(np.mean([r["makespan_ratio"] for r in rows["expert"]]))
    lines = str(result).splitlines()
    assert len(lines) == 4 and lines[2].startswith("| office | expert | 2 |")
    assert lines[3].startswith("| office | mine | 2 |")


@pytest.fixture
def start_kpoi_scenario(tmp_path) -> Path:
    """office with a third KPOI 5 cm from robot_0's start place (2.6, 3.95)."""
    data = yaml.safe_load((ROOT / "configs" / "office.yaml").read_text())
    data["name"] = "office_start_kpoi"
    data["kpois"] = [*data["kpois"], [2.55, 3.95]]
    path = tmp_path / "office_start_kpoi.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_standing_still_visits_what_the_start_visits(start_kpoi_scenario):
    scenario = str(start_kpoi_scenario)
    seeds = [0, 1]
    env = parcover_env.parallel_env(scenario)
    kpois, radius = np.array(env.scenario.kpois), env.scenario.kpoi_radius
    expected = []
    for seed in seeds:  # the KPOIs within kpoi_radius of a robot's true start place
        env.reset(seed=seed)
        d = np.linalg.norm(env.true_poses()[:, None, :2] - kpois[None], axis=-1)
        expected.append(float(np.mean((d <= radius).any(axis=0))))
    assert expected == [1 / 3, 1 / 3]  # the hand-placed KPOI, and only it
    result = parcover_env.compare(Still(), scenario, seeds, max_steps=30, name="still")
    rows = _by_policy(result)["still"]
    assert [r["kpoi_fraction"] for r in rows] == expected
    assert [r["success"] for r in rows] == [0.0, 0.0] and [r["steps"] for r in rows] == [30, 30]
    assert all(math.isnan(r["makespan"]) for r in rows)
    assert result.row("still")["success"] == 0.0 and result.row("still")["kpoi_fraction"] == pytest.approx(1 / 3)


def test_workers_need_a_policy_that_pickles():
    def local_factory(env, seed):
        return Still()

    with pytest.raises(ParcoverError) as info:
        parcover_env.compare(local_factory, "office", [0], workers=2, max_steps=5)
    assert str(info.value).startswith(
        "policy 'local_factory' does not pickle (AttributeError: Can't pickle local object "
        "'test_workers_need_a_policy_that_pickles.<locals>.local_factory'), so it cannot run with workers > 1: "
        "define a factory (env, seed) -> Policy at module level in an importable module and pass it, "
        "or name it by the spec 'py:MODULE:ATTR', or run with workers=1")


def test_a_policy_that_pickles_here_but_not_in_a_worker(monkeypatch):
    """A function of a module that exists only in this process (a notebook's ``__main__``, say)
    pickles here by reference; the worker cannot import it: one error naming the policy."""
    import types

    ghost = types.ModuleType("ghost_agents")

    def make(env, seed):
        return Still()

    make.__module__, make.__qualname__ = "ghost_agents", "make"
    ghost.make = make
    monkeypatch.setitem(sys.modules, "ghost_agents", ghost)
    with pytest.raises(ParcoverError) as info:
        parcover_env.compare(make, "office", [0], workers=2, max_steps=5, against=("random",))
    assert str(info.value) == (
        "policy 'make' cannot be unpickled in a worker process (ModuleNotFoundError: No module named "
        "'ghost_agents'), so it cannot run with workers > 1: define a factory (env, seed) -> Policy at module "
        "level in an importable module and pass it, or name it by the spec 'py:MODULE:ATTR', or run with workers=1")


def test_a_module_level_factory_reaches_two_workers(monkeypatch):
    """Pickled by reference, the factory is imported in each spawned worker; the episodes are those
    of one process."""
    monkeypatch.syspath_prepend(str(FIXTURES))
    import user_policies

    two = parcover_env.compare(user_policies.SeededRandom, "office", [3, 4], workers=2, max_steps=40,
                               against=("random",))
    one = parcover_env.compare(user_policies.SeededRandom, "office", [3, 4], workers=1, max_steps=40,
                               against=("random",))
    assert [r["policy"] for r in two.episodes] == ["random", "random", "SeededRandom", "SeededRandom"]
    for a, b in zip(_by_policy(two).values(), _by_policy(one).values(), strict=True):
        _same(a, b)
    ours = _by_policy(two)["SeededRandom"]
    assert len({(r["collisions"], r["localization_error"]) for r in ours}) == 2  # the seed reached the class


def test_a_spec_string_and_bad_arguments():
    result = parcover_env.compare("random", "office", [2], max_steps=10, name="rnd", against=("waypoint",))
    assert [r["policy"] for r in result.episodes] == ["waypoint", "rnd"]
    bad = [
        (dict(seeds=3), "seeds must be a sequence of episode seeds, e.g. range(1000, 1010), got 3"),
        (dict(seeds=[0, -1]), "seeds must be one or more integers >= 0, got [0, -1]"),
        (dict(seeds=[]), "seeds must be one or more integers >= 0, got []"),
        (dict(scenarios=[]), "scenarios must be one or more scenario names or paths, got []"),
        (dict(workers=0), "workers must be an integer >= 1, got 0"),
        (dict(backend="slurm"), "backend must be 'local' or 'ray', got 'slurm'"),
        (dict(max_steps=0), "max_steps must be an integer >= 1 or None, got 0"),
        (dict(name="expert"), "policy name 'expert' is also a baseline in against=['expert']: give another name"),
        (dict(env_overrides=[1]), "env_overrides must be a mapping, got list"),
        (dict(against=("greedy",)), "unknown policy 'greedy'"),
    ]
    bad += [
        (dict(policy={"a": Still()}, name="b"),
         "name= labels a single policy; the keys of a mapping of policies are their names"),
        (dict(policy={}), "a mapping of policies needs one or more names (str) as keys, got []"),
        (dict(policy={"expert": Still()}),
         "policy name 'expert' is also a baseline in against=['expert']: give another name"),
        (dict(policy="greedy"), "unknown policy 'greedy'"),
    ]
    for kwargs, message in bad:
        args = {"policy": Still(), "scenarios": "office", "seeds": [0], **kwargs}
        with pytest.raises(ParcoverError) as info:
            parcover_env.compare(args.pop("policy"), args.pop("scenarios"), args.pop("seeds"), **args)
        assert str(info.value).startswith(message), (kwargs, str(info.value))
    with pytest.raises(KeyError, match="no single summary row for policy 'nobody'"):
        result.row("nobody")


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(FIXTURES)]))
    return subprocess.run([sys.executable, "-m", "parcover_env.cli", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=600)


def test_cli_bench_py_spec_with_two_workers(tmp_path):
    """``parcover bench --workers 2``: the spawned workers import the user's module from PYTHONPATH;
    the expert as a ``py:`` policy is the expert row, episode by episode."""
    p = _cli("bench", "office", "--policies", "expert,py:user_policies:make_expert,py:user_policies:make_still",
             "--seeds", "2", "--workers", "2", "--out", str(tmp_path / "out"), "--no-plots", "--quiet",
             "--json", str(tmp_path / "eps.json"), cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    rows: dict[str, list[dict]] = {}
    for r in json.loads((tmp_path / "eps.json").read_text()):
        rows.setdefault(r["policy"], []).append(r)
    assert list(rows) == ["expert", "py:user_policies:make_expert", "py:user_policies:make_still"]
    _same(rows["py:user_policies:make_expert"], rows["expert"])
    assert [r["seed"] for r in rows["expert"]] == [1000, 1001] and [r["success"] for r in rows["expert"]] == [1, 1]
    still = rows["py:user_policies:make_still"]
    # office has no KPOI at the start: standing still visits none, until the step limit
    assert [(r["kpoi_fraction"], r["success"], r["steps"]) for r in still] == [(0.0, 0.0, 900)] * 2
    assert "| office | py:user_policies:make_still | 2 |" in p.stdout


@pytest.mark.parametrize(("args", "message"), [
    (("bench", "office", "--policies", "expert,py:no_such_module:make", "--workers", "2"),
     "parcover: error: policy 'py:no_such_module:make': cannot import module 'no_such_module' "
     "(ModuleNotFoundError: No module named 'no_such_module'); is the folder that holds it on PYTHONPATH?"),
    (("bench", "office", "--policies", "py:user_policies:returns_number", "--workers", "2", "--seeds", "1",
      "--no-plots", "--quiet"),
     "parcover: error: policy 'py:user_policies:returns_number': returns_number(env, seed) returned int, "
     "not a Policy (it has no act, reset, stats, belief; subclass parcover_env.policies.Policy)"),
    (("run", "office", "--policy", "py:user_policies:WrongShape", "--quiet"),
     "parcover: error: policy 'py:user_policies:WrongShape' was trained on observations of shape (3,); "
     "scenario 'office' gives"),
])
def test_cli_py_spec_errors_are_one_line(tmp_path, args, message):
    p = _cli(*args, "--out", str(tmp_path / "out"), cwd=tmp_path) if args[0] == "bench" else _cli(*args, cwd=tmp_path)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and p.stderr.startswith(message), p.stderr

"""Fuzzing every ``parcover`` subcommand: argument lists drawn from valid and invalid values of each
option (scenarios, policy specs with broken checkpoints, numbers, paths that cannot be written)
and stray tokens. Each must end with status 0, 1 or 2 and, on bad input, one error line; never a
traceback. Episodes are kept short (``--steps`` / ``--max-steps`` of at most 3); ``parcover train``
runs its checks for real and stops before training (``harness.marl.train`` is replaced)."""

from __future__ import annotations

import tempfile
from pathlib import Path
from unittest import mock

from cli_outcome import check_outcome, run_cli
from fuzz_files import files, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

FUZZ = fuzz_settings(12)

_OUT = Path(tempfile.mkdtemp(prefix="parcover_cli_fuzz_"))
_NOT_A_DIR = _OUT / "a_file"
_NOT_A_DIR.write_text("x")


def mostly(good, bad):
    """A value from ``good`` three times in four, else from ``bad``: whole valid command lines are
    common enough that the commands run, not only their argument checks."""
    return st.sampled_from([True, True, True, False]).flatmap(lambda ok: good if ok else bad)


def _pick(values) -> st.SearchStrategy:
    return st.sampled_from(values)


SCENARIOS = mostly(_pick(["office", "hallway", "t_room", "tree", "triangle_room", "generated:3", "generated:17"]),
                   _pick(["generated:abc", "generated:", "generated:-1", "nosuch", "", "offce"])
                   | st.builds(lambda k: str(files()[k]), _pick(["yaml_bad", "yaml_list", "bc", "missing", "dir",
                                                                 "empty"])))
CHECKPOINTS = ("bc", "torchrl", "ppo", "empty", "junk", "text", "pickle", "list", "nokeys", "bc_trunc", "bc_tail",
               "bc_shape", "bc_hidden", "dir", "missing")
POLICIES = mostly(_pick(["expert", "waypoint", "random"]) | st.builds(
    lambda kind: f"{kind}:{files()[kind.split('_')[0]]}", _pick(["bc", "torchrl", "torchrl_sampled", "ppo"])),
    _pick(["nosuch", "", ":", "expert:x", "bc:", "random:1"]) | st.builds(
        lambda kind, name: f"{kind}:{files()[name]}", _pick(["bc", "mappo", "torchrl", "torchrl_sampled", "ppo"]),
        _pick(CHECKPOINTS)))
INTS = mostly(_pick(["0", "1", "2", "7", "99999999999999999999"]), _pick(["-1", "x", "", "1.5", " 3", "1e3"]))
SMALL_STEPS = mostly(_pick(["1", "2", "3"]), _pick(["0", "-2", "x"]))
WRITABLE = mostly(st.just("ok"), _pick(["not_a_dir", "missing_parent", "is_dir", "bad_suffix"]))
TOKENS = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=6)


def _file(kind: str, suffix: str) -> str:
    return {"ok": str(_OUT / f"out{suffix}"), "not_a_dir": str(_NOT_A_DIR / f"x{suffix}"),
            "missing_parent": str(_OUT / "no" / "such" / f"x{suffix}"), "is_dir": str(_OUT),
            "bad_suffix": str(_OUT / "out.txt")}[kind]


def _dir(kind: str) -> str:
    return {"ok": str(_OUT / "dir"), "not_a_dir": str(_NOT_A_DIR), "missing_parent": str(_OUT / "new" / "sub"),
            "is_dir": str(_OUT), "bad_suffix": str(_NOT_A_DIR / "sub")}[kind]


@st.composite
def _options(draw, pairs: dict) -> list[str]:
    """Some of ``pairs`` (``--option: strategy``, strategy None for a flag) in a drawn order, and
    now and then a stray token."""
    argv = []
    for opt, strategy in pairs.items():
        if draw(st.booleans()):
            argv += [opt] if strategy is None else [opt, draw(strategy)]
    if draw(st.integers(0, 9)) == 0:
        argv.insert(draw(st.integers(0, len(argv))), draw(TOKENS))
    return argv


@st.composite
def run_args(draw) -> list[str]:
    argv = ["run", draw(SCENARIOS), "--quiet", "--steps", draw(SMALL_STEPS)]
    return argv + draw(_options({"--seed": INTS, "--policy": POLICIES, "--preset": st.sampled_from(
        ["realistic", "ideal", "IDEAL", ""]), "--gif": st.builds(_file, WRITABLE, st.just(".gif")),
        "--gif-every": INTS, "--json": None, "--allow-failure": None}))


@st.composite
def bench_args(draw) -> list[str]:
    scenarios = ",".join(draw(st.lists(SCENARIOS, min_size=draw(mostly(st.just(1), st.just(0))), max_size=2)))
    policies = ",".join(draw(st.lists(POLICIES, min_size=draw(mostly(st.just(1), st.just(0))), max_size=2)))
    argv = ["bench", scenarios, "--policies", policies, "--quiet", "--no-plots", "--workers", "1",
            "--max-steps", draw(SMALL_STEPS), "--seeds", draw(st.sampled_from(["1", "2", "0", "x"])),
            "--out", draw(st.builds(_dir, WRITABLE))]
    return argv + draw(_options({"--seed-offset": INTS, "--preset": st.sampled_from(["realistic", "ideal", "x"]),
                                 "--json": st.builds(_file, WRITABLE, st.just(".json")),
                                 "--backend": st.sampled_from(["local", "x"]), "--ray-address": TOKENS}))


_TRAINED = {"init": None, "agent_steps": 0, "episodes": 0, "wall_time": 0.0, "policy": "torchrl:x"}


@st.composite
def train_args(draw) -> list[str]:
    argv = ["train", draw(st.sampled_from(["ippo", "mappo", "x"])), draw(SCENARIOS | st.sampled_from(
        ["generated:0-3", "generated:5-3", "generated:0-5000", "generated:a-b"]))]
    return argv + draw(_options({"--steps": INTS, "--out": st.builds(_dir, WRITABLE),
                                 "--backend": st.sampled_from(["local", "x"]), "--ray-address": TOKENS,
                                 "--seed": INTS, "--config": st.builds(lambda k: str(files()[k]), st.sampled_from(
                                     ["yaml_bad", "yaml_list", "bc", "missing", "empty"])),
                                 "--init": st.builds(lambda k: str(files()[k]), st.sampled_from(list(CHECKPOINTS)))}))


@st.composite
def other_args(draw) -> list[str]:
    command = draw(st.sampled_from(["render", "plan", "kinect", "sectors", "scenarios", "collect", "", "nosuch"]))
    argv = [command] if command else []
    if draw(st.booleans()):
        argv.append(draw(SCENARIOS))
    pairs = {
        "render": {"--png": st.builds(_file, WRITABLE, st.just(".png")), "--seed": INTS},
        "plan": {"--png": st.builds(_file, WRITABLE, st.just(".png")), "--n-robots": INTS, "--json": None},
        "kinect": {"--out": st.builds(_dir, WRITABLE), "--seed": INTS},
        "sectors": {"--rule": st.sampled_from(["0", "1", "2", "3", "x"]),
                    "--png": st.builds(_file, WRITABLE, st.just(".png")),
                    "--range": st.sampled_from(["inf", "0", "-1", "nan", "1e-300", "1e300", "x", "2.5"]),
                    "--json": None, "--rearrangement": st.builds(_file, WRITABLE, st.just(".png"))},
        "collect": {"--episodes": INTS, "--policy": POLICIES, "--driver": POLICIES,
                    "--driver-prob": st.sampled_from(["0.5", "nan", "2", "x", "-0"]), "--max-steps": SMALL_STEPS,
                    "--out": st.builds(_dir, WRITABLE)},
    }.get(command, {"--version": None, "--help": None})
    return argv + draw(_options(pairs))


def _check(argv: list[str]) -> None:
    status, _, err = run_cli(argv)
    check_outcome(argv, status, err)


@FUZZ
@given(run_args())
def test_fuzz_run(argv):
    _check(argv)


@FUZZ
@given(bench_args())
def test_fuzz_bench(argv):
    _check(argv)


@FUZZ
@given(train_args())
def test_fuzz_train(argv):
    with mock.patch("parcover_env.harness.marl.train", return_value=_TRAINED):
        _check(argv)


@fuzz_settings(20)
@given(other_args())
def test_fuzz_other_commands(argv):
    _check(argv)

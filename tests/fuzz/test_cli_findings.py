"""What the CLI fuzzing found, pinned: each input was a traceback, a late or unnamed error, or a
memory blow-up; each is now one line naming the option, exit status 2, before any work."""

from __future__ import annotations

import pytest
from cli_outcome import run_cli


def _one_line(argv: list[str]) -> str:
    status, _, err = run_cli(argv)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, (status, err)
    return lines[0]


def test_gif_must_be_a_gif(tmp_path):  # was RuntimeError: `GIF-PIL` can not handle the given uri
    path = tmp_path / "x.txt"
    line = _one_line(["run", "office", "--steps", "1", "--quiet", "--gif", str(path)])
    assert line == f"parcover: error: --gif: {path}: expected a file name ending in .gif"
    assert not path.exists()


def test_bench_json_that_is_a_directory_is_refused_before_the_sweep(tmp_path):  # was [Errno 21] after it
    line = _one_line(["bench", "office", "--policies", "random", "--seeds", "1", "--max-steps", "1", "--workers", "1",
                      "--no-plots", "--quiet", "--out", str(tmp_path / "out"), "--json", str(tmp_path)])
    assert line == f"parcover: error: --json: {tmp_path} is a directory, expected a file name"
    assert list((tmp_path / "out").iterdir()) == []  # no episode ran, nothing was written


@pytest.mark.parametrize(("argv", "message"), [
    (["plan", "office", "--n-robots", "99999999999999999999"],  # was MemoryError after minutes (GBs cached)
     "parcover plan: error: argument --n-robots: must be <= 256, got 99999999999999999999 (see parcover plan --help)"),
    (["bench", "office", "--seeds", "99999999999999999999"],  # was OverflowError
     "parcover bench: error: argument --seeds: must be <= 100000, got 99999999999999999999 "
     "(see parcover bench --help)"),
])
def test_counts_that_would_exhaust_memory_are_bounded(argv, message):
    assert _one_line(argv) == message


def test_plan_scenario_bounds_the_robots():
    from parcover_env.errors import ArgumentError
    from parcover_env.planning import plan_scenario
    from parcover_env.scenarios import load_scenario

    with pytest.raises(ArgumentError, match=r"^n_robots must be an integer in \[1, 256\] or None, got 257$"):
        plan_scenario(load_scenario("office"), 257)


def test_rearrangement_of_a_one_robot_scenario_is_refused_before_any_output(tmp_path):  # was ValueError traceback
    png = tmp_path / "s.png"
    line = _one_line(["sectors", "t_room", "--png", str(png), "--json", "--rearrangement", str(tmp_path / "r.png")])
    assert line == ("parcover: error: --rearrangement: scenario 't_room' plans 1 robot(s); Kim, Pearce & Amato Fig. 9 "
                    "needs two")
    assert not png.exists()


def test_waypoint_under_ideal_sends_the_scan_component(tmp_path):  # was ActionError: action must have shape (3,)
    status, out, _ = run_cli(["run", "t_room", "--preset", "ideal", "--policy", "waypoint", "--steps", "3", "--quiet",
                              "--allow-failure"])
    assert status == 0 and "steps" in out

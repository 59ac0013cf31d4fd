"""The parcover command line."""

from __future__ import annotations

from parcover_env.cli import main


def test_scenarios_lists_shipped(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    for name in ("office", "tree", "hallway", "t_room"):
        assert name in out


def test_run_prints_metrics_and_writes_gif(tmp_path, capsys):
    gif = tmp_path / "office.gif"
    assert main(["run", "office", "--seed", "0", "--quiet", "--gif", str(gif), "--gif-every", "20"]) == 0
    out = capsys.readouterr().out
    assert "kpois_visited        2" in out and "success              True" in out
    assert gif.stat().st_size > 1000


def test_plan_draws_and_prints(tmp_path, capsys):
    png = tmp_path / "plan.png"
    assert main(["plan", "tree", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "r = 15 robots" in out and "Kinect tree rooted at A" in out and png.stat().st_size > 1000


def test_sectors_and_kinect_views(tmp_path, capsys):
    assert main(["sectors", "t_room", "--rule", "1", "--png", str(tmp_path / "s.png")]) == 0
    assert "6 features" in capsys.readouterr().out
    assert main(["kinect", "office", "--out", str(tmp_path / "k")]) == 0
    assert len(list((tmp_path / "k").glob("*.png"))) == 5


def test_bad_input_is_one_line_and_exit_2(capsys):
    assert main(["run", "offce", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "did you mean 'office'" in err[0]

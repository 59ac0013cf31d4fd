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
    assert "r = 15 robots" in out and "4 turning positions" in out and "Kinect tree rooted at A" in out
    assert png.stat().st_size > 1000


def test_sectors_and_kinect_views(tmp_path, capsys):
    assert main(["sectors", "t_room", "--rule", "1", "--png", str(tmp_path / "s.png")]) == 0
    assert "6 features" in capsys.readouterr().out
    assert main(["kinect", "office", "--out", str(tmp_path / "k")]) == 0
    assert len(list((tmp_path / "k").glob("*.png"))) == 5


def test_bad_input_is_one_line_and_exit_2(capsys):
    assert main(["run", "offce", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "did you mean 'office'" in err[0]


def _json_out(capsys, argv) -> dict:
    import json

    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_plan_json_tree_is_fig6(capsys):
    d = _json_out(capsys, ["plan", "tree", "--json"])
    assert d["n_robots"] == 15 and len(d["turning_positions"]) == 4
    assert d["kinect_tree"] == [["A", "B"], ["A", "C"], ["A", "D"], ["B", "D"]]
    assert d["c_max"] > 0 and len(d["routes"]) == 15
    assert sorted(k for r in d["routes"] for k in r["kpois"]) == list(range(15))
    assert all(len(p) == 2 for p in d["turning_positions"])


def test_sectors_range_and_json(capsys):
    for rule, n in ((1, 6), (2, 2)):  # seed B Fig. 3 at unlimited range
        d = _json_out(capsys, ["sectors", "t_room", "--rule", str(rule), "--range", "inf", "--json"])
        assert d["n_sectors"] == n == len(d["sectors"]) and d["range_max"] is None
        assert len(d["features"]) == 6 and d["rule"] == rule
    d = _json_out(capsys, ["sectors", "t_room", "--rule", "2", "--range", "2.54", "--json"])
    assert d["range_max"] == 2.54 and d["n_sectors"] == 4
    assert main(["sectors", "t_room", "--range", "inf"]) == 0
    assert "unlimited range" in capsys.readouterr().out
    assert main(["sectors", "t_room", "--range", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--range" in err and len(err.strip().splitlines()) == 1


def test_sectors_rule0_json_triangle_room(capsys):
    """Fig. 4's rules through the CLI on our room (the paper gives no coordinates; its 65 / 7 / 3
    are not comparable): rule 0 / 1 / 2 at unlimited range, every key of the JSON."""
    counts = []
    for rule in (0, 1, 2):
        d = _json_out(capsys, ["sectors", "triangle_room", "--rule", str(rule), "--range", "inf", "--json"])
        assert set(d) >= {"scenario", "rule", "rule_name", "range_max", "n_features", "n_sectors", "features",
                          "sectors"}
        assert d["scenario"] == "triangle_room" and d["range_max"] is None and d["n_features"] == 4
        assert all(set(s) == {"features", "common", "area", "centroid"} for s in d["sectors"])
        assert all(0 <= k < 4 for s in d["sectors"] for k in s["features"])
        counts.append(d["n_sectors"])
    assert counts == [11, 4, 2]  # tests/localization/sonar/test_sonar_sectors.py derives them


def test_run_json_is_one_object_on_stdout(capsys):
    import json

    assert main(["run", "office", "--json", "--steps", "5", "--allow-failure", "--quiet"]) == 0
    captured = capsys.readouterr()
    m = json.loads(captured.out)
    assert m["steps"] == 5 and "kinect_splits" in m and "scenario office" in captured.err
    assert (m["scenario"], m["seed"], m["policy"], m["preset"]) == ("office", 0, "expert", "realistic")
    assert "preset realistic" in captured.err


def test_run_json_preset_ideal_matches_the_ideal_env(capsys):
    import json

    import parcover_env
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy

    assert main(["run", "office", "--json", "--steps", "40", "--seed", "2", "--preset", "ideal",
                 "--allow-failure", "--quiet"]) == 0
    m = json.loads(capsys.readouterr().out)
    env = parcover_env.parallel_env("office", preset="ideal")
    ref = run_episode(env, make_policy("expert", env, 2), 2, 40, None, progress=False)
    assert m["preset"] == "ideal" and m["localization_error"] == ref["localization_error"]
    env_r = parcover_env.parallel_env("office")
    real = run_episode(env_r, make_policy("expert", env_r, 2), 2, 40, None, progress=False)
    assert real["localization_error"] != ref["localization_error"]  # the flag changes the run


def test_sectors_draws_fig9_rearrangement(tmp_path, capsys):
    png = tmp_path / "fig9.png"
    assert main(["sectors", "hallway", "--rearrangement", str(png)]) == 0
    out = capsys.readouterr().out
    assert "Fig. 9 subgoals" in out and png.stat().st_size > 1000


def test_run_json_reports_the_sonar_navigators_figures(capsys):
    """``run hallway --json``: rearranged subgoal pairs, the scan-angle bias before/after eq. 1 and the
    robots' lateral offset while both drive (side by side on parallel paths, lanes 0.58 m apart)."""
    import json

    assert main(["run", "hallway", "--json", "--steps", "400", "--allow-failure", "--quiet"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert {"sonar_rearranged", "sonar_separate_sectors", "sonar_bias_before_deg", "sonar_bias_after_deg",
            "sonar_bias_subgoals", "sonar_lateral_offset"} <= set(m)
    assert m["sonar_lateral_offset"] >= 0.3 and m["sonar_rearranged"] >= 0
    assert m["sonar_bias_subgoals"] >= 1 and m["sonar_bias_after_deg"] <= m["sonar_bias_before_deg"]

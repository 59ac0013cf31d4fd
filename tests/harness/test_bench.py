"""Benchmark harness: statistics, report files, local and Ray backends, CLI wiring, collect."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from parcover_env.cli import bench as cli_bench
from parcover_env.errors import ParcoverError
from parcover_env.harness import bench
from parcover_env.policies import check_policy_spec


def test_wilson_interval():
    lo, hi = bench.wilson_ci(20, 20)
    assert hi == pytest.approx(1.0) and 0.8 < lo < 0.85
    lo, hi = bench.wilson_ci(0, 2)
    assert lo == pytest.approx(0.0) and 0.6 < hi < 0.7


def _row(policy, success, ratio, seed):
    return {
        "scenario": "s",
        "policy": policy,
        "seed": seed,
        "success": success,
        "makespan_ratio": ratio,
        "makespan": ratio,
        "kpois_visited": 2,
        "kpoi_fraction": 1.0 if success else 0.5,
        "collisions": seed,
        "messages": 10,
        "steps": 5,
        "localization_error": 0.0,
        "wall_time": 0.1,
    }


def test_summary_takes_makespan_over_successes_only(tmp_path):
    rows = [_row("a", 1.0, 1.2, 0), _row("a", 0.0, math.nan, 1), _row("b", 1.0, 2.0, 0)]
    s = {x["policy"]: x for x in bench.summarize(rows)}
    assert s["a"]["success"] == 0.5 and s["a"]["makespan_ratio"] == 1.2 and s["a"]["makespan_ratio_n"] == 1
    # two values: the 25 % trim cuts int(0.5) = 0 of them, so the IQM is their mean
    assert s["a"]["collisions"] == 0.5 and s["a"]["kpoi_fraction"] == 0.75
    paths = bench.write_report(rows, tmp_path)
    table = paths["table"].read_text().splitlines()
    assert len(table) == 4 and table[2].startswith("| s | a | 2 | 0.50 [0.00, 1.00] (Wilson 0.09-0.91) |")
    assert paths["plot"].stat().st_size > 1000


def test_unknown_policy_and_bad_arguments():
    with pytest.raises(ParcoverError, match="unknown policy"):
        check_policy_spec("greedy")
    with pytest.raises(ParcoverError, match="does not exist"):
        check_policy_spec("ppo:/nonexistent/model")
    with pytest.raises(ValueError, match="backend"):
        bench.run_sweep(["office"], ["random"], [0], backend="slurm")


def _parser():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers()
    cli_bench.add_bench_parser(sub)
    cli_bench.add_collect_parser(sub)
    return p


def test_cli_bench_local_two_seeds(tmp_path, capsys):
    args = _parser().parse_args(
        [
            "bench",
            "office",
            "--policies",
            "waypoint,random",
            "--seeds",
            "2",
            "--workers",
            "1",
            "--max-steps",
            "40",
            "--out",
            str(tmp_path),
            "--quiet",
            "--no-plots",
            "--json",
            str(tmp_path / "eps.json"),
        ]
    )
    assert args.seed_offset == 1000  # evaluation seeds are disjoint from the trainers' (< 1000)
    assert args.func(args) == 0
    rows = list((tmp_path / "episodes.csv").read_text().splitlines())
    assert len(rows) == 1 + 4
    assert "| office | waypoint | 2 |" in capsys.readouterr().out
    recs = bench.read_episodes(tmp_path / "eps.json")
    assert [r["seed"] for r in recs] == [1000, 1001, 1000, 1001]
    assert set(bench.EPISODE_FIELDS) == set(recs[0])
    for r in recs:  # 40 steps: nobody finishes, so makespan is null in the JSON and NaN when read back
        assert r["preset"] == "realistic" and r["success"] == 0.0 and math.isnan(r["makespan"])
        assert r["kpoi_fraction"] == pytest.approx(r["kpois_visited"] / r["n_kpois"])
    assert bench.summarize(recs)[0]["episodes"] == 2
    # seeded: a second run gives the same episodes (wall time aside)
    again = bench.run_sweep(["office"], ["random"], [0, 1], max_steps=40, progress=False)
    first = [r for r in bench.run_sweep(["office"], ["random"], [0, 1], max_steps=40, progress=False)]
    for a, b in zip(again, first, strict=False):
        assert {k: v for k, v in a.items() if k != "wall_time"} == {
            k: v for k, v in b.items() if k != "wall_time"
        }


def test_process_pool_matches_in_process():
    a = bench.run_sweep(["office"], ["random"], [3, 4], workers=2, max_steps=30, progress=False)
    b = bench.run_sweep(["office"], ["random"], [3, 4], workers=1, max_steps=30, progress=False)
    assert [r["collisions"] for r in a] == [r["collisions"] for r in b]
    assert [r["seed"] for r in a] == [3, 4]


@pytest.mark.slow
def test_ray_backend_two_seeds():
    pytest.importorskip("ray")
    rows = bench.run_sweep(
        ["office"], ["random"], [0, 1], workers=2, backend="ray", max_steps=30, progress=False
    )
    local = bench.run_sweep(["office"], ["random"], [0, 1], max_steps=30, progress=False)
    assert [r["steps"] for r in rows] == [r["steps"] for r in local] == [30, 30]
    assert np.allclose([r["kpoi_fraction"] for r in rows], [r["kpoi_fraction"] for r in local])


def test_collect_two_episodes_as_minari(tmp_path):
    minari = pytest.importorskip("minari")
    pytest.importorskip("h5py")
    args = _parser().parse_args(["collect", "office", "--episodes", "2", "--out", str(tmp_path)])
    assert args.func(args) == 0
    import os

    os.environ["MINARI_DATASETS_PATH"] = str(tmp_path)
    ds = minari.load_dataset("parcover/office-expert-v0")
    assert ds.total_episodes == 4  # 2 missions x 2 robots
    ep = next(ds.iterate_episodes())
    assert ep.observations.shape[0] == ep.actions.shape[0] + 1
    assert np.all(np.abs(ep.actions) <= 1.0)

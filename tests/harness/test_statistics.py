"""Bench statistics: IQM and stratified percentile-bootstrap CIs (rliable conventions) checked by hand,
scipy Wilson intervals that always contain the estimate (no negative error bars)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from parcover_env.harness import bench


@pytest.mark.parametrize("n", range(1, 21))
def test_wilson_contains_the_estimate_for_every_count(n):
    for k in range(n + 1):
        lo, hi = bench.wilson_ci(k, n)
        assert 0.0 <= lo <= k / n <= hi <= 1.0, (k, n, lo, hi)


def test_wilson_matches_scipy_and_the_formula():
    lo, hi = bench.wilson_ci(3, 10)
    z = stats.norm.ppf(0.975)
    p, n = 0.3, 10
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert lo == pytest.approx(centre - half) and hi == pytest.approx(centre + half)
    assert all(math.isnan(v) for v in bench.wilson_ci(0, 0))


def test_iqm_is_the_25_percent_trimmed_mean_with_a_bootstrap_ci():
    x = [1.0, 2.0, 3.0, 4.0, 100.0, 5.0, 6.0, 7.0]
    iqm, lo, hi = bench.iqm_ci(x)
    assert iqm == pytest.approx(np.mean([3.0, 4.0, 5.0, 6.0]))  # outlier 100 and the low tail trimmed
    assert lo <= iqm <= hi and hi < 50
    assert bench.iqm_ci(x) == (iqm, lo, hi)  # seeded: reproducible
    assert bench.iqm_ci([2.0, 2.0, 2.0]) == (2.0, 2.0, 2.0)
    one = bench.iqm_ci([4.0, math.nan, None])
    assert one[0] == 4.0 and math.isnan(one[1]) and math.isnan(one[2])
    assert all(math.isnan(v) for v in bench.iqm_ci([]))


def test_stratified_bootstrap_resamples_within_each_task():
    a, b = [1.0, 1.1, 0.9, 1.0], [5.0, 5.2, 4.8, 5.0]
    iqm, lo, hi = bench.stratified_iqm_ci([a, b], n_resamples=500)
    assert iqm == pytest.approx(stats.trim_mean(a + b, 0.25))
    assert lo <= iqm <= hi
    # every resample keeps 4 runs of each task, so the IQM can never collapse onto one task's values
    assert lo > 1.1 and hi < 4.8


def test_summary_has_iqm_columns_and_table_shows_them(tmp_path):
    rows = [{"scenario": "s", "policy": "p", "seed": i, "success": 1.0, "makespan_ratio": r, "makespan": r,
             "kpois_visited": 1, "kpoi_fraction": 1.0, "collisions": 0, "messages": 0, "steps": 1,
             "localization_error": 0.0, "wall_time": 0.1} for i, r in enumerate([1.0, 1.2, 1.4, 9.0])]
    (s,) = bench.summarize(rows)
    assert s["makespan_ratio"] == pytest.approx(1.3)  # IQM of 1.0, 1.2, 1.4, 9.0: mean of 1.2, 1.4
    assert "makespan ratio IQM [95% CI]" in bench.markdown_table([s])
    # all successes: the success error bar is never negative (the default `parcover bench` crash)
    assert s["success_lo"] <= s["success"] == 1.0 <= s["success_hi"]
    bench.plot_summary([s], tmp_path / "p.png")


def test_iqm_of_eight_values_by_hand():
    # sorted 1, 2, 3, 4, 5, 6, 7, 100: a quarter (2 values) cut from each end -> mean of 3, 4, 5, 6
    assert bench.iqm([7.0, 1.0, 100.0, 2.0, 6.0, 3.0, 5.0, 4.0]) == 4.5
    assert math.isnan(bench.iqm([None, math.nan]))


def test_bootstrap_ci_matches_the_exact_resampling_distribution():
    # one group [0, 1]: a resample is (0,0), (0,1), (1,0) or (1,1) with probability 1/4 each, so its
    # mean is 0 (p 1/4), 0.5 (p 1/2) or 1 (p 1/4): the 2.5 % and 97.5 % quantiles are 0 and 1, and
    # the share of resample means equal to 0.5 is about 1/2
    est, lo, hi = bench.stratified_bootstrap_ci([[0.0, 1.0]], "mean", n_resamples=4000)
    assert (est, lo, hi) == (0.5, 0.0, 1.0)
    # two strata [0, 1] and [10, 10]: the second never varies, so every resample mean is
    # (m1 * 2 + 20) / 4 with m1 in {0, 0.5, 1}: 5, 5.25, 5.5
    est, lo, hi = bench.stratified_bootstrap_ci([[0.0, 1.0], [10.0, 10.0]], "mean", n_resamples=4000)
    assert est == 5.25 and lo == 5.0 and hi == 5.5
    # pooled (unstratified) resampling could draw four 10s (mean 10) or four 0/1s: stratified cannot
    rng = np.random.default_rng(0)
    x = np.array([0.0, 1.0, 10.0, 10.0])
    pooled = x[rng.integers(0, 4, (4000, 4))].mean(axis=1)
    assert pooled.max() == 10.0 and hi < 6


def test_success_rate_bootstrap_and_wilson_in_the_summary():
    rows = [{"scenario": "s", "policy": "p", "seed": i, "success": float(i < 7), "makespan_ratio": 1.0,
             "kpoi_fraction": 1.0, "collisions": 0, "messages": 0, "wall_time": 0.1} for i in range(10)]
    (s,) = bench.summarize(rows)
    assert s["success"] == 0.7
    assert 0.35 <= s["success_lo"] < 0.7 < s["success_hi"] <= 1.0
    lo, hi = bench.wilson_ci(7, 10)
    assert (s["success_wilson_lo"], s["success_wilson_hi"]) == (lo, hi)


def test_generated_maps_get_a_stratified_aggregate_row():
    def row(sc, k, frac):
        return {"scenario": sc, "policy": "p", "seed": k, "success": 0.0, "makespan_ratio": math.nan,
                "kpoi_fraction": frac, "collisions": 0, "messages": 0, "wall_time": 0.1}

    rows = [row("generated:1", k, 0.2) for k in range(4)] + [row("generated:2", k, 0.8) for k in range(4)]
    by = {s["scenario"]: s for s in bench.summarize(rows)}
    assert set(by) == {"generated:1", "generated:2", "generated:*"}
    agg = by["generated:*"]
    assert agg["episodes"] == 8 and agg["maps"] == 2
    # every resample keeps 4 episodes per map: the IQM is always 0.5, never 0.2 or 0.8
    assert agg["kpoi_fraction"] == agg["kpoi_fraction_lo"] == agg["kpoi_fraction_hi"] == pytest.approx(0.5)
    assert "| generated:* | p | 8 (2 maps) |" in bench.markdown_table(list(by.values()))


def test_rliable_agrees_when_installed():
    rly = pytest.importorskip("rliable.metrics")
    x = np.array([[0.1, 0.9], [0.3, 0.7], [0.2, 0.5], [0.4, 1.0], [0.9, 0.0]])  # runs x tasks
    assert bench.iqm(x.ravel()) == pytest.approx(rly.aggregate_iqm(x))


def test_one_episode_per_map_resamples_the_maps():
    rows = [{"scenario": f"generated:{m}", "policy": "p", "seed": 1000, "success": float(m % 2),
             "makespan_ratio": math.nan, "kpoi_fraction": m / 10, "collisions": 0, "messages": 0,
             "wall_time": 0.1} for m in range(10)]
    agg = next(s for s in bench.summarize(rows) if s["scenario"] == "generated:*")
    assert agg["maps"] == 10 and agg["episodes"] == 10
    # resampling within a one-episode map could never move the estimate; over maps it does
    assert agg["success"] == 0.5 and agg["success_lo"] < 0.5 < agg["success_hi"]
    assert agg["kpoi_fraction"] == pytest.approx(np.mean([0.2, 0.3, 0.4, 0.5, 0.6, 0.7]))  # IQM: 2 cut each side
    assert agg["kpoi_fraction_lo"] < agg["kpoi_fraction"] < agg["kpoi_fraction_hi"]


def test_generated_maps_aggregate_per_preset_label():
    from parcover_env.harness.bench import family, summarize

    assert family("generated:17") == "generated:*" and family("generated:17 (ideal)") == "generated:* (ideal)"
    assert family("tree (ideal)") == "tree" + " (ideal)" and family("office") == "office"
    rows = [{"scenario": sc, "policy": "p", "seed": 0, "success": s, "kpoi_fraction": s, "makespan_ratio": 1.0,
             "collisions": 0.0, "messages": 1.0, "wall_time": 1.0}
            for sc, s in (("generated:1", 1.0), ("generated:2", 1.0), ("generated:1 (ideal)", 0.0),
                          ("generated:2 (ideal)", 0.0))]
    agg = {s["scenario"]: s["success"] for s in summarize(rows) if s["scenario"].startswith("generated:*")}
    assert agg == {"generated:*": 1.0, "generated:* (ideal)": 0.0}  # the presets are not pooled

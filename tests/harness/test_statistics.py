"""Bench statistics: scipy Wilson intervals that always contain the estimate (no negative error bars),
IQM with bootstrap CIs, stratified bootstrap across scenarios."""

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
    assert s["makespan_ratio_iqm"] == pytest.approx(1.3)
    assert "makespan ratio IQM [95% CI]" in bench.markdown_table([s])
    # all successes: the success error bar is never negative (the default `parcover bench` crash)
    assert s["success_lo"] <= s["success"] == 1.0 <= s["success_hi"]
    bench.plot_summary([s], tmp_path / "p.png")

"""Benchmark harness: ``parcover bench`` runs (scenario x policy x seed) episodes in parallel and
writes a Markdown table, CSVs and plots with 95 % confidence intervals; ``parcover collect``
records expert demonstrations as a Minari dataset.

Policies by spec: ``expert``, ``waypoint``, ``random``, ``ppo:PATH`` (``train_ppo.py`` output dir
or ``model.zip``), ``bc:PATH`` (``train_bc.py`` output dir or ``bc.pt``). Backends: ``local``
(a process pool, or in-process with ``--workers 1``) and ``ray`` (local Ray by default, or
``--ray-address``; optional extra).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from parcover_env.errors import ParcoverError
from parcover_env.policies.registry import check_policy_spec

__all__ = [
    "run_job",
    "run_sweep",
    "summarize",
    "write_report",
    "METRICS",
]

METRICS = {  # column -> (label, lower is better)
    "success": ("success rate", False),
    "makespan_ratio": ("makespan / (c_max/v_max)", True),
    "kpoi_fraction": ("KPOIs visited (fraction)", False),
    "collisions": ("collisions", True),
    "messages": ("messages", True),
    "wall_time": ("wall time (s)", True),
}


_ENV_CACHE: dict[tuple[str, int | None], Any] = {}


def run_job(scenario: str, policy: str, seed: int, max_steps: int | None = None) -> dict:
    """One episode; a flat row of metrics plus scenario, policy and seed. Envs are cached per process."""
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy

    key = (scenario, max_steps)
    if key not in _ENV_CACHE:
        _ENV_CACHE[key] = ParallelCoverageEnv(
            scenario, overrides={"episode": {"max_steps": max_steps}} if max_steps else None
        )
    env = _ENV_CACHE[key]
    m = run_episode(env, make_policy(policy, env, seed), seed)
    return {
        "scenario": scenario,
        "policy": policy,
        "seed": seed,
        "success": float(m["success"]),
        "makespan_ratio": m["makespan_ratio"] if m["makespan_ratio"] is not None else math.nan,
        "makespan": m["makespan"] if m["makespan"] is not None else math.nan,
        "kpois_visited": m["kpois_visited"],
        "kpoi_fraction": m["kpois_visited"] / m["n_kpois"],
        "collisions": m["collisions"],
        "messages": int(sum(m["messages"].values())),
        "steps": m["steps"],
        "localization_error": m["localization_error"],
        "wall_time": m["wall_time"],
    }


def run_sweep(
    scenarios: list[str],
    policies: list[str],
    seeds: list[int],
    workers: int = 1,
    backend: str = "local",
    max_steps: int | None = None,
    progress: bool = True,
    ray_address: str | None = None,
) -> list[dict]:
    """All (scenario, policy, seed) episodes; rows in job order."""
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {backend!r}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    for p in policies:
        check_policy_spec(p)
    jobs = [(s, p, seed) for s in scenarios for p in policies for seed in seeds]
    if not jobs:
        raise ValueError("nothing to run: no scenarios, policies or seeds")
    from tqdm import tqdm

    with tqdm(total=len(jobs), unit="episode", desc="bench", disable=not progress, dynamic_ncols=True) as bar:
        report = bar.update
        if backend == "ray":
            return _run_ray(jobs, workers, max_steps, report, ray_address)
        if workers == 1:
            rows = []
            for s, p, seed in jobs:
                rows.append(run_job(s, p, seed, max_steps))
                report(1)
            return rows
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        rows: list[dict | None] = [None] * len(jobs)
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(run_job, s, p, seed, max_steps): i for i, (s, p, seed) in enumerate(jobs)}
            for fut in as_completed(futures):
                rows[futures[fut]] = fut.result()  # a ParcoverError in a worker is re-raised here as itself
                report(1)
        return rows  # type: ignore[return-value]


def _run_ray(jobs, workers, max_steps, report, address) -> list[dict]:
    try:
        import ray
    except ImportError:
        raise ParcoverError("--backend ray needs Ray: pip install 'parcover_env[distributed]'") from None
    started = not ray.is_initialized()
    if started:
        ray.init(
            address=address,
            num_cpus=None if address else workers,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
    try:
        remote = ray.remote(num_cpus=1)(run_job)
        refs = [remote.remote(s, p, seed, max_steps) for s, p, seed in jobs]
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            report(len(ready))
        return ray.get(refs)
    finally:
        if started:
            ray.shutdown()


# ---------------------------------------------------------------------------------------------
# Statistics


def mean_ci(values, level: float = 0.95) -> tuple[float, float, int]:
    """(mean, half-width of the Student-t confidence interval, n) of the finite values."""
    from scipy import stats

    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if len(x) == 0:
        return math.nan, math.nan, 0
    if len(x) == 1:
        return float(x[0]), math.nan, 1
    half = stats.t.ppf(0.5 + level / 2, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x))
    return float(x.mean()), float(half), len(x)


def wilson_ci(k: float, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion k/n (scipy), clipped so that lo <= k/n <= hi."""
    from scipy import stats

    if n == 0:
        return math.nan, math.nan
    ci = stats.binomtest(int(round(k)), int(n)).proportion_ci(confidence_level=level, method="wilson")
    p = k / n
    return min(float(ci.low), p), max(float(ci.high), p)


IQM_BOOTSTRAP = 2000
"""Bootstrap resamples of the IQM confidence interval."""


def iqm_ci(values, level: float = 0.95, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean (scipy ``trim_mean`` at 25 %) and its percentile-bootstrap CI (lo, hi) over
    the finite values; the CI is clipped to contain the IQM. NaN when fewer than 2 values."""
    from scipy import stats

    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if len(x) == 0:
        return math.nan, math.nan, math.nan
    iqm = float(stats.trim_mean(x, 0.25))
    if len(x) < 2 or np.ptp(x) == 0:
        return iqm, iqm if len(x) >= 2 else math.nan, iqm if len(x) >= 2 else math.nan
    res = stats.bootstrap((x,), lambda a, axis: stats.trim_mean(a, 0.25, axis=axis), confidence_level=level,
                          n_resamples=IQM_BOOTSTRAP, method="percentile", rng=np.random.default_rng(seed))
    return iqm, min(float(res.confidence_interval.low), iqm), max(float(res.confidence_interval.high), iqm)


def stratified_iqm_ci(groups: list[list[float]], level: float = 0.95, seed: int = 0,
                      n_resamples: int = IQM_BOOTSTRAP) -> tuple[float, float, float]:
    """IQM over all runs of several tasks (scenarios) and its stratified-bootstrap CI: each resample
    draws runs with replacement within every task (Agarwal et al. 2021, rliable); clipped to contain
    the IQM."""
    from scipy import stats

    xs = [np.asarray([v for v in g if v is not None and np.isfinite(v)], dtype=float) for g in groups]
    xs = [x for x in xs if len(x)]
    if not xs:
        return math.nan, math.nan, math.nan
    iqm = float(stats.trim_mean(np.concatenate(xs), 0.25))
    rng = np.random.default_rng(seed)
    boots = np.empty(n_resamples)
    for b in range(n_resamples):
        boots[b] = stats.trim_mean(np.concatenate([x[rng.integers(0, len(x), len(x))] for x in xs]), 0.25)
    lo, hi = np.quantile(boots, [(1 - level) / 2, (1 + level) / 2])
    return iqm, min(float(lo), iqm), max(float(hi), iqm)


def summarize(rows: list[dict]) -> list[dict]:
    """One row per (scenario, policy): n, success (+ Wilson CI), mean +- 95 % CI of the metrics.

    ``makespan_ratio`` is averaged over successful episodes only (undefined otherwise)."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["policy"]), []).append(r)
    out = []
    for (scenario, policy), g in groups.items():
        n, k = len(g), sum(r["success"] for r in g)
        lo, hi = wilson_ci(k, n)
        s = {
            "scenario": scenario,
            "policy": policy,
            "episodes": n,
            "success": k / n,
            "success_lo": lo,
            "success_hi": hi,
        }
        for m in METRICS:
            if m == "success":
                continue
            mean, half, cnt = mean_ci([r[m] for r in g])
            s[m], s[f"{m}_ci"], s[f"{m}_n"] = mean, half, cnt
        s["makespan_ratio_iqm"], s["makespan_ratio_iqm_lo"], s["makespan_ratio_iqm_hi"] = iqm_ci(
            [r["makespan_ratio"] for r in g])
        out.append(s)
    return out


def _fmt(mean: float, half: float, digits: int = 2) -> str:
    if not np.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f}" + (f" ± {half:.{digits}f}" if np.isfinite(half) else "")


def markdown_table(summary: list[dict]) -> str:
    head = [
        "scenario",
        "policy",
        "episodes",
        "success [95% CI]",
        "makespan / (c_max/v_max)",
        "makespan ratio IQM [95% CI]",
        "KPOIs visited",
        "collisions",
        "messages",
        "wall time (s)",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in summary:
        cells = [
            s["scenario"],
            s["policy"],
            str(s["episodes"]),
            f"{s['success']:.2f} [{s['success_lo']:.2f}, {s['success_hi']:.2f}]",
            _fmt(s["makespan_ratio"], s["makespan_ratio_ci"])
            + (f" (n={s['makespan_ratio_n']})" if s["makespan_ratio_n"] else ""),
            (f"{s['makespan_ratio_iqm']:.2f} [{s['makespan_ratio_iqm_lo']:.2f}, {s['makespan_ratio_iqm_hi']:.2f}]"
             if np.isfinite(s["makespan_ratio_iqm_lo"]) else _fmt(s["makespan_ratio_iqm"], math.nan)),
            _fmt(s["kpoi_fraction"], s["kpoi_fraction_ci"]),
            _fmt(s["collisions"], s["collisions_ci"], 1),
            _fmt(s["messages"], s["messages_ci"], 0),
            _fmt(s["wall_time"], s["wall_time_ci"]),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def plot_summary(summary: list[dict], path: Path) -> None:
    """One bar chart per metric, policies side by side per scenario, 95 % CI error bars."""
    from parcover_env.errors import require

    matplotlib = require("matplotlib", "viz", "bench plots")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = list(dict.fromkeys(s["scenario"] for s in summary))
    policies = list(dict.fromkeys(s["policy"] for s in summary))
    by = {(s["scenario"], s["policy"]): s for s in summary}
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5))
    width = 0.8 / len(policies)
    for ax, (m, (label, _)) in zip(axes.ravel(), METRICS.items(), strict=False):
        for j, p in enumerate(policies):
            xs = np.arange(len(scenarios)) + (j - (len(policies) - 1) / 2) * width
            vals, errs = [], [[], []]
            for sc in scenarios:
                s = by.get((sc, p))
                if s is None:
                    vals.append(np.nan)
                    errs[0].append(0)
                    errs[1].append(0)
                elif m == "success":
                    vals.append(s["success"])
                    errs[0].append(max(0.0, s["success"] - s["success_lo"]))  # never a negative error bar
                    errs[1].append(max(0.0, s["success_hi"] - s["success"]))
                else:
                    half = s[f"{m}_ci"] if np.isfinite(s[f"{m}_ci"]) else 0.0
                    vals.append(s[m])
                    errs[0].append(half)
                    errs[1].append(half)
            ax.bar(xs, vals, width, yerr=errs, capsize=3, label=p)
        ax.set_xticks(range(len(scenarios)), scenarios)
        ax.set_title(label)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_report(rows: list[dict], out: str | Path, plots: bool = True) -> dict[str, Path]:
    """episodes.csv, summary.csv, table.md and summary.png under ``out``; returns their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarize(rows)
    paths = {"episodes": out / "episodes.csv", "summary": out / "summary.csv", "table": out / "table.md"}
    _write_csv(paths["episodes"], rows)
    _write_csv(paths["summary"], summary)
    paths["table"].write_text(markdown_table(summary))
    if plots:
        paths["plot"] = out / "summary.png"
        plot_summary(summary, paths["plot"])
    return paths

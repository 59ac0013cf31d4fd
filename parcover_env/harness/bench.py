"""Benchmark harness: ``parcover bench`` runs (scenario x policy x seed) episodes in parallel and
writes a Markdown table, CSVs and plots; ``parcover collect`` records expert demonstrations as a
Minari dataset.

Statistics follow the rliable conventions (Agarwal et al., 2021, "Deep RL at the edge of the
statistical precipice"): per (scenario, policy) the interquartile mean (IQM, the 25 %-trimmed mean)
of every metric with a 95 % percentile-bootstrap CI, the success rate (a mean of 0/1 outcomes) with
its bootstrap CI, and, over several procedural maps, one aggregate row whose bootstrap resamples
episodes within each map (stratified bootstrap). No normal-approximation intervals.

Policies by spec: ``expert``, ``waypoint``, ``random``, ``ppo:PATH`` (``train_ppo.py`` output dir
or ``model.zip``), ``bc:PATH`` (``docs/lab/scripts/train_bc.py`` output dir or ``bc.pt``), ... and ``py:MODULE:ATTR``
(a policy of your own, imported in every worker); :func:`parcover_env.compare` benches a policy
object or factory from Python with this module's runner and statistics. Backends: ``local``
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
    "EPISODE_FIELDS",
    "bench_env",
    "episode_record",
    "run_calls",
    "iqm",
    "read_episodes",
    "stratified_bootstrap_ci",
    "write_json",
    "run_job",
    "run_sweep",
    "summarize",
    "write_report",
    "METRICS",
]

METRICS = {  # column -> (label, lower is better)
    "success": ("success rate", False),
    "kpoi_fraction": ("KPOIs visited (fraction)", False),
    "makespan_ratio": ("makespan / (c_max/v_max)", True),
    "collisions": ("collisions", True),
    "messages": ("messages", True),
    "wall_time": ("wall time (s)", True),
}
"""Summarized metrics; ``success`` by its mean, the others by their IQM (both with bootstrap CIs)."""

EPISODE_FIELDS = ("scenario", "policy", "preset", "seed", "success", "kpois_visited", "n_kpois", "kpoi_fraction",
                  "makespan", "makespan_ratio", "collisions", "messages", "steps", "localization_error",
                  "wall_time")
"""Keys of one per-episode record (``episodes.csv``, ``--json``)."""


_ENV_CACHE: dict[tuple[str, int | None, str, str], Any] = {}


def bench_env(scenario: str, max_steps: int | None = None, preset: str = "realistic", extra: dict | None = None):
    """The env of one benchmark episode: ``scenario`` with ``preset``, the step limit ``max_steps``
    (None: the scenario's) and the overrides ``extra`` of the policy that drives it. Cached per process."""
    from parcover_env.config import deep_merge
    from parcover_env.envs import ParallelCoverageEnv

    key = (scenario, max_steps, preset, repr(extra))
    if key not in _ENV_CACHE:
        overrides = {"episode": {"max_steps": max_steps}} if max_steps else None
        if extra:
            overrides = deep_merge(overrides or {}, extra)
        _ENV_CACHE[key] = ParallelCoverageEnv(scenario, overrides=overrides, preset=preset)
    return _ENV_CACHE[key]


def episode_record(scenario: str, policy: str, preset: str, seed: int, m: dict) -> dict:
    """The flat record (``EPISODE_FIELDS``) of one episode's metrics ``m`` (``run_episode``'s)."""
    return {
        "scenario": scenario,
        "policy": policy,
        "preset": preset,
        "seed": seed,
        "success": float(m["success"]),
        "kpois_visited": m["kpois_visited"],
        "n_kpois": m["n_kpois"],
        "kpoi_fraction": m["kpois_visited"] / m["n_kpois"],
        "makespan": m["makespan"] if m["makespan"] is not None else math.nan,
        "makespan_ratio": m["makespan_ratio"] if m["makespan_ratio"] is not None else math.nan,
        "collisions": m["collisions"],
        "messages": int(sum(m["messages"].values())),
        "steps": m["steps"],
        "localization_error": m["localization_error"],
        "wall_time": m["wall_time"],
    }


def run_job(scenario: str, policy: str, seed: int, max_steps: int | None = None, preset: str = "realistic") -> dict:
    """One episode; a flat record (``EPISODE_FIELDS``). Envs are cached per process."""
    from parcover_env.harness.rollout import run_episode
    from parcover_env.policies.registry import make_policy, policy_overrides

    env = bench_env(scenario, max_steps, preset, policy_overrides(policy, scenario))
    m = run_episode(env, make_policy(policy, env, seed), seed)
    return episode_record(scenario, policy, preset, seed, m)


def run_sweep(
    scenarios: list[str],
    policies: list[str],
    seeds: list[int],
    workers: int = 1,
    backend: str = "local",
    max_steps: int | None = None,
    progress: bool = True,
    ray_address: str | None = None,
    preset: str = "realistic",
) -> list[dict]:
    """All (scenario, policy, seed) episodes; rows in job order."""
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {backend!r}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    for p in policies:
        check_policy_spec(p)
    jobs = [(s, p, seed, max_steps, preset) for s in scenarios for p in policies for seed in seeds]
    if not jobs:
        raise ValueError("nothing to run: no scenarios, policies or seeds")
    return run_calls(run_job, jobs, workers, backend, progress, ray_address)


def run_calls(fn, jobs: list[tuple], workers: int = 1, backend: str = "local", progress: bool = True,
              ray_address: str | None = None) -> list:
    """``[fn(*job) for job in jobs]``, in job order: in this process (``workers`` 1), in a pool of
    ``workers`` spawned processes (``fn`` and the jobs must pickle) or as Ray tasks; a tqdm bar over
    the episodes when ``progress``. A ParcoverError raised in a worker is re-raised here as itself."""
    from tqdm import tqdm

    with tqdm(total=len(jobs), unit="episode", desc="bench", disable=not progress, dynamic_ncols=True) as bar:
        report = bar.update
        if backend == "ray":
            return _run_ray(fn, jobs, workers, report, ray_address)
        if workers == 1:
            rows = []
            for job in jobs:
                rows.append(fn(*job))
                report(1)
            return rows
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        rows: list[Any] = [None] * len(jobs)
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(fn, *job): i for i, job in enumerate(jobs)}
            for fut in as_completed(futures):
                rows[futures[fut]] = fut.result()  # a ParcoverError in a worker is re-raised here as itself
                report(1)
        return rows


def _run_ray(fn, jobs, workers, report, address) -> list:
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
        remote = ray.remote(num_cpus=1)(fn)
        refs = [remote.remote(*job) for job in jobs]
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

IQM_BOOTSTRAP = 2000
"""Bootstrap resamples of every confidence interval."""


def _finite(values) -> np.ndarray:
    return np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)


def iqm(values) -> float:
    """Interquartile mean: the mean of the middle 50 % (scipy ``trim_mean`` cutting 25 % each side,
    as rliable); NaN without finite values."""
    from scipy import stats

    x = _finite(values)
    return float(stats.trim_mean(x, 0.25)) if len(x) else math.nan


def stratified_bootstrap_ci(groups: list, statistic: str = "iqm", level: float = 0.95, seed: int = 0,
                            n_resamples: int = IQM_BOOTSTRAP) -> tuple[float, float, float]:
    """(estimate, lo, hi): ``statistic`` (``"iqm"`` or ``"mean"``) of all finite values of all groups,
    and its percentile-bootstrap CI where every resample draws, with replacement, as many values from
    each group (task / map) as it has (Agarwal et al. 2021, rliable's stratified bootstrap). The CI is
    clipped to contain the estimate. NaN without values; lo = hi = NaN with a single value."""
    from scipy import stats

    if statistic not in ("iqm", "mean"):
        raise ValueError(f"statistic must be 'iqm' or 'mean', got {statistic!r}")
    xs = [x for x in (_finite(g) for g in groups) if len(x)]
    if not xs:
        return math.nan, math.nan, math.nan
    both = np.concatenate(xs)
    fn = (lambda a: stats.trim_mean(a, 0.25, axis=-1)) if statistic == "iqm" else (lambda a: a.mean(axis=-1))
    est = float(fn(both))
    if len(both) < 2:
        return est, math.nan, math.nan
    rng = np.random.default_rng(seed)
    boots = fn(np.concatenate([x[rng.integers(0, len(x), (n_resamples, len(x)))] for x in xs], axis=1))
    lo, hi = np.quantile(boots, [(1 - level) / 2, (1 + level) / 2])
    return est, min(float(lo), est), max(float(hi), est)


def iqm_ci(values, level: float = 0.95, seed: int = 0) -> tuple[float, float, float]:
    """IQM of the finite values and its percentile-bootstrap CI (one group)."""
    return stratified_bootstrap_ci([values], "iqm", level, seed)


def stratified_iqm_ci(groups: list[list[float]], level: float = 0.95, seed: int = 0,
                      n_resamples: int = IQM_BOOTSTRAP) -> tuple[float, float, float]:
    """IQM over all runs of several tasks and its stratified-bootstrap CI."""
    return stratified_bootstrap_ci(groups, "iqm", level, seed, n_resamples)


def wilson_ci(k: float, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion k/n (scipy), clipped so that lo <= k/n <= hi. Reported
    beside the bootstrap CI of the success rate, which collapses to a point at 0/n and n/n."""
    from scipy import stats

    if n == 0:
        return math.nan, math.nan
    ci = stats.binomtest(int(round(k)), int(n)).proportion_ci(confidence_level=level, method="wilson")
    p = k / n
    return min(float(ci.low), p), max(float(ci.high), p)


def family(scenario: str) -> str:
    """``generated:17`` -> ``generated:*`` (a label after the map number stays: ``generated:17 (ideal)``
    -> ``generated:* (ideal)``); other scenarios are their own family."""
    if not scenario.startswith("generated:"):
        return scenario
    rest = scenario.removeprefix("generated:")
    digits = len(rest) - len(rest.lstrip("0123456789"))
    return "generated:*" + rest[digits:]


def _summary_row(scenario: str, policy: str, strata: list[list[dict]]) -> dict:
    rows = [r for g in strata for r in g]
    n, k = len(rows), sum(r["success"] for r in rows)
    s: dict[str, Any] = {"scenario": scenario, "policy": policy, "episodes": n, "maps": len(strata)}
    s["preset"] = ",".join(sorted({str(r.get("preset", "")) for r in rows}))
    s["success"], s["success_lo"], s["success_hi"] = stratified_bootstrap_ci(
        [[r["success"] for r in g] for g in strata], "mean")
    s["success_wilson_lo"], s["success_wilson_hi"] = wilson_ci(k, n)
    for m in METRICS:
        if m == "success":
            continue
        s[m], s[f"{m}_lo"], s[f"{m}_hi"] = stratified_bootstrap_ci([[r[m] for r in g] for g in strata], "iqm")
        s[f"{m}_n"] = int(sum(len(_finite([r[m] for r in g])) for g in strata))
    return s


def summarize(rows: list[dict]) -> list[dict]:
    """One row per (scenario, policy): episodes, success rate (mean, stratified bootstrap CI, and the
    Wilson interval), and the IQM [95 % bootstrap CI] of every other metric; ``makespan_ratio`` over
    successful episodes only (undefined otherwise). When a policy ran on several ``generated:*`` maps
    an aggregate ``generated:*`` row follows, its bootstrap stratified by map (resampling episodes
    within each map); with a single episode per map a stratum cannot vary, so the maps themselves are
    resampled (plain bootstrap over maps)."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["policy"]), []).append(r)
    out = [_summary_row(sc, p, [g]) for (sc, p), g in groups.items()]
    fams: dict[tuple[str, str], list[list[dict]]] = {}
    for (sc, p), g in groups.items():
        if family(sc) != sc:
            fams.setdefault((family(sc), p), []).append(g)
    for (f, p), strata in fams.items():
        if len(strata) < 2:
            continue
        if all(len(g) == 1 for g in strata):  # one episode per map: the maps are the runs (plain bootstrap)
            row = _summary_row(f, p, [[g[0] for g in strata]])
            row["maps"] = len(strata)
            out.append(row)
        else:
            out.append(_summary_row(f, p, strata))
    return out


def _fmt_ci(est: float, lo: float, hi: float, digits: int = 2) -> str:
    if not np.isfinite(est):
        return "-"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{est:.{digits}f}"
    return f"{est:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


TABLE_HEAD = (
    "scenario", "policy", "episodes", "success [95% CI]", "KPOI fraction IQM [95% CI]",
    "makespan ratio IQM [95% CI]", "collisions IQM [95% CI]", "messages IQM [95% CI]", "wall time (s) IQM",
)


def markdown_table(summary: list[dict]) -> str:
    """The summary as a Markdown table (IQM and 95 % stratified bootstrap CIs; the success rate's
    Wilson interval in parentheses)."""
    lines = ["| " + " | ".join(TABLE_HEAD) + " |", "|" + "---|" * len(TABLE_HEAD)]
    for s in summary:
        succ = _fmt_ci(s["success"], s["success_lo"], s["success_hi"])
        if np.isfinite(s["success_wilson_lo"]):
            succ += f" (Wilson {s['success_wilson_lo']:.2f}-{s['success_wilson_hi']:.2f})"
        eps = str(s["episodes"]) + (f" ({s['maps']} maps)" if s["maps"] > 1 else "")
        ms = _fmt_ci(s["makespan_ratio"], s["makespan_ratio_lo"], s["makespan_ratio_hi"])
        if s["makespan_ratio_n"]:
            ms += f" (n={s['makespan_ratio_n']})"
        cells = [
            s["scenario"], s["policy"], eps, succ,
            _fmt_ci(s["kpoi_fraction"], s["kpoi_fraction_lo"], s["kpoi_fraction_hi"]), ms,
            _fmt_ci(s["collisions"], s["collisions_lo"], s["collisions_hi"], 1),
            _fmt_ci(s["messages"], s["messages_lo"], s["messages_hi"], 0),
            _fmt_ci(s["wall_time"], math.nan, math.nan),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def write_json(rows: list[dict], path: str | Path) -> Path:
    """The per-episode records as a JSON list (NaN written as null)."""
    import json

    clean = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()} for r in rows]
    path = Path(path)
    path.write_text(json.dumps(clean, indent=1) + "\n")
    return path


def read_episodes(path: str | Path) -> list[dict]:
    """Per-episode records from a ``--json`` file or an ``episodes.csv`` (null/empty -> NaN)."""
    import json

    path = Path(path)
    if path.suffix == ".json":
        rows = json.loads(path.read_text())
        return [{k: (math.nan if v is None else v) for k, v in r.items()} for r in rows]
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            row: dict[str, Any] = {}
            for k, v in r.items():
                if k in ("scenario", "policy", "preset"):
                    row[k] = v
                else:
                    try:
                        row[k] = float(v) if v != "" else math.nan
                    except ValueError:
                        row[k] = v
            out.append(row)
    return out


def plot_summary(summary: list[dict], path: Path) -> None:
    """One bar chart per metric, policies side by side per scenario: success rate and IQMs with
    their 95 % bootstrap CIs as error bars."""
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
                v = s[m] if s is not None else math.nan
                lo = s[f"{m}_lo"] if s is not None else math.nan
                hi = s[f"{m}_hi"] if s is not None else math.nan
                vals.append(v)
                ok = np.isfinite(v) and np.isfinite(lo) and np.isfinite(hi)
                errs[0].append(max(0.0, v - lo) if ok else 0.0)  # never a negative error bar
                errs[1].append(max(0.0, hi - v) if ok else 0.0)
            ax.bar(xs, vals, width, yerr=errs, capsize=3, label=p)
        ax.set_xticks(range(len(scenarios)), scenarios, fontsize=8)
        ax.set_title(label + ("" if m == "success" else " (IQM)"))
    axes[0, 0].legend(fontsize=7)
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

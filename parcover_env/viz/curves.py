"""Learning curves of training runs: ``curve.csv`` (training episodes) and ``eval.csv`` (periodic
evaluation) written by ``baselines/train_ppo.py`` (agent-steps in ``timesteps``) and ``parcover train``
(agent-steps in ``agent_steps``), against agent-steps and wall time: one figure, two panels sharing the y axis."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = ["read_rows", "smooth", "Series", "training_series", "eval_series", "learning_curve_figure",
           "plot_learning_curves"]


def read_rows(path: str | Path) -> list[dict[str, float]]:
    """A CSV as a list of dicts, numeric columns as floats (others kept as strings)."""
    out = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            conv = {}
            for k, v in row.items():
                try:
                    conv[k] = float(v)
                except (TypeError, ValueError):
                    conv[k] = v
            out.append(conv)
    return out


def smooth(x: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average: entry i is the mean of ``x[max(0, i - window + 1) .. i]``."""
    x = np.asarray(x, dtype=float)
    if window < 1:
        raise ValueError(f"window must be >= 1, got {window}")
    c = np.concatenate([[0.0], np.cumsum(x)])
    idx = np.arange(len(x))
    lo = np.maximum(0, idx - window + 1)
    return (c[idx + 1] - c[lo]) / (idx + 1 - lo)


class Series(NamedTuple):
    """One curve, on both x axes."""

    agent_steps: np.ndarray
    wall_minutes: np.ndarray
    value: np.ndarray


def training_series(rows: list[dict], metric: str = "kpoi_fraction", window: int = 20) -> Series:
    """The training episodes of a ``curve.csv`` (rows in order): ``metric`` as a trailing ``window``-episode
    mean against agent-steps (``agent_steps``, or ``timesteps`` in older files) and wall time."""
    steps = [r["agent_steps"] if "agent_steps" in r else r["timesteps"] for r in rows]
    return Series(np.array(steps, dtype=float), np.array([r["wall_time"] for r in rows], dtype=float) / 60,
                  smooth(np.array([r[metric] for r in rows], dtype=float), window))


def eval_series(rows: list[dict], metric: str = "kpoi_fraction") -> Series:
    """The periodic evaluations of an ``eval.csv``: the mean ``metric`` of each evaluation (rows sharing
    ``timesteps``), at its agent-steps and at the wall time its last row was written."""
    steps = sorted({r["timesteps"] for r in rows})
    at = [[r for r in rows if r["timesteps"] == s] for s in steps]
    return Series(np.array(steps, dtype=float), np.array([max(r["wall_time"] for r in g) for g in at]) / 60,
                  np.array([np.mean([r[metric] for r in g]) for g in at]))


FRACTIONS = ("kpoi_fraction", "success")
"""Metrics in [0, 1]: their curves are drawn on that whole range."""


def learning_curve_figure(runs: list[str | Path], labels: list[str] | None = None, metric: str = "kpoi_fraction",
                          window: int = 20):
    """A matplotlib figure, two panels (x = agent-steps, x = wall time in minutes) sharing the y axis:
    per run directory, :func:`training_series` of its ``curve.csv`` (thin line) and :func:`eval_series`
    of its ``eval.csv`` (markers), one colour per run."""
    from parcover_env.errors import require

    matplotlib = require("matplotlib", "viz", "learning curves")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = labels or [Path(r).name for r in runs]
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    for k, (run, label) in enumerate(zip(runs, labels, strict=True)):
        color, run = f"C{k}", Path(run)
        rows = read_rows(run / "curve.csv") if (run / "curve.csv").is_file() else []
        if rows:
            train = training_series(rows, metric, window)
            axes[0].plot(train.agent_steps, train.value, color=color, lw=1, alpha=0.6, label=label)
            axes[1].plot(train.wall_minutes, train.value, color=color, lw=1, alpha=0.6)
        ev = read_rows(run / "eval.csv") if (run / "eval.csv").is_file() else []
        if ev:
            val = eval_series(ev, metric)
            axes[0].plot(val.agent_steps, val.value, "o--", color=color, label=f"{label} (eval)")
            axes[1].plot(val.wall_minutes, val.value, "o--", color=color)
    name = metric.replace("_", " ")
    axes[0].set(xlabel="agent-steps", ylabel=name)
    if metric in FRACTIONS:  # a fraction keeps its whole range in view; a return scales to its data
        axes[0].set_ylim(-0.05, 1.05)
    axes[1].set(xlabel="wall time (min)")
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=8, loc="best")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"{name}: training episodes ({window}-episode mean, lines), evaluation (markers)", fontsize=9)
    fig.tight_layout()
    return fig


def plot_learning_curves(runs: list[str | Path], path: str | Path, labels: list[str] | None = None,
                         metric: str = "kpoi_fraction", window: int = 20) -> Path:
    """Write :func:`learning_curve_figure` to ``path``."""
    import matplotlib.pyplot as plt

    fig = learning_curve_figure(runs, labels, metric, window)
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path

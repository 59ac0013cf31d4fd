"""Learning curves of training runs: ``curve.csv`` (training episodes) and ``eval.csv`` (periodic
evaluation) written by ``baselines/train_ppo.py`` (agent-steps in ``timesteps``) and ``parcover train``
(agent-steps in ``agent_steps``), against agent-steps and wall time."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

__all__ = ["read_rows", "smooth", "plot_learning_curves"]


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


def plot_learning_curves(runs: list[str | Path], path: str | Path, labels: list[str] | None = None,
                         metric: str = "kpoi_fraction", window: int = 20) -> Path:
    """One figure, two panels (x = agent-steps, x = wall time in minutes): the training episodes'
    ``metric`` (moving average over ``window`` episodes, thin) and the periodic evaluation's mean
    (markers) for every run directory."""
    from parcover_env.errors import require

    matplotlib = require("matplotlib", "viz", "learning curves")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = labels or [Path(r).name for r in runs]
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    for k, (run, label) in enumerate(zip(runs, labels, strict=True)):
        color = f"C{k}"
        run = Path(run)
        if (run / "curve.csv").is_file():
            rows = read_rows(run / "curve.csv")
            if rows:
                y = smooth(np.array([r[metric] for r in rows]), window)
                steps = [r["agent_steps"] if "agent_steps" in r else r["timesteps"] for r in rows]
                axes[0].plot(steps, y, color=color, lw=1, alpha=0.6)
                axes[1].plot([r["wall_time"] / 60 for r in rows], y, color=color, lw=1, alpha=0.6)
        if (run / "eval.csv").is_file():
            ev = read_rows(run / "eval.csv")
            steps = sorted({r["timesteps"] for r in ev})
            mean = [np.mean([r[metric] for r in ev if r["timesteps"] == s]) for s in steps]
            wall = [max(r["wall_time"] for r in ev if r["timesteps"] == s) / 60 for s in steps]
            axes[0].plot(steps, mean, "o--", color=color, label=f"{label} (eval)")
            axes[1].plot(wall, mean, "o--", color=color)
    name = metric.replace("_", " ")
    axes[0].set(xlabel="agent-steps", ylabel=name, ylim=(-0.05, 1.05))
    axes[1].set(xlabel="wall time (min)")
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=8, loc="best")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"{name}: training episodes ({window}-episode mean, lines), validation (markers)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path

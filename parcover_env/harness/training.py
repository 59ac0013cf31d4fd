"""Run records of a training run, shared by ``parcover train`` and the SB3 scripts: :class:`RunRecord`
writes a run's sidecar JSON (the exact command, the git commit when the run started, versions, CPU
count), :func:`write_csv`, :func:`plot_curve`. The SB3 helpers live in
:mod:`parcover_env.harness.sb3_training`.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import platform
import shlex
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["RunRecord", "git_commit", "versions", "write_csv", "plot_curve"]


def git_commit(where: Path) -> str:
    """``HEAD`` of the git checkout holding ``where`` (``-dirty`` when tracked files changed), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=where, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=where,
                               capture_output=True, text=True, check=True).stdout.strip()
        return sha.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def versions() -> dict[str, str]:
    """Python's and the training stack's package versions."""
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("parcover_env", "stable-baselines3", "torch", "numpy", "gymnasium", "pettingzoo", "pymunk"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


@dataclass
class RunRecord:
    """How a training run was started: ``python SCRIPT ARGV`` at ``commit`` (read when the run
    starts: HEAD may move during a long run)."""

    script: Path
    argv: list[str] = field(default_factory=list)
    commit: str = ""

    @classmethod
    def start(cls, script: str | Path, argv: list[str]) -> RunRecord:
        script = Path(script).resolve()
        return cls(script, list(argv), git_commit(script.parent))

    def write_sidecar(self, path: Path, info: dict) -> None:
        """``info`` plus the command, the git commit, the CPU count and the versions, as JSON."""
        rel = self.script
        with contextlib.suppress(ValueError):
            rel = rel.relative_to(Path.cwd())
        record = {"command": shlex.join(["python", str(rel), *self.argv]), "git_commit": self.commit or "unknown",
                  "versions": versions(), "cpu_count": os.cpu_count(), **info}
        path.write_text(json.dumps(record, indent=2, default=str) + "\n")


def write_csv(path: Path, rows: list[dict]) -> None:
    """``rows`` (dicts with the same keys) as CSV; nothing when there are no rows."""
    if not rows:
        return
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def plot_curve(out: Path) -> None:
    """``OUT/curve.png`` from ``curve.csv`` (+ ``eval.csv``); see :mod:`parcover_env.viz.curves`."""
    from parcover_env.viz.curves import plot_learning_curves

    if (out / "curve.csv").is_file():
        plot_learning_curves([out], out / "curve.png")

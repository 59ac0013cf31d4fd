"""Run one episode of a policy in an env and return its metrics."""

from __future__ import annotations

import sys
import time

__all__ = ["run_episode"]


def _progress(done: int, total: int, width: int = 30, stream=sys.stderr, ended: bool = False) -> None:
    """A one-line progress bar over the step limit; ``ended`` closes it when the episode ends."""
    if not (ended or stream.isatty()) and done % max(total // 10, 1):
        return
    filled = width if ended else int(width * done / max(total, 1))
    tail = f"episode ended after {done} steps" if ended else f"{done}/{total} steps"
    stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {tail}" + ("\n" if ended else ""))
    stream.flush()


def run_episode(env, policy, seed: int | None, max_steps: int | None = None, frames: list | None = None,
                progress: bool = False) -> dict:
    """Run one episode; returns the episode metrics (plus wall time)."""
    obs, _ = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset(obs)
    limit = max_steps or env.scenario.episode.max_steps
    summary, t0, step = None, time.perf_counter(), 0
    if frames is not None:
        frames.append(env.render())
    while env.agents and step < limit:
        obs, _, _, _, infos = env.step(policy.act(obs))
        step += 1
        if frames is not None:
            frames.append(env.render())
        if progress and env.agents and step < limit:
            _progress(step, limit)
        if not env.agents:
            summary = next(iter(infos.values()))["episode"]
    if progress:
        _progress(step, limit, ended=True)
    if summary is None:
        summary = env.metrics.summary()
    summary["wall_time"] = time.perf_counter() - t0
    if hasattr(policy, "stats"):
        summary.update(policy.stats())
    return summary

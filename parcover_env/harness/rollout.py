"""Run one episode of a policy in an env and return its metrics."""

from __future__ import annotations

import math
import time

from parcover_env.envs.metrics import episode_metrics
from parcover_env.policies.protocol import Policy

__all__ = ["add_free_space_ratio", "makespan_ratio", "run_episode"]


def makespan_ratio(makespan: float | None, bound: float, max_speed: float) -> float | None:
    """``makespan / (bound / max_speed)``: the makespan (s) over the time (s) a robot at top speed
    needs for ``bound`` (m); None without a makespan (a failed mission), NaN for a bound <= 0."""
    if makespan is None:
        return None
    time_bound = bound / max_speed if bound > 0 and max_speed > 0 else math.nan
    return makespan / time_bound


def add_free_space_ratio(summary: dict, plan) -> dict:
    """Add ``c_free`` (the plan's free-space lower bound, m) and ``makespan_ratio_free`` (the
    makespan over ``c_free / v_max``; ``makespan_ratio`` divides by ``c_max / v_max``, the roadmap
    metric) to an episode summary (:meth:`EpisodeMetrics.summary`); returns it."""
    summary["c_free"] = float(plan.c_free)
    summary["makespan_ratio_free"] = makespan_ratio(summary.get("makespan"), plan.c_free, summary["max_speed"])
    return summary


def run_episode(env, policy: Policy, seed: int | None, max_steps: int | None = None, frames=None,
                progress: bool = False) -> dict:
    """Run one episode; returns the episode metrics (plus wall time).

    ``frames``: anything with ``append`` (a list, or a streaming ``viz.render.GifRecorder``) that
    receives every rendered frame, the first and the last included. ``progress``: a tqdm bar over
    the step limit on stderr, closed with the step at which the episode ended.
    """
    obs, _ = env.reset(seed=seed)
    policy.reset(obs)
    limit = max_steps or env.scenario.episode.max_steps
    summary, t0, step = None, time.perf_counter(), 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=limit, unit="step", desc=env.scenario.name, leave=True, dynamic_ncols=True)
    if frames is not None:
        frames.append(env.render())
    try:
        while env.agents and step < limit:
            obs, _, _, _, infos = env.step(policy.act(obs))
            step += 1
            if frames is not None:
                frames.append(env.render())
            if bar is not None:
                bar.update(1)
            if not env.agents:
                summary = episode_metrics(next(iter(infos.values())))
        if bar is not None:
            bar.set_postfix_str(f"episode ended after {step} steps", refresh=False)
    finally:
        if bar is not None:
            bar.close()
    if summary is None:
        summary = env.metrics.summary()
    summary["wall_time"] = time.perf_counter() - t0
    add_free_space_ratio(summary, env.plan)
    summary.update(policy.stats())
    return summary

"""Why did an episode fail? Roll out with a few extra measurements, then name one cause.

:func:`run_diagnosed` runs an episode like :func:`~parcover_env.harness.rollout.run_episode` and
adds what the summary metrics cannot tell: how close any robot ever came to each KPOI, how far
each robot moved in the last ``window`` seconds, how far each robot ended from the walls and the
other robots, and each robot's final pose error — of the env's estimate and, when the policy keeps
its own belief (``policy.belief()``, e.g. sonar-corrected), of that belief.

:func:`classify_failure` turns those into one cause, checked in this order (the first that holds
wins), looking only at the robots credited with an unvisited KPOI (the plan's ``kpoi_owner``):

* ``solved`` — every KPOI visited;
* ``error`` — the rollout raised;
* ``localization lost`` — such a robot's pose belief is off by more than ``kpoi_radius``;
* ``collision-locked`` — all such robots stopped moving in the last ``window`` seconds and at
  least one of them is touching a wall or a robot;
* ``stalled`` — all such robots stopped moving, none touching anything (waiting, turning in place);
* ``KPOI never approached`` — no robot ever came within twice ``kpoi_radius`` of an unvisited KPOI;
* ``timeout`` — robots were still on their way when the step limit came.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass

import numpy as np

from parcover_env.envs.metrics import episode_metrics
from parcover_env.harness.rollout import add_free_space_ratio
from parcover_env.policies.protocol import Policy

__all__ = ["EpisodeDiagnosis", "CAUSES", "classify_failure", "run_diagnosed"]

CAUSES = ("solved", "error", "localization lost", "collision-locked", "stalled", "KPOI never approached",
          "timeout")


@dataclass(frozen=True)
class EpisodeDiagnosis:
    """Per-episode measurements behind :func:`classify_failure` (SI units)."""

    visited: np.ndarray
    """``(K,)`` bool: KPOI visited."""
    owner: np.ndarray
    """``(K,)`` index of the robot the plan credits with each KPOI."""
    closest: np.ndarray
    """``(K,)`` closest any robot's true centre came to each KPOI (m)."""
    moved: np.ndarray
    """``(N,)`` straight-line distance each robot moved over the last ``window`` seconds (m)."""
    clearance: np.ndarray
    """``(N,)`` final gap between each robot's disc and the nearest wall or robot disc (m)."""
    belief_error: np.ndarray
    """``(N,)`` final position error of the pose the robot steers by (m)."""
    kpoi_radius: float
    error: str | None = None


def classify_failure(d: EpisodeDiagnosis, still: float = 0.1, contact: float = 0.02) -> str:
    """One cause from :data:`CAUSES` (see the module docstring); ``still`` (m) is the movement under
    which a robot counts as stopped, ``contact`` (m) the gap under which it counts as touching."""
    if d.error is not None:
        return "error"
    if d.visited.all():
        return "solved"
    open_k = ~d.visited
    resp = np.unique(d.owner[open_k])
    resp = resp[resp >= 0]
    if len(resp) and np.any(d.belief_error[resp] > d.kpoi_radius):
        return "localization lost"
    if len(resp) and np.all(d.moved[resp] < still):
        return "collision-locked" if np.any(d.clearance[resp] < contact) else "stalled"
    if np.all(d.closest[open_k] > 2 * d.kpoi_radius):
        return "KPOI never approached"
    return "timeout"


def _clearance(env, true: np.ndarray) -> np.ndarray:
    import shapely

    r = env.scenario.robot.radius
    walls = np.asarray(shapely.distance(env.map.free.boundary, shapely.points(true[:, :2]))) - r
    gaps = np.hypot(*(true[:, None, :2] - true[None, :, :2]).transpose(2, 0, 1)) - 2 * r
    np.fill_diagonal(gaps, np.inf)
    return np.minimum(walls, gaps.min(axis=1))


def _true_poses(env) -> np.ndarray:
    return env.true_poses() if hasattr(env, "true_poses") else env.world.poses()


def _estimates(env) -> np.ndarray:
    return env.pose_estimates() if hasattr(env, "pose_estimates") else env.estimate


def run_diagnosed(env, policy: Policy, seed: int | None, window: float = 20.0) -> tuple[dict, EpisodeDiagnosis]:
    """Run one episode; returns (episode summary + ``cause``, diagnosis). ``window`` in seconds."""
    plan, kpois = env.plan, np.asarray(env.scenario.kpois, dtype=float)
    n, dt = env.n_robots, env.scenario.physics.control_dt
    keep = max(1, int(round(window / dt)))
    closest = np.full(len(kpois), np.inf)
    history: list[np.ndarray] = []
    summary, error, t0 = None, None, time.perf_counter()
    try:
        obs, _ = env.reset(seed=seed)
        policy.reset(obs)
        while env.agents:
            obs, _, _, _, infos = env.step(policy.act(obs))
            true = _true_poses(env)
            d = np.hypot(*(kpois[:, None, :] - true[None, :, :2]).transpose(2, 0, 1))
            closest = np.minimum(closest, d.min(axis=1))
            history.append(true[:, :2].copy())
            if len(history) > keep:
                history.pop(0)
            if not env.agents:
                summary = episode_metrics(next(iter(infos.values())))
    except Exception as exc:  # noqa: BLE001 - a benchmark reports crashes as a cause, it does not stop
        error = f"{type(exc).__name__}: {exc}"
    if summary is None:
        summary = env.metrics.summary()
    summary["wall_time"] = time.perf_counter() - t0
    add_free_space_ratio(summary, env.plan)
    summary.update(policy.stats())
    true = _true_poses(env)
    belief = _estimates(env)
    with contextlib.suppress(RuntimeError):  # no observation yet
        own = policy.belief()
        if own is not None:  # the policy steers by its own estimate
            belief = np.asarray(own, dtype=float).reshape(n, -1)
    moved = np.hypot(*(history[-1] - history[0]).T) if history else np.zeros(n)
    diag = EpisodeDiagnosis(visited=env.progress.visited.copy(), owner=plan.kpoi_owner(), closest=closest,
                            moved=moved, clearance=_clearance(env, true),
                            belief_error=np.hypot(*(belief[:, :2] - true[:, :2]).T),
                            kpoi_radius=env.scenario.kpoi_radius, error=error)
    summary["cause"] = classify_failure(diag)
    return summary, diag

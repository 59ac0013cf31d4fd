"""Named reward terms. Each agent's reward is the sum of its terms; the terms go into ``info``.

The functions take one world's ``(N,)`` arrays or ``K`` worlds' ``(K, N)`` blocks (the stepper's
score phase scores every world in one call); the numbers are the same either way.
"""

from __future__ import annotations

import numpy as np

from parcover_env.config import RewardConfig
from parcover_env.geometry.rays import point_segment_distance

__all__ = ["TERMS", "TERMS_V2", "TEAM_TERMS", "REWARD_KEYS", "terms_for", "reward_terms", "own_visits", "touching",
           "sigma_major"]

TERMS = ("kpoi", "progress", "time", "collision")
"""The terms of version 1 (and of version 2 after ``own_kpoi``)."""
TERMS_V2 = ("own_kpoi", *TERMS)
"""The terms of version 2: the per-robot ``own_kpoi`` first."""
TEAM_TERMS = ("kpoi", "time")
"""The terms :func:`reward_terms` gives one value for all agents of a world (one number broadcast)."""
REWARD_KEYS = tuple(f"reward_{t}" for t in TERMS)
"""Info keys of the version-1 terms: ``info[agent]["reward_kpoi"]`` etc. (flat, present at reset as 0)."""


def terms_for(version: int, contact: bool = False, uncertainty: bool = False) -> tuple[str, ...]:
    """The reward terms of observation ``version`` (1: :data:`TERMS`, 2: :data:`TERMS_V2`), then
    ``contact`` when ``contact`` and ``uncertainty`` when ``uncertainty`` (their weights are not 0)."""
    terms = TERMS_V2 if version == 2 else TERMS
    return (*terms, *(("contact",) if contact else ()), *(("uncertainty",) if uncertainty else ()))


def sigma_major(cov: np.ndarray) -> np.ndarray:
    """The major axis (1 sigma, m) of the position uncertainty ellipse of pose covariances
    ``(..., 3, 3)`` (x, y, heading): the square root of the larger eigenvalue of the x-y block."""
    a, b, c = cov[..., 0, 0], cov[..., 0, 1], cov[..., 1, 1]
    return np.sqrt(np.maximum(0.5 * (a + c) + np.hypot(0.5 * (a - c), b), 0.0))


def touching(xy: np.ndarray, segments: np.ndarray, radius: float, gap: float) -> np.ndarray:
    """``(N,)`` float, 1 where robot ``i`` (a disc of ``radius`` centred at ``xy[i]``, ``xy (N, 2)``)
    is within ``gap`` of touching a wall (``segments (S, 4)``) or another robot, else 0."""
    xy = np.asarray(xy, dtype=float)
    near = np.zeros(len(xy), dtype=bool)
    if len(segments):
        near |= point_segment_distance(xy, segments).min(axis=1) < radius + gap
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    near |= (d < 2.0 * radius + gap).any(axis=1)
    return near.astype(float)


def own_visits(newly: np.ndarray, visitor: np.ndarray, owner: np.ndarray, n_robots: int) -> np.ndarray:
    """KPOIs of its own route each robot visited this step ``(N,)``: ``newly (n_kpois,)`` bool the
    KPOIs first visited this step, ``visitor`` the robot that visited each, ``owner`` the robot
    whose route the plan credits with each. ``K`` worlds: ``newly`` and ``visitor`` ``(K, n_kpois)``,
    the result ``(K, N)``."""
    lead = newly.shape[:-1]
    mine = newly & (visitor == owner) & (visitor >= 0)
    world = np.arange(int(np.prod(lead, dtype=np.int64))).reshape(*lead, 1)
    counts = np.bincount((visitor + n_robots * world)[mine], minlength=world.size * n_robots)
    return counts.reshape(*lead, n_robots).astype(float)


def reward_terms(w: RewardConfig, n_new_kpois, progress: np.ndarray,
                 new_contacts: np.ndarray, own_new: np.ndarray | None = None,
                 touch: np.ndarray | None = None, sigma: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Weighted terms per agent ``{name: (N,)}`` (or ``(K, N)`` for ``K`` worlds: ``progress``,
    ``new_contacts`` and ``own_new`` ``(K, N)``, ``n_new_kpois (K,)``).

    own_kpoi (only when ``own_new`` is given, version 2): ``w.own_kpoi`` per KPOI of the agent's own
    route that the agent itself visited this step (``own_new``, from :func:`own_visits`);
    kpoi: ``w.kpoi`` per KPOI newly visited by anyone (team reward / team bonus, every agent);
    progress: ``w.progress`` per metre of route-length-to-go removed this step (potential-based);
    time: ``w.time`` every step; collision: ``w.collision`` per new contact of this agent;
    contact (only when ``touch`` is given, 1 where the agent touches something this step, from
    :func:`touching`): ``w.contact`` per step in contact; uncertainty (only when ``sigma`` is given,
    the agent's :func:`sigma_major` in m): ``w.uncertainty * sigma`` per step.
    """
    shape = np.shape(progress)
    kpoi = np.empty(shape)
    kpoi[...] = np.multiply(w.kpoi, n_new_kpois)[..., None]
    terms = {} if own_new is None else {"own_kpoi": w.own_kpoi * own_new}
    terms.update({
        "kpoi": kpoi,
        "progress": w.progress * progress,
        "time": np.full(shape, w.time),
        "collision": w.collision * new_contacts.astype(float),
    })
    if touch is not None:
        terms["contact"] = w.contact * touch
    if sigma is not None:
        terms["uncertainty"] = w.uncertainty * sigma
    return terms

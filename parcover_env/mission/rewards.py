"""Named reward terms, one table (:data:`TERM_TABLE`). Each agent's reward is the sum of its world's
terms (its feature set's, :mod:`parcover_env.envs.feature_sets`, then the optional terms it weights:
:func:`paid_terms`); the terms go into ``info``. A term is its weight's name in
:class:`~parcover_env.config.RewardConfig`, the function of the step's :class:`RewardInputs` it pays,
and the optional input it needs (computed by the score phase only for worlds that pay the term).

The functions take one world's ``(N,)`` arrays or ``K`` worlds' ``(K, N)`` blocks (the
score phase scores every world in one call); the numbers are the same either way.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from parcover_env.config import RewardConfig
from parcover_env.geometry.rays import point_segment_distance

__all__ = ["TERMS", "TERMS_V2", "TEAM_TERMS", "REWARD_KEYS", "RewardInputs", "Term", "TERM_TABLE",
           "paid_terms", "inputs_needed", "reward_terms", "own_visits", "touching", "sigma_major"]

TERMS = ("kpoi", "progress", "time", "collision")
"""The terms of version 1 (and of version 2 after ``own_kpoi``)."""
TERMS_V2 = ("own_kpoi", *TERMS)
"""The terms of version 2: the per-robot ``own_kpoi`` first."""
REWARD_KEYS = tuple(f"reward_{t}" for t in TERMS)
"""Info keys of the version-1 terms: ``info[agent]["reward_kpoi"]`` etc. (flat, present at reset as 0)."""


class RewardInputs(NamedTuple):
    """What the reward terms of ``K`` worlds read (one world: ``K = 1``, or arrays without the leading
    axis). An input that no term of the worlds :attr:`~Term.needs` may be None."""

    new_kpois: np.ndarray | int
    """``(K,)`` KPOIs first visited this step in each world (by anyone)."""
    gained: np.ndarray
    """``(K, N)`` route length to go each robot removed this step (m)."""
    new_contacts: np.ndarray
    """``(K, N)`` new wall and robot contacts of each robot this step."""
    own_new: np.ndarray | None = None
    """``(K, N)`` KPOIs of its own route each robot itself visited this step (:func:`own_visits`)."""
    touch: np.ndarray | None = None
    """``(K, N)`` 1 where the robot touches something this step, else 0 (:func:`touching`)."""
    sigma: np.ndarray | None = None
    """``(K, N)`` each robot's :func:`sigma_major` after this step's fixes (m)."""


@dataclass(frozen=True)
class Term:
    """One named reward term: ``value(weight, inputs, shape)`` is its ``(K, N)`` (``shape``) values for the
    :class:`~parcover_env.config.RewardConfig` weight named ``weight``."""

    weight: str
    value: Callable[[float, RewardInputs, tuple[int, ...]], np.ndarray]
    doc: str
    team: bool = False
    """One value for all the agents of a world (the infos read it once per world)."""
    needs: str | None = None
    """The optional :class:`RewardInputs` field the term reads (computed only for worlds that pay it)."""
    optional: bool = False
    """Paid only when its weight is not 0 (:func:`paid_terms`): with weight 0 the term is absent (no info
    key, no input computed), so rollouts are those without it."""


def _kpoi(c: float, x: RewardInputs, shape: tuple[int, ...]) -> np.ndarray:
    out = np.empty(shape)
    out[...] = np.multiply(c, x.new_kpois)[..., None]
    return out


TERM_TABLE: dict[str, Term] = {
    "own_kpoi": Term("own_kpoi", lambda c, x, shape: c * x.own_new, needs="own_new",
                     doc="per KPOI of the agent's own route that the agent itself visited this step (version 2)"),
    "kpoi": Term("kpoi", _kpoi, team=True, doc="per KPOI newly visited by anyone (team reward, every agent)"),
    "progress": Term("progress", lambda c, x, shape: c * x.gained,
                     doc="per metre of route length to go removed this step (potential-based)"),
    "time": Term("time", lambda c, x, shape: np.full(shape, c), team=True, doc="every step"),
    "collision": Term("collision", lambda c, x, shape: c * x.new_contacts.astype(float),
                      doc="per new contact of this agent"),
    "contact": Term("contact", lambda c, x, shape: c * x.touch, needs="touch", optional=True,
                    doc="per step in contact (within ``contact_gap`` of a wall or robot)"),
    "uncertainty": Term("uncertainty", lambda c, x, shape: c * x.sigma, needs="sigma", optional=True,
                        doc="times the agent's position uncertainty (1-sigma major axis, m), per step"),
}
"""Every reward term by name, in the order a world sums (and reports) them."""
TEAM_TERMS = tuple(name for name, t in TERM_TABLE.items() if t.team)
"""The terms with one value for all agents of a world (one number broadcast)."""


def paid_terms(terms: Sequence[str], weights: RewardConfig) -> tuple[str, ...]:
    """The terms a world pays: ``terms`` (its feature set's), then every :attr:`~Term.optional` term of
    :data:`TERM_TABLE` whose weight in ``weights`` is not 0, in the table's order."""
    return (*terms, *(name for name, t in TERM_TABLE.items() if t.optional and getattr(weights, t.weight) != 0))



def inputs_needed(terms: Sequence[str]) -> frozenset[str]:
    """The optional :class:`RewardInputs` fields the ``terms`` read."""
    return frozenset(TERM_TABLE[t].needs for t in terms if TERM_TABLE[t].needs)


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


def reward_terms(w: RewardConfig, terms: Sequence[str], x: RewardInputs) -> dict[str, np.ndarray]:
    """The weighted values ``{name: (K, N)}`` (or ``(N,)`` for one world's inputs) of the reward ``terms``,
    in that order, from the step's inputs ``x`` (:data:`TERM_TABLE`):

    own_kpoi: ``w.own_kpoi`` per KPOI of the agent's own route that the agent itself visited this step;
    kpoi: ``w.kpoi`` per KPOI newly visited by anyone (team reward, every agent);
    progress: ``w.progress`` per metre of route-length-to-go removed this step (potential-based);
    time: ``w.time`` every step; collision: ``w.collision`` per new contact of this agent;
    contact: ``w.contact`` per step in contact; uncertainty: ``w.uncertainty * sigma`` per step.
    """
    shape = np.shape(x.gained)
    out = {}
    for name in terms:
        term = TERM_TABLE[name]
        out[name] = term.value(getattr(w, term.weight), x, shape)
    return out

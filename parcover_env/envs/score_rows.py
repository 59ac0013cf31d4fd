"""The score phase's per-world state of ``K`` worlds as ``(K, ...)`` blocks (:func:`score_blocks`), so
that one compiled call updates every world in place.

Each world's route tracker, team, metrics and score state make their arrays (:data:`PARTS`) once
and never rebind them: every step, split and record writes into them in place. So for one world
the blocks are simply ``(1, ...)`` views of its own arrays. For ``K > 1`` worlds one
:class:`ScoreGroup` owns a ``(K, ...)`` block per array and the worlds' arrays are views of their
rows (:class:`~parcover_env.envs.world_rows.SharedRows`: an owner is adopted by copying its values in
and handing it the row's views). Each world records the group it was attached to last
(``score_group``, which the env leaves out of its copies and pickles); a group stepped again with
the very worlds and owners it holds has nothing to attach, and a world reset since (new owners) or
attached to another group since is adopted again.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import Any, NamedTuple

import numpy as np

from parcover_env.envs.metrics import SUMS
from parcover_env.envs.team import TEAM_ROWS
from parcover_env.envs.world_rows import SharedRows
from parcover_env.scenarios.progress import STATE

__all__ = ["HELD", "PARTS", "ScoreBlocks", "ScoreGroup", "score_blocks"]

HELD = ("remaining", "wall", "robot")
"""The arrays of a world's ``score_state`` (:class:`~parcover_env.envs.score_phase.ScoreState`)."""

PARTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "progress": ("progress", STATE),
    "team": ("team", TEAM_ROWS),
    "metrics": ("metrics", SUMS),
    "held": ("score_state", HELD),
}
"""Each part of a world the score phase updates: the world's attribute holding the owner, and the
owner's arrays."""


class ScoreBlocks(NamedTuple):
    """The :data:`PARTS` of ``K`` worlds, each a dict ``{array name: (K, ...) block}``."""

    progress: dict[str, np.ndarray]
    team: dict[str, np.ndarray]
    metrics: dict[str, np.ndarray]
    held: dict[str, np.ndarray]


def _owners(worlds: Sequence[Any], attr: str) -> list[Any]:
    return list(map(attrgetter(attr), worlds))


class ScoreGroup:
    """The blocks of ``K > 1`` worlds of one scenario (see the module docstring)."""

    def __init__(self, worlds: Sequence[Any]):
        self.rows = {part: SharedRows(len(worlds), names, getattr(worlds[0], attr))
                     for part, (attr, names) in PARTS.items()}
        self.blocks = ScoreBlocks(**{part: rows.blocks for part, rows in self.rows.items()})

    @property
    def size(self) -> int:
        """The number of worlds ``K``."""
        return self.rows["team"].size

    def fits(self, worlds: Sequence[Any]) -> bool:
        """True if these blocks can hold ``worlds`` (as many, shaped as these)."""
        return all(rows.fits(len(worlds), getattr(worlds[0], PARTS[part][0])) for part, rows in self.rows.items())

    def holds(self, worlds: Sequence[Any]) -> bool:
        """True if ``worlds`` were attached to this group last, in this order, with the owners they hold now."""
        return ([getattr(w, "score_group", None) for w in worlds].count(self) == len(worlds)
                and all(rows.owners == _owners(worlds, PARTS[part][0]) for part, rows in self.rows.items()))

    def attach(self, worlds: Sequence[Any]) -> None:
        """Make world ``k``'s owners those of row ``k`` (:meth:`SharedRows.attach`) and this group theirs."""
        for part, rows in self.rows.items():
            rows.attach(_owners(worlds, PARTS[part][0]))
        for w in worlds:
            w.score_group = self


def score_blocks(worlds: Sequence[Any]) -> ScoreBlocks:
    """The :data:`PARTS` of the ``K`` worlds as ``(K, ...)`` blocks that the worlds' arrays are rows of:
    for one world, views of its own arrays; for more, the blocks of their :class:`ScoreGroup` (the
    group the first world was attached to, if it fits; else a new one), every world attached."""
    if len(worlds) == 1:
        w = worlds[0]
        return ScoreBlocks(**{part: {name: getattr(getattr(w, attr), name)[None] for name in names}
                              for part, (attr, names) in PARTS.items()})
    group = getattr(worlds[0], "score_group", None)
    if group is None or not group.fits(worlds):
        group = ScoreGroup(worlds)
    if not group.holds(worlds):
        group.attach(worlds)
    return group.blocks

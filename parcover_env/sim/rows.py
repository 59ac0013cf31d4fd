"""The per-robot arrays of ``K`` worlds as rows of shared blocks, so that compiled calls work on all
worlds without gathering and scattering them every step.

Each world keeps owning its state: its objects' attributes (an odometry's ``estimate``, a drive's
``wheels``, ...) stay arrays of that world's values. Here they are *views* of row ``k`` of one
``(K, ...)`` block per attribute: a compiled call on the block updates every world in place. A
copy or pickle of a world holds plain arrays of its own (numpy copies a view's values), and an
object that is not attached (a world reset since, an attribute rebound by a per-world method) is
adopted again before the blocks are used: :meth:`SharedRows.attach` copies its values into its row
and gives it that row's views, after detaching the row's previous owner (which gets copies of its
values). So the blocks and the worlds' attributes always hold the same values, whoever wrote them.
The act phase's rows (:func:`act_rows`) are kept on the pose estimators.

The score phase's per-world state of ``K`` worlds as ``(K, ...)`` blocks (:func:`score_blocks`), so
that one compiled call updates every world in place.

Each world's route tracker, team, metrics and score state make their arrays (:data:`PARTS`) once
and never rebind them: every step, split and record writes into them in place. So for one world
the blocks are simply ``(1, ...)`` views of its own arrays. For ``K > 1`` worlds one
:class:`ScoreGroup` owns a ``(K, ...)`` block per array and the worlds' arrays are views of their
rows (:class:`SharedRows`: an owner is adopted by copying its values in
and handing it the row's views). Each world records the group it was attached to last
(``score_group``, which the env leaves out of its copies and pickles); a group stepped again with
the very worlds and owners it holds has nothing to attach, and a world reset since (new owners) or
attached to another group since is adopted again.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter, is_
from typing import Any, NamedTuple

import numpy as np

from parcover_env.mission.metrics import SUMS
from parcover_env.mission.team import TEAM_ROWS
from parcover_env.scenarios.progress import STATE

__all__ = ["SharedRows", "ActRows", "act_rows", "HELD", "PARTS", "ScoreBlocks", "ScoreGroup", "score_blocks"]


class SharedRows:
    """The attributes ``names`` of ``K`` owners as rows of one block per name: ``blocks[name]``
    ``(K, ...)``; owner ``k``'s attribute ``name`` is the view ``blocks[name][k]`` once attached.
    Shapes and dtypes are those of ``template``'s attributes (every owner's must match)."""

    def __init__(self, k: int, names: Sequence[str], template: Any):
        self.names = tuple(names)
        self.blocks: dict[str, np.ndarray] = {}
        self.views: dict[str, list[np.ndarray]] = {}
        for name in self.names:
            value = np.asarray(getattr(template, name))
            block = np.empty((k, *value.shape), dtype=value.dtype)
            self.blocks[name] = block
            self.views[name] = list(block)
        self._get = attrgetter(*self.names) if len(self.names) > 1 else (lambda o, g=attrgetter(self.names[0]): (g(o),))
        self._rows = [tuple(self.views[name][k] for name in self.names) for k in range(k)]
        self.flat = {name: b.reshape(-1, *b.shape[2:]) for name, b in self.blocks.items()}
        """Each block with its first two axes (worlds, robots) as one (a view)."""
        self.owners: list[Any] = [None] * k
        self.memo: tuple | None = None
        """Free for the caller that keeps these rows (:func:`act_rows`: what it found attached last)."""

    def fits(self, k: int, template: Any) -> bool:
        """True if these rows can hold ``k`` owners like ``template`` (the same shapes and dtypes)."""
        if k != len(self.owners):
            return False
        for name in self.names:
            value, view = getattr(template, name), self.views[name][0]
            if not isinstance(value, np.ndarray) or value.shape != view.shape or value.dtype != view.dtype:
                return False
        return True

    @property
    def size(self) -> int:
        """The number of rows ``K``."""
        return len(self.owners)

    def attached(self, k: int, owner: Any) -> bool:
        """True if ``owner`` holds the views of row ``k`` in every attribute."""
        return self.owners[k] is owner and all(map(is_, self._get(owner), self._rows[k]))

    def attach(self, owners: Sequence[Any]) -> None:
        """Make owner ``k`` the owner of row ``k`` for every ``k`` (``len(owners) == K``): an owner not
        attached yet has its values copied into its row and gets the row's views; a previous owner
        of that row that still holds its views gets copies of them instead (it keeps its values)."""
        get, rows, current = self._get, self._rows, self.owners
        for k, owner in enumerate(owners):
            if current[k] is not owner or not all(map(is_, get(owner), rows[k])):
                self._adopt(k, owner)

    def _adopt(self, k: int, owner: Any) -> None:
        old = self.owners[k]
        for name in self.names:
            view = self.views[name][k]
            if old is not None and old is not owner and getattr(old, name) is view:
                setattr(old, name, view.copy())
            value = getattr(owner, name)
            if value is not view:
                value = np.asarray(value)
                if value.shape != view.shape:
                    raise ValueError(f"{type(owner).__name__}.{name}: shape {value.shape}, the rows hold {view.shape}")
                view[...] = value
                setattr(owner, name, view)
        self.owners[k] = owner


class ActRows(NamedTuple):
    """The act phase's per-robot state of ``K`` worlds as shared rows (:func:`act_rows`)."""

    estimators: SharedRows
    """The pose estimators' :data:`ESTIMATOR` arrays."""
    odometry: SharedRows
    """Their wheel odometries' :data:`ODOMETRY` arrays."""
    drives: SharedRows | None
    """The worlds' drives' :data:`DRIVE` arrays (None: no drive, ``drive: instant``)."""
    kinect: SharedRows | None = None
    """The estimators' Kinect systems' :data:`KINECT` arrays (None: no Kinect source, or ``K = 1``)."""


ESTIMATOR = ("velocity", "fix_age")
"""Rows of :class:`~parcover_env.localization.estimator.PoseEstimator`."""
ODOMETRY = ("estimate", "covariance", "travelled", "turned", "factors", "believed_base")
"""Rows of :class:`~parcover_env.sensors.odometry.Odometry`."""
DRIVE = ("wheels", "travel", "speed_change")
"""Rows of :class:`~parcover_env.world.drive.DiffDrive`."""
KINECT = ("next_tick",)
"""Rows of :class:`~parcover_env.localization.kinect.system.KinectSystem` (each Kinect's next frame time)."""


def act_rows(estimators: Sequence[Any], drives: Sequence[Any]) -> ActRows:
    """The shared rows of ``K`` worlds' pose ``estimators`` (of one scenario), their Kinect systems
    (``kinect_system``) and their ``drives`` (``None`` s for ``drive: instant``), every array attached
    (:meth:`SharedRows.attach`). The rows are kept on the estimators (``act_rows``, never copied or
    pickled) and reused while they fit. When every estimator, odometry, Kinect system and drive
    still holds the very objects it held when last attached (the common step), one identity check
    per world replaces the attach passes."""
    first = estimators[0]
    rows = first.act_rows
    if rows is not None and _unchanged(rows, estimators, drives):
        return rows
    if rows is None:  # after world 0's reset: the rows another world holds
        rows = next((e.act_rows for e in estimators if e.act_rows is not None), None)
    k = len(estimators)
    if rows is None or rows.estimators.size != k or not (_holds(rows, first, drives[0])
                                                         or _fits(rows, k, first, drives[0])):
        rows = ActRows(SharedRows(k, ESTIMATOR, first), SharedRows(k, ODOMETRY, first.odometry),
                       None if drives[0] is None else SharedRows(k, DRIVE, drives[0]))
    rows.estimators.attach(estimators)
    rows.odometry.attach([e.odometry for e in estimators])
    if rows.drives is not None:
        rows.drives.attach(drives)
    if k > 1:  # K = 1 updates its one system's ticks in place already
        rows = _with_kinect(rows, k, [e.kinect_system for e in estimators])
    for e in estimators:
        if e.act_rows is not rows:
            e.act_rows = rows
    _remember(rows, estimators, drives)
    return rows


def _getter(rows: ActRows):
    """``f(estimator, drive)``: the objects and arrays of one world that :func:`act_rows` attaches."""
    names = ["act_rows", "kinect_system", *ESTIMATOR, *(f"odometry.{n}" for n in ODOMETRY)]
    if rows.kinect is not None:
        names += [f"kinect_system.{n}" for n in KINECT]
    mine = attrgetter(*names)
    if rows.drives is None:
        return lambda e, d: (*mine(e), d)
    theirs = attrgetter(*DRIVE)
    return lambda e, d: (*mine(e), d, *theirs(d))


def _remember(rows: ActRows, estimators: Sequence[Any], drives: Sequence[Any]) -> None:
    """Keep what every world holds now that ``rows`` are attached (for :func:`_unchanged`)."""
    get = _getter(rows)
    rows.estimators.memo = (rows, get, [get(e, d) for e, d in zip(estimators, drives, strict=True)])


def _unchanged(rows: ActRows, estimators: Sequence[Any], drives: Sequence[Any]) -> bool:
    """True if every world still holds what it held when ``rows`` were last attached to these
    estimators and drives (so all of them are attached)."""
    memo = rows.estimators.memo
    if memo is None or memo[0] is not rows or len(memo[2]) != len(estimators):
        return False
    get = memo[1]
    return all(all(map(is_, get(e, d), held)) for e, d, held in zip(estimators, drives, memo[2], strict=True))


def _with_kinect(rows: ActRows, k: int, systems: Sequence[Any]) -> ActRows:
    """``rows`` with the Kinect ``systems``' rows attached (made when missing or not fitting); without
    rows for them when some world has no Kinect system."""
    if any(s is None for s in systems):
        return rows if rows.kinect is None else ActRows(rows.estimators, rows.odometry, rows.drives)
    if rows.kinect is None or not rows.kinect.fits(k, systems[0]):
        rows = ActRows(rows.estimators, rows.odometry, rows.drives, SharedRows(k, KINECT, systems[0]))
    rows.kinect.attach(systems)
    return rows


def _holds(rows: ActRows, estimator: Any, drive: Any) -> bool:
    """True if ``estimator`` (and its odometry and ``drive``) hold row 0 of ``rows`` (so they fit)."""
    return (rows.estimators.attached(0, estimator) and rows.odometry.attached(0, estimator.odometry)
            and (drive is None if rows.drives is None else rows.drives.attached(0, drive)))


def _fits(rows: ActRows, k: int, estimator: Any, drive: Any) -> bool:
    """True if ``rows`` can hold ``k`` worlds like ``estimator``'s (and its odometry's and ``drive``'s)."""
    return (rows.estimators.fits(k, estimator) and rows.odometry.fits(k, estimator.odometry)
            and (rows.drives is None) == (drive is None) and (drive is None or rows.drives.fits(k, drive)))


HELD = ("remaining", "wall", "robot")
"""The arrays of a world's ``score_state`` (:class:`~parcover_env.sim.score_phase.ScoreState`)."""

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

"""Batching plumbing: the per-world arrays of ``K`` worlds as rows of shared ``(K, ...)`` blocks
(:class:`SharedRows`), so that compiled calls work on all worlds without gathering and scattering
them every step, and a cheap ``np.stack`` (:func:`stack`).

Each world keeps owning its state: its objects' attributes (an odometry's ``estimate``, a drive's
``wheels``, ...) stay arrays of that world's values. Here they are *views* of row ``k`` of one
``(K, ...)`` block per attribute: a compiled call on the block updates every world in place. A
copy or pickle of a world holds plain arrays of its own (numpy copies a view's values), and an
object that is not attached (a world reset since, an attribute rebound by a per-world method) is
adopted again before the blocks are used: :meth:`SharedRows.attach` copies its values into its row
and gives it that row's views, after detaching the row's previous owner (which gets copies of its
values). So the blocks and the worlds' attributes always hold the same values, whoever wrote them.
The pose estimators' rows: :func:`parcover_env.localization.estimator.act_rows`; the score phase's:
:func:`parcover_env.sim.score_phase.score_blocks`.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter, is_
from typing import Any

import numpy as np

__all__ = ["SharedRows", "stack"]


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

    def attach(self, owners: Sequence[object]) -> None:
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


def stack(arrays: Sequence[np.ndarray], copy: bool = False) -> np.ndarray:
    """``np.stack(arrays)``; for one array a ``(1, ...)`` view of it (a copy with ``copy``), which
    skips ``np.stack``'s few microseconds of dispatch. Arrays of one shape (at least 1-d) are joined
    end to end and reshaped, the same values at a third of ``np.stack``'s cost for 64 small ones."""
    if len(arrays) == 1:
        one = np.asarray(arrays[0])[None]
        return one.copy() if copy else one
    shape = np.shape(arrays[0]) if arrays else ()
    if shape and all(type(a) is np.ndarray and a.shape == shape for a in arrays):
        return np.concatenate(arrays).reshape(len(arrays), *shape)
    return np.stack(arrays)

"""The score phase's per-world state of ``K`` worlds as rows of shared blocks
(:class:`~parcover_env.envs.world_rows.SharedRows`, the act phase's pattern), so that one compiled
call updates every world in place: each owner (a world's metrics, route tracker, ...) keeps its
arrays, which are views of its row while it steps with the others; a copy or pickle of it holds
plain arrays, and an owner made or rebound since (a reset) is adopted again before the blocks are used.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import Any

from parcover_env.envs.world_rows import SharedRows
from parcover_env.geometry.row_owner import RowOwner

__all__ = ["shared_rows"]


def shared_rows(owners: Sequence[Any], names: Sequence[str]) -> SharedRows:
    """The rows of the attributes ``names`` of ``K`` ``owners`` of one kind (their shapes and dtypes
    match), every owner attached (:meth:`SharedRows.attach`). The rows are kept on the owners'
    ``rows`` attribute (which their copies and pickles leave None) and reused while they fit. Owners
    of the :class:`~parcover_env.geometry.row_owner.RowOwner` kind forget their rows when an array is
    rebound, so when the rows' owners are these very ``owners``, in order, and each still holds the
    rows, nothing needs attaching (a few C-level calls instead of one check per owner and array)."""
    first, k = owners[0], len(owners)
    rows = first.rows  # after world 0's reset: the rows another world holds
    if (rows is not None and isinstance(first, RowOwner) and rows.names == tuple(names) and rows.owners == owners
            and list(map(_ROWS, owners)).count(rows) == k):
        return rows
    if rows is None:
        rows = next((o.rows for o in owners if o.rows is not None), None)
    if rows is None or rows.size != k or rows.names != tuple(names) or not (rows.attached(0, first)
                                                                             or rows.fits(k, first)):
        rows = SharedRows(k, names, first)
    rows.attach(owners)
    for o in owners:
        if o.rows is not rows:
            o.rows = rows
    return rows


_ROWS = attrgetter("rows")

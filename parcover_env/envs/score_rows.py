"""The score phase's per-world state of ``K`` worlds as rows of shared blocks
(:class:`~parcover_env.envs.world_rows.SharedRows`, the act phase's pattern), so that one compiled
call updates every world in place: each owner (a world's metrics, route tracker, ...) keeps its
arrays, which are views of its row while it steps with the others; a copy or pickle of it holds
plain arrays, and an owner made or rebound since (a reset) is adopted again before the blocks are used.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from parcover_env.envs.world_rows import SharedRows

__all__ = ["shared_rows"]


def shared_rows(owners: Sequence[Any], names: Sequence[str]) -> SharedRows:
    """The rows of the attributes ``names`` of ``K`` ``owners`` of one kind (their shapes and dtypes
    match), every owner attached (:meth:`SharedRows.attach`). The rows are kept on the owners'
    ``rows`` attribute (which their copies and pickles leave None) and reused while they fit."""
    first, k = owners[0], len(owners)
    rows = first.rows  # after world 0's reset: the rows another world holds
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

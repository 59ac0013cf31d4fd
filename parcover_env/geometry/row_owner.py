"""Owners of per-world arrays that may be rows of shared ``(K, ...)`` blocks (the batched stepper's
shared rows, ``parcover_env.envs.score_rows``): :class:`RowOwner` tells in one look whether all of its
arrays are still its row's views."""

from __future__ import annotations

from typing import Any

__all__ = ["RowOwner"]


class RowOwner:
    """A mixin for an object whose array attributes may be views of its row of shared blocks: it
    keeps those rows in :attr:`rows` (an object with the attribute names in ``names``) and forgets
    them (``rows`` becomes None) whenever one of those attributes is rebound to another object, so
    ``owner.rows is rows`` means every one of them is still the view it was given. Rows are set
    after the views (setting the views forgets them); copies and pickles drop them."""

    rows: Any = None

    def __setattr__(self, name: str, value: Any) -> None:
        rows = self.__dict__.get("rows")
        if rows is not None and name in rows.names and value is not self.__dict__.get(name):
            object.__setattr__(self, "rows", None)
        object.__setattr__(self, name, value)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["rows"] = None  # a copy owns plain arrays (numpy copies the views' values)
        return state

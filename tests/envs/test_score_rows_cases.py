"""``shared_rows`` on hand-built owners: the rows hold every owner's values, are reused while they
fit, and an owner whose array changed shape (a rebound attribute) gets new rows of the new shape."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from parcover_env.envs.score_rows import shared_rows


def _owner(values):
    return SimpleNamespace(a=np.array(values, dtype=float), rows=None)


def test_rows_hold_the_owners_values_and_are_reused_while_they_fit():
    owners = [_owner([1.0, 2.0]), _owner([3.0, 4.0])]
    rows = shared_rows(owners, ("a",))
    assert rows.blocks["a"].tolist() == [[1.0, 2.0], [3.0, 4.0]] and all(o.rows is rows for o in owners)
    rows.blocks["a"][1, 0] = 9.0  # the owners' arrays are views of their rows
    assert owners[1].a.tolist() == [9.0, 4.0]
    assert shared_rows(owners, ("a",)) is rows


def test_an_owner_whose_array_changed_shape_gets_new_rows():
    owners = [_owner([1.0, 2.0]), _owner([3.0, 4.0])]
    old = shared_rows(owners, ("a",))
    owners[0].a = np.array([5.0, 6.0, 7.0])  # rebound (a reset with another map): no longer fits
    owners[1].a = np.array([8.0, 9.0, 10.0])
    rows = shared_rows(owners, ("a",))
    assert rows is not old and rows.blocks["a"].tolist() == [[5.0, 6.0, 7.0], [8.0, 9.0, 10.0]]
    rows.blocks["a"][0, 2] = 0.5
    assert owners[0].a.tolist() == [5.0, 6.0, 0.5]

"""Named records for compiled code: every field by name, read-only, read by name in numba."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from parcover_env.geometry.records import record, table

_DT = np.dtype([("range_max", "f8"), ("specular", "?"), ("box", "f8", (2,))])


@njit
def _read(rules):
    r = rules[0]
    return r.range_max * (2.0 if r.specular else 1.0) + r.box[1]


def test_a_record_holds_every_field_by_name_and_numba_reads_them_by_name():
    r = record(_DT, range_max=2.5, specular=True, box=(0.0, 0.25))
    assert r.shape == (1,) and r[0]["range_max"] == 2.5 and not r.flags.writeable
    assert _read(r) == 5.25
    assert _read(record(_DT, range_max=2.5, specular=False, box=(0.0, 0.5))) == 3.0


def test_missing_or_unknown_fields_are_named():
    with pytest.raises(TypeError, match=r"missing \['box'\], unknown \[\]"):
        record(_DT, range_max=1.0, specular=True)
    with pytest.raises(TypeError, match=r"unknown \['range_min'\]"):
        record(_DT, range_max=1.0, specular=True, box=(0, 0), range_min=0.1)


def test_a_table_has_one_row_per_item():
    t = table(_DT, [dict(range_max=float(i), specular=i % 2 == 1, box=(i, -i)) for i in range(3)])
    assert t["range_max"].tolist() == [0.0, 1.0, 2.0] and t["specular"].tolist() == [False, True, False]
    assert t["box"][2].tolist() == [2.0, -2.0] and not t.flags.writeable

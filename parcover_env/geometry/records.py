"""Named records for compiled code: the constants a numba kernel reads travel as a numpy structured
array whose fields have names, so a kernel reads ``rules.range_max``, never ``par[3]``.

Why structured arrays: numba types an array argument in its C dispatcher, so a record of any
number of fields adds about 0.3 us to a kernel call, where a ``NamedTuple`` is typed field by
field in Python: about 1.2-1.4 us for a few fields, more when nested
(``docs/lab/scripts/kernel_records.py``). Kernels take the one-element array :func:`record` builds and
read ``rules[0]``; per-item tables (one row per Kinect, say) come from :func:`table`. Bundles of
arrays are ``NamedTuple`` classes next to the kernels that take them, used where a kernel would
otherwise take more than 12 arguments.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

__all__ = ["record", "table"]


def record(dtype: np.dtype, **fields) -> np.ndarray:
    """A read-only one-element structured array of ``dtype`` with every field given by name."""
    return table(dtype, [fields])


def table(dtype: np.dtype, rows: Iterable[Mapping]) -> np.ndarray:
    """A read-only structured array of ``dtype``, one element per row (every field given by name)."""
    rows = list(rows)
    out = np.zeros(len(rows), dtype=dtype)
    names = set(dtype.names)
    for i, row in enumerate(rows):
        if set(row) != names:
            missing, extra = sorted(names - set(row)), sorted(set(row) - names)
            raise TypeError(f"record fields: missing {missing}, unknown {extra}")
        for name, value in row.items():
            out[i][name] = value
    out.setflags(write=False)
    return out

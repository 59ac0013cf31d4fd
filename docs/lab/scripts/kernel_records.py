"""Cost of passing named records to a compiled (numba) kernel: the figures behind
:mod:`parcover_env.geometry.records` (why constants travel as structured arrays and bundles of
arrays as NamedTuples only where needed).

    PYTHONPATH=. python docs/lab/scripts/kernel_records.py

Prints the wall time per call (minimum over chunks) of a kernel that does nothing with its argument:
numba types every argument at every call, so the difference to a float argument is the price of
the argument's kind.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.records import record
from parcover_env.sensors import sonar_kernels


class _Floats(NamedTuple):
    a: float
    b: float
    c: float
    d: float
    e: float
    f: float
    g: float


class _Arrays(NamedTuple):
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray


@njit(cache=True)
def _nothing(x):
    return 0


def _per_call(x, calls: int = 20000, chunks: int = 7) -> float:
    _nothing(x)
    best = float("inf")
    for _ in range(chunks):
        t0 = time.perf_counter()
        for _ in range(calls):
            _nothing(x)
        best = min(best, (time.perf_counter() - t0) / calls)
    return best * 1e6


def main() -> int:
    rules = record(sonar_kernels.SONAR_RULES, **{name: 1.0 for name in sonar_kernels.SONAR_RULES.names})
    arrays = [np.zeros(8) for _ in range(4)]
    cases = {
        "float": 1.0,
        "array (8,)": np.zeros(8),
        f"record (SONAR_RULES, {len(rules.dtype.names)} fields)": rules,
        "tuple of 4 arrays": tuple(arrays),
        "NamedTuple of 4 arrays": _Arrays(*arrays),
        "NamedTuple of 7 floats": _Floats(*(float(i) for i in range(7))),
        "NamedTuple of 2 NamedTuples": (_Arrays(*arrays), _Floats(*(float(i) for i in range(7)))),
    }
    base = _per_call(1.0)
    for name, value in cases.items():
        t = _per_call(value)
        print(f"{name:34s} {t:6.2f} us per call ({t - base:+.2f} us vs a float)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

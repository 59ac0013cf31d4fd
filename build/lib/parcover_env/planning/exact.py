"""Exact PPCP for small instances on the metric closure ``D`` ((n+1) x (n+1), row/col 0 = start).

1. Held–Karp over subsets for open paths from the start: ``H[U, j]`` = cheapest path leaving the
   start, visiting exactly the KPOIs of ``U`` and ending at ``j``; ``best[U] = min_j H[U, j]``.
   On a metric closure ``best`` is monotone (dropping a KPOI never costs more), so the family of
   subsets feasible under a deadline is closed under taking subsets and a cover is a partition.
2. Minimum r under a deadline: grow the sets coverable by k feasible subsets (only maximal ones
   matter) until the full set is reached.
3. Min–max c_p for a given r: bisection over the sorted distinct values of ``best``.

Cost: O(2^n n^2) for step 1; n <= 12 takes well under a second (see ``benchmarks/planner.py``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["held_karp", "exact_min_robots", "exact_minmax", "route_cost", "MAX_EXACT_KPOIS"]

MAX_EXACT_KPOIS = 14


def _check_matrix(D) -> np.ndarray:
    D = np.asarray(D, dtype=float)
    if D.ndim != 2 or D.shape[0] != D.shape[1] or D.shape[0] < 2:
        raise ValueError(f"distance matrix must be square (n+1, n+1) with n >= 1, got shape {D.shape}")
    n = D.shape[0] - 1
    if n > MAX_EXACT_KPOIS:
        raise ValueError(f"exact solver handles at most {MAX_EXACT_KPOIS} KPOIs, got {n}")
    if not np.all(np.isfinite(D)) or np.any(D < 0):
        raise ValueError("distance matrix must be finite and >= 0 (is every KPOI reachable?)")
    return D


def route_cost(D, route) -> float:
    """Cost of the open path start -> route[0] -> ... (KPOI indices 0-based; row 0 = start)."""
    D = np.asarray(D, dtype=float)
    idx = [0] + [int(k) + 1 for k in route]
    return float(sum(D[a, b] for a, b in zip(idx[:-1], idx[1:], strict=False)))


def held_karp(D) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``best (2^n,)``, ``H (2^n, n)`` and predecessor ``P (2^n, n)`` (-1 = from the start)."""
    D = _check_matrix(D)
    n = D.shape[0] - 1
    size = 1 << n
    H = np.full((size, n), np.inf)
    P = np.full((size, n), -1, dtype=np.int64)
    bits = 1 << np.arange(n)
    H[bits, np.arange(n)] = D[0, 1:]
    masks = np.arange(size)
    pop = np.zeros(size, dtype=np.int64)
    for k in range(n):
        pop += (masks >> k) & 1
    Dk = D[1:, 1:]
    for p in range(2, n + 1):
        layer = masks[pop == p]
        for k in range(n):
            U = layer[(layer >> k) & 1 == 1]
            prev = U ^ (1 << k)
            vals = H[prev] + Dk[:, k][None, :]
            j = np.argmin(vals, axis=1)
            H[U, k] = vals[np.arange(len(U)), j]
            P[U, k] = j
    best = H.min(axis=1)
    best[0] = 0.0
    return best, H, P


def _order(H: np.ndarray, P: np.ndarray, U: int) -> list[int]:
    """Optimal visiting order of subset ``U`` from the Held–Karp tables."""
    if U == 0:
        return []
    j = int(np.argmin(H[U]))
    out = []
    while j >= 0:
        out.append(j)
        U2 = U ^ (1 << j)
        j = int(P[U, j]) if U2 else -1
        U = U2
    return out[::-1]


def _maximal(feasible: np.ndarray, n: int) -> np.ndarray:
    masks = np.arange(len(feasible))
    is_max = feasible.copy()
    for k in range(n):
        sup = masks | (1 << k)
        is_max &= ~(feasible[sup] & (sup != masks))
    return masks[is_max]


def _min_cover(feasible: np.ndarray, n: int, limit: int) -> list[int] | None:
    """Fewest feasible subsets (<= ``limit``) covering all n KPOIs, as a list of masks, or None."""
    full = (1 << n) - 1
    fmax = _maximal(feasible, n)
    if len(fmax) == 0:
        return None
    frontier = fmax.copy()
    history = [(frontier, None, None)]
    for k in range(1, limit + 1):
        if np.any(frontier == full):
            sets, cur = [], full
            for step in range(k - 1, -1, -1):
                front, prev_idx, used = history[step]
                idx = int(np.flatnonzero(front == cur)[0])
                if step == 0:
                    sets.append(cur)
                else:
                    sets.append(int(used[idx]))
                    cur = int(history[step - 1][0][prev_idx[idx]])
            return sets
        if k == limit:
            break
        union = (frontier[:, None] | fmax[None, :]).ravel()
        new, first = np.unique(union, return_index=True)
        prev_idx = first // len(fmax)
        used = fmax[first % len(fmax)]
        frontier = new
        history.append((frontier, prev_idx, used))
    return None


def _routes_from_sets(sets: list[int], H, P, n: int) -> list[list[int]]:
    taken = 0
    routes = []
    for S in sets:
        S &= ~taken  # a cover -> a partition (subsets of feasible sets stay feasible)
        taken |= S
        if S:
            routes.append(_order(H, P, S))
    return routes


def exact_min_robots(D, deadline: float, tables=None) -> tuple[int, list[list[int]]]:
    """Minimum number of open paths from the start, each of cost <= ``deadline``, covering all
    KPOIs; returns ``(r, routes)`` with routes as lists of 0-based KPOI indices."""
    D = _check_matrix(D)
    n = D.shape[0] - 1
    best, H, P = tables if tables is not None else held_karp(D)
    feasible = best <= deadline + 1e-9
    sets = _min_cover(feasible, n, n)
    if sets is None:
        raise ValueError(f"deadline {deadline:.3f} is below the distance to the furthest KPOI")
    routes = _routes_from_sets(sets, H, P, n)
    return len(routes), routes


def exact_minmax(D, r: int, tables=None) -> tuple[float, list[list[int]]]:
    """Minimum over partitions into at most ``r`` routes of the maximum route cost: ``(c_p, routes)``."""
    D = _check_matrix(D)
    n = D.shape[0] - 1
    if int(r) < 1:
        raise ValueError(f"r must be >= 1, got {r}")
    r = min(int(r), n)
    best, H, P = tables if tables is not None else held_karp(D)
    values = np.unique(best[1:])
    lo, hi = int(np.searchsorted(values, D[0, 1:].max() - 1e-9)), len(values) - 1
    found = _min_cover(best <= values[hi] + 1e-9, n, r)
    while lo < hi:
        mid = (lo + hi) // 2
        sets = _min_cover(best <= values[mid] + 1e-9, n, r)
        if sets is None:
            lo = mid + 1
        else:
            hi, found = mid, sets
    if found is None or lo != hi:  # pragma: no cover - values[hi] always admits one route
        raise RuntimeError("min-max search failed")
    found = _min_cover(best <= values[lo] + 1e-9, n, r)
    routes = _routes_from_sets(found, H, P, n)
    return max(route_cost(D, rt) for rt in routes), routes

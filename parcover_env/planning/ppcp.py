"""Parallel Path Coverage Problem (Min et al. §II): minimum robots r at the minimum coverage cost.

Interpretation of the paper (its reference [6] is not public; see ``ALGORITHMS.md``):

* ``c_max`` = roadmap shortest-path distance from the start to the furthest KPOI: no team can
  finish faster, so it is the lower bound and the target cost.
* Stage 1 (Fig. 6c): prune the shortest-path tree from the start to the union of the paths to the
  KPOIs. Each leaf (a KPOI with no KPOI below it) gets one robot driving start -> leaf; a KPOI on
  the way is covered in passing and credited to the robot leading the group there. ``c_p = c_max``.
* Stage 2 (Fig. 1b, tours): merge routes into open paths start -> a1 -> ... -> am while the cost
  stays <= c_max, reducing r at unchanged c_p ("minimum vehicle routing with a deadline", NP-hard).
  Heuristic: Clarke–Wright savings for open paths on the KPOI metric closure — repeatedly merge
  the pair of routes (either may go first, either may be reversed) with the largest saving
  ``cost(A) + cost(B) - cost(A+B)`` among merges whose cost stays <= the deadline.
* Given r (min–max variant): bisection on the deadline T >= c_max with the same merging, keeping
  the smallest T whose merge needs <= r routes; spare robots split the costliest routes, and robots
  left without KPOIs stay at the start.
* ``method="auto"`` also runs the exact solver (``exact.py``) when there are <= ``EXACT_AUTO_MAX``
  distinct KPOI nodes and keeps it only if it is strictly better (heuristic routes follow the tree
  and make nicer formations at equal r / c_p).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np
from scipy.sparse import csgraph

from parcover_env.planning import exact as exact_mod
from parcover_env.planning.plan import Plan

__all__ = ["Closure", "metric_closure", "stage1_routes", "merge_routes", "split_routes", "minmax_routes",
           "routes_cost", "solve_ppcp", "EXACT_AUTO_MAX"]

EXACT_AUTO_MAX = 10
_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class Closure:
    """Shortest paths among the start and the KPOIs on a roadmap graph."""

    D: np.ndarray
    """(n+1, n+1) distances; index 0 = start, i+1 = KPOI i."""
    nodelist: list
    index: dict
    source_row: dict
    """Roadmap node -> row of ``pred`` (the start and every KPOI node are sources)."""
    pred: np.ndarray
    start: object
    kpoi_nodes: tuple

    def node_path(self, a, b) -> list:
        """Roadmap nodes of a shortest path a -> b (``a`` must be the start or a KPOI node)."""
        row = self.pred[self.source_row[a]]
        ia, cur = self.index[a], self.index[b]
        out = [cur]
        while cur != ia:
            cur = int(row[cur])
            if cur < 0:
                raise ValueError(f"no path from {a} to {b} on the roadmap")
            out.append(cur)
        return [self.nodelist[i] for i in out[::-1]]

    def tree_parent(self, node):
        """Parent of ``node`` in the shortest-path tree from the start (None at the start)."""
        p = int(self.pred[self.source_row[self.start], self.index[node]])
        return None if p < 0 else self.nodelist[p]


def metric_closure(graph: nx.Graph, start, kpoi_nodes: Sequence) -> Closure:
    """Dijkstra from the start and every KPOI node (scipy) on edge attribute ``weight``."""
    if start not in graph:
        raise ValueError(f"start node {start!r} is not in the roadmap graph")
    for i, k in enumerate(kpoi_nodes):
        if k not in graph:
            raise ValueError(f"kpois[{i}]: node {k!r} is not in the roadmap graph")
    nodelist = list(graph.nodes)
    index = {n: i for i, n in enumerate(nodelist)}
    for u, v, w in graph.edges(data="weight"):
        if w is None or not np.isfinite(w) or w < 0:
            raise ValueError(f"edge ({u}, {v}) needs a finite weight >= 0, got {w}")
    A = nx.to_scipy_sparse_array(graph, nodelist=nodelist, weight="weight", format="csr")
    sources = list(dict.fromkeys([start, *kpoi_nodes]))
    dist, pred = csgraph.dijkstra(A, directed=False, indices=[index[s] for s in sources],
                                  return_predecessors=True)
    row = {s: i for i, s in enumerate(sources)}
    terms = [start, *kpoi_nodes]
    D = dist[[row[t] for t in terms]][:, [index[t] for t in terms]]
    D = np.minimum(D, D.T)
    bad = np.flatnonzero(~np.isfinite(D[0, 1:]))
    if len(bad):
        raise ValueError(f"kpois[{int(bad[0])}] is not connected to the start on the roadmap")
    return Closure(D=D, nodelist=nodelist, index=index, source_row=row, pred=pred, start=start,
                   kpoi_nodes=tuple(kpoi_nodes))


def routes_cost(D: np.ndarray, routes) -> np.ndarray:
    """Cost of each open route start -> route[0] -> ... (0-based KPOI indices)."""
    return np.array([exact_mod.route_cost(D, r) if len(r) else 0.0 for r in routes], dtype=float)


def stage1_routes(closure: Closure) -> list[list[int]]:
    """One route per leaf of the pruned shortest-path tree, in depth-first order; each route lists
    the not-yet-credited KPOIs on the tree path to its leaf (interior ones covered in passing)."""
    start, kpoi_nodes = closure.start, closure.kpoi_nodes
    at_node: dict = {}
    for i, k in enumerate(kpoi_nodes):
        at_node.setdefault(k, []).append(i)
    children: dict = {}
    has_below: set = set()
    for k in at_node:
        cur = k
        while cur != start:
            par = closure.tree_parent(cur)
            children.setdefault(par, set()).add(cur)
            if par in has_below:
                break
            has_below.add(par)
            cur = par
    routes, credited = [], set()
    stack = [(start, [start])]
    while stack:  # depth-first; children visited in ascending node order
        node, chain = stack.pop()
        kids = sorted(children.get(node, ()), key=repr, reverse=True)
        if node in at_node and node not in has_below:
            route = []
            for c in chain:
                for i in at_node.get(c, ()):
                    if i not in credited:
                        credited.add(i)
                        route.append(i)
            routes.append(route)
        for kid in kids:
            stack.append((kid, chain + [kid]))
    return routes


def _pair_costs(D, f1, l1, c1, f2, l2, c2):
    """Best merged cost of route sets 1 x 2 (broadcast) over who goes first and both orientations.
    ``f``/``l`` are closure indices of the route ends, ``c`` the internal costs. Returns (cost, code)."""
    d0 = D[0]
    opts = []
    for first, second in (((f1, l1), (f2, l2)), ((f2, l2), (f1, l1))):
        (fa, la), (fb, lb) = first, second
        for sa, ea in ((fa, la), (la, fa)):
            for sb in (fb, lb):
                opts.append(d0[sa] + D[ea, sb])
    stack = np.stack(np.broadcast_arrays(*opts))
    code = np.argmin(stack, axis=0)
    return np.take_along_axis(stack, code[None], 0)[0] + c1 + c2, code


def _apply_code(a: list[int], b: list[int], code: int) -> list[int]:
    first, second = (a, b) if code < 4 else (b, a)
    ra, rb = (code % 4) // 2, code % 2
    return (first[::-1] if ra else first) + (second[::-1] if rb else second)


def merge_routes(D: np.ndarray, routes, deadline: float) -> list[list[int]]:
    """Savings merging of open routes keeping every merged route's cost <= ``deadline``."""
    routes = [list(r) for r in routes if len(r)]
    R = len(routes)
    if R <= 1:
        return routes
    D = np.asarray(D, dtype=float)
    first = np.array([r[0] + 1 for r in routes])
    last = np.array([r[-1] + 1 for r in routes])
    inner = np.array([exact_mod.route_cost(D, r) - D[0, r[0] + 1] for r in routes])
    cost = D[0, first] + inner
    C, code = _pair_costs(D, first[:, None], last[:, None], inner[:, None],
                          first[None], last[None], inner[None])
    alive = np.ones(R, bool)
    saving = np.where(deadline + _EPS >= C, cost[:, None] + cost[None] - C, -np.inf)
    np.fill_diagonal(saving, -np.inf)
    while True:
        flat = int(np.argmax(saving))
        i, j = divmod(flat, R)
        if not np.isfinite(saving[i, j]):
            break
        routes[i] = _apply_code(routes[i], routes[j], int(code[i, j]))
        routes[j] = []
        alive[j] = False
        saving[j, :] = saving[:, j] = -np.inf
        first[i], last[i] = routes[i][0] + 1, routes[i][-1] + 1
        inner[i] = exact_mod.route_cost(D, routes[i]) - D[0, first[i]]
        cost[i] = D[0, first[i]] + inner[i]
        ci, cdi = _pair_costs(D, first[i], last[i], inner[i], first, last, inner)
        C[i, :], code[i, :] = ci, cdi
        C[:, i], code[:, i] = ci, np.where(cdi < 4, cdi + 4, cdi - 4)
        row = np.where((ci <= deadline + _EPS) & alive, cost[i] + cost - ci, -np.inf)
        row[i] = -np.inf
        saving[i, :] = saving[:, i] = row
    return [r for r in routes if r]


def split_routes(D: np.ndarray, routes, r: int) -> list[list[int]]:
    """Split the costliest splittable routes until there are ``r`` (or none can be split)."""
    routes = [list(x) for x in routes]
    while len(routes) < r:
        costs = routes_cost(D, routes)
        order = np.argsort(-costs)
        for idx in order:
            rt = routes[idx]
            if len(rt) >= 2:
                parts = [max(exact_mod.route_cost(D, rt[:k]), exact_mod.route_cost(D, rt[k:]))
                         for k in range(1, len(rt))]
                k = int(np.argmin(parts)) + 1
                routes[idx:idx + 1] = [rt[:k], rt[k:]]
                break
        else:
            break
    return routes


def minmax_routes(D: np.ndarray, base_routes, r: int, c_max: float, iters: int = 40) -> list[list[int]]:
    """Min–max heuristic for a given r: bisection on the deadline of :func:`merge_routes`."""
    best = merge_routes(D, base_routes, c_max)
    if len(best) > r:
        best = merge_routes(D, base_routes, np.inf)
        lo, hi = c_max, float(routes_cost(D, best).max())
        for _ in range(iters):
            if hi - lo <= 1e-4 * max(1.0, c_max):
                break
            mid = 0.5 * (lo + hi)
            cand = merge_routes(D, base_routes, mid)
            if len(cand) <= r:
                best, hi = cand, float(routes_cost(D, cand).max())
            else:
                lo = mid
    return split_routes(D, best, r)


def _distinct_problem(closure: Closure):
    """Closure restricted to distinct KPOI nodes (KPOIs sharing a node are one target)."""
    groups: dict = {}
    for i, k in enumerate(closure.kpoi_nodes):
        groups.setdefault(k, []).append(i)
    reps = [g[0] for g in groups.values()]
    idx = [0] + [i + 1 for i in reps]
    return closure.D[np.ix_(idx, idx)], list(groups.values())


def solve_ppcp(graph: nx.Graph, start, kpois: Sequence, n_robots: int | None = None, *,
               method: str = "auto", merge_tours: bool = True, start_point=None, tp_merge_tol: float = 0.0,
               simplify: Callable[[np.ndarray], np.ndarray] | None = None) -> Plan:
    """Solve the PPCP on a roadmap ``graph`` (nodes with ``pos``, edges with ``weight`` and optional
    ``path`` polylines) from node ``start`` to KPOI nodes ``kpois`` (KPOI i sits at node kpois[i]).

    ``n_robots=None``: fewest robots at ``c_p = c_max`` (stage 1, then stage 2 if ``merge_tours``).
    ``n_robots=r``: min–max routes for exactly r robots. ``method``: ``heuristic``, ``exact``
    (<= 12 distinct KPOI nodes) or ``auto``. ``simplify`` smooths polylines between plan-tree nodes.
    ``tp_merge_tol`` (m): TPs reached within this distance after another merge into it (one multi-way TP).
    """
    from parcover_env.planning.plan_builder import build_plan

    if method not in ("auto", "heuristic", "exact"):
        raise ValueError(f"method must be 'auto', 'heuristic' or 'exact', got {method!r}")
    if len(kpois) == 0:
        raise ValueError("at least one KPOI is required")
    if n_robots is not None and (int(n_robots) != n_robots or n_robots < 1):
        raise ValueError(f"n_robots must be a positive integer or None, got {n_robots!r}")
    closure = metric_closure(graph, start, kpois)
    D = closure.D
    far = int(np.argmax(D[0, 1:]))
    c_max = float(D[0, far + 1])
    base = stage1_routes(closure)
    if n_robots is None:
        routes = merge_routes(D, base, c_max) if merge_tours else base
        label = "tours" if merge_tours and len(routes) < len(base) else "paths"
    else:
        routes = minmax_routes(D, base, int(n_robots), c_max)
        label = "minmax"
    Dd, groups = _distinct_problem(closure)
    n_distinct = len(groups)
    if method == "exact" and n_distinct > exact_mod.MAX_EXACT_KPOIS:
        raise ValueError(f"method='exact' handles at most {exact_mod.MAX_EXACT_KPOIS} distinct KPOI "
                         f"positions, got {n_distinct}")
    if method == "exact" or (method == "auto" and n_distinct <= EXACT_AUTO_MAX):
        tables = exact_mod.held_karp(Dd)
        if n_robots is None:
            _, ex = exact_mod.exact_min_robots(Dd, c_max, tables)
        else:
            _, ex = exact_mod.exact_minmax(Dd, int(n_robots), tables)
        ex = split_routes(Dd, ex, int(n_robots)) if n_robots is not None else ex
        ex = [[i for j in rt for i in groups[j]] for rt in ex]
        h_key = (len(routes), float(routes_cost(D, routes).max()))
        e_key = (len(ex), float(routes_cost(D, ex).max()))
        better = e_key[0] < h_key[0] if n_robots is None else e_key[1] < h_key[1] - 1e-9
        if method == "exact" or better:
            routes, label = ex, "exact" if n_robots is None else "exact_minmax"
    if n_robots is not None:
        routes = routes + [[] for _ in range(int(n_robots) - len(routes))]
    return build_plan(graph, closure, routes, c_max=c_max, furthest=far, method=label, n_leaves=len(base),
                      start_point=start_point, simplify=simplify, tp_merge_tol=tp_merge_tol)

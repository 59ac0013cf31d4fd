"""Hand-made roadmap graphs for planner tests."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np

from parcover_env.planning.exact import route_cost


def graph_from(pos: dict, edges: list[tuple]) -> nx.Graph:
    """Graph with node positions; edge weight = Euclidean length unless given as a third item."""
    g = nx.Graph()
    for n, p in pos.items():
        g.add_node(n, pos=tuple(map(float, p)))
    for e in edges:
        u, v = e[:2]
        w = e[2] if len(e) > 2 else float(np.hypot(*(np.subtract(pos[u], pos[v]))))
        g.add_edge(u, v, weight=float(w))
    return g


def random_graph(rng: np.random.Generator, n_nodes: int, extra: int) -> nx.Graph:
    """Random connected geometric graph: a random spanning tree plus ``extra`` chords."""
    pts = rng.uniform(0, 10, size=(n_nodes, 2))
    pos = {i: pts[i] for i in range(n_nodes)}
    edges = [(i, int(rng.integers(0, i))) for i in range(1, n_nodes)]
    for _ in range(extra):
        a, b = rng.choice(n_nodes, size=2, replace=False)
        edges.append((int(a), int(b)))
    return graph_from(pos, edges)


def set_partitions(items: list):
    """All partitions of ``items`` into non-empty blocks."""
    if not items:
        yield []
        return
    head, rest = items[0], items[1:]
    for part in set_partitions(rest):
        for i in range(len(part)):
            yield part[:i] + [[head] + part[i]] + part[i + 1:]
        yield [[head]] + part


def best_order_cost(D: np.ndarray, block: list[int]) -> float:
    return min(route_cost(D, list(p)) for p in itertools.permutations(block))


def brute_min_robots(D: np.ndarray, deadline: float) -> int:
    n = D.shape[0] - 1
    return min(len(p) for p in set_partitions(list(range(n)))
               if all(best_order_cost(D, b) <= deadline + 1e-9 for b in p))


def brute_minmax(D: np.ndarray, r: int) -> float:
    n = D.shape[0] - 1
    return min(max(best_order_cost(D, b) for b in p) for p in set_partitions(list(range(n))) if len(p) <= r)

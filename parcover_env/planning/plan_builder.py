"""Turn routes (ordered KPOI lists) into a :class:`Plan`: walks on the roadmap, the prefix tree of
walks (robots travel together while their walks agree), robot numbering, TPs and polylines.

A turning position is a node of the prefix tree where the set of robots travelling together
splits (>= 2 children, or robots ending there while others continue). Walks from the start to a
KPOI below another follow the start's shortest-path tree, so stage-1 routes share their prefixes
exactly (ties in the roadmap metric cannot make two robots of one group part and re-join).
"""

from __future__ import annotations

from collections.abc import Callable

import networkx as nx
import numpy as np

from parcover_env.planning import exact as exact_mod
from parcover_env.planning.plan import Branch, Plan, PlanTree, RobotPlan, TurningPoint
from parcover_env.planning.roadmap import edge_polyline

__all__ = ["build_plan", "polyline_length", "merge_turning_points"]


def polyline_length(points: np.ndarray) -> float:
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) if len(pts) > 1 else 0.0


def _segment(closure, a, b) -> list:
    """Roadmap nodes a -> b: the start's tree path when ``a`` is a tree ancestor of ``b``."""
    if a == b:
        return [a]
    chain, cur = [b], b
    while cur != a and cur != closure.start:
        cur = closure.tree_parent(cur)
        if cur is None:
            break
        chain.append(cur)
    if chain[-1] == a:
        return chain[::-1]
    return closure.node_path(a, b)


def _join(parts: list[np.ndarray]) -> np.ndarray:
    out = [parts[0]]
    for p in parts[1:]:
        out.append(p[1:] if np.allclose(p[0], out[-1][-1]) else p)
    return np.concatenate(out, axis=0)


def merge_turning_points(tps: list[TurningPoint], tol: float) -> list[TurningPoint]:
    """Merge every TP reached within ``tol`` metres (along the paths) after the TP whose branch leads to
    it into that TP: one multi-way TP instead of a cascade of splits a few centimetres apart (a
    roadmap forks at several nearby points where corridors meet). The merged TP keeps the first
    TP's position; its branches are the later TP's branches in place of the branch leading there."""
    if tol <= 0:
        return list(tps)
    by_group = {tp.robots: tp for tp in tps}
    out = []
    absorbed: set[tuple[int, int]] = set()
    for tp in sorted(tps, key=lambda t: t.distance):
        if tp.robots in absorbed:
            continue
        branches, changed = list(tp.branches), True
        while changed:
            changed = False
            for k, b in enumerate(branches):
                nxt = by_group.get(b.robots)
                if (nxt is not None and nxt is not tp and b.robots not in absorbed
                        and nxt.distance - tp.distance <= tol + 1e-9):
                    branches[k:k + 1] = list(nxt.branches)
                    absorbed.add(b.robots)
                    changed = True
                    break
        out.append(TurningPoint(node=tp.node, position=tp.position, distance=tp.distance, robots=tp.robots,
                                branches=tuple(branches)))
    return sorted(out, key=lambda t: t.node)


def build_plan(graph: nx.Graph, closure, routes: list[list[int]], *, c_max: float, furthest: int, method: str,
               n_leaves: int = 0, start_point=None, tp_merge_tol: float = 0.0,
               simplify: Callable[[np.ndarray], np.ndarray] | None = None) -> Plan:
    """Assemble the plan for ``routes`` (one per robot; an empty route = a robot idle at the start)."""
    start = closure.start
    walks, visits = [], []
    for rt in routes:
        walk, vis = [start], []
        for k in rt:
            node = closure.kpoi_nodes[k]
            walk.extend(_segment(closure, walk[-1], node)[1:])
            vis.append((len(walk) - 1, k))
        walks.append(walk)
        visits.append(vis)
    # Prefix tree (trie) of the walks.
    t_parent, t_node, t_kids, t_end = [-1], [start], [{}], [[]]
    route_trie = []
    for r, walk in enumerate(walks):
        cur, ids = 0, [0]
        for node in walk[1:]:
            nxt = t_kids[cur].get(node)
            if nxt is None:
                nxt = len(t_parent)
                t_parent.append(cur)
                t_node.append(node)
                t_kids.append({})
                t_end.append([])
                t_kids[cur][node] = nxt
            cur = nxt
            ids.append(cur)
        t_end[cur].append(r)
        route_trie.append(ids)
    T = len(t_parent)
    visit_at: dict[int, list[tuple[int, int]]] = {}
    for r, vis in enumerate(visits):
        for wi, k in vis:
            visit_at.setdefault(route_trie[r][wi], []).append((r, k))
    # Depth-first robot numbering: children first, the one leading to the costliest route first (so
    # the robots with the furthest to go head the column), then robots ending here.
    route_cost = []
    for rt in routes:
        idx = [0] + [k + 1 for k in rt]
        route_cost.append(float(sum(closure.D[a, b] for a, b in zip(idx, idx[1:]))))
    reach = [0.0] * T
    for r, ids in enumerate(route_trie):
        for t in ids:
            reach[t] = max(reach[t], route_cost[r])
    lo, hi = [0] * T, [0] * T
    robot_of = [0] * len(routes)
    counter = 0
    stack: list[tuple[str, int]] = [("enter", 0)]
    while stack:
        op, t = stack.pop()
        if op == "enter":
            lo[t] = counter
            kids = sorted(t_kids[t].values(), key=lambda c: -reach[c])  # stable: ties keep route order
            stack += [("exit", t), ("term", t)] + [("enter", c) for c in reversed(kids)]
        elif op == "term":
            for r in t_end[t]:
                robot_of[r] = counter
                counter += 1
        else:
            hi[t] = counter
    is_key = [t == 0 or len(t_kids[t]) + len(t_end[t]) >= 2 or bool(t_end[t]) or t in visit_at
              for t in range(T)]
    # Compressed plan tree over key trie nodes (pre-order), with polylines.
    root_pos = np.asarray(graph.nodes[start]["pos"], dtype=float)
    moved_start = start_point is not None and not np.allclose(start_point, root_pos)
    if start_point is not None:
        root_pos = np.asarray(start_point, dtype=float)
    tree_of = {0: 0}
    positions, parent, edge_paths, dist, kp_at, rmn = [root_pos], [-1], [root_pos[None]], [0.0], [[]], [start]
    stack2 = [(c, 0, [start]) for c in reversed(t_kids[0].values())]
    while stack2:
        t, key_anc, chain = stack2.pop()
        chain = chain + [t_node[t]]
        if is_key[t]:
            parts = [edge_polyline(graph, a, b) for a, b in zip(chain[:-1], chain[1:], strict=False)]
            raw = _join(parts)
            if key_anc == 0 and moved_start:
                raw = np.vstack([root_pos, raw])
            poly = simplify(raw) if simplify is not None else raw
            poly = np.asarray(poly, dtype=float)
            poly.setflags(write=False)
            pi = tree_of[key_anc]
            tree_of[t] = len(parent)
            positions.append(poly[-1])
            parent.append(pi)
            edge_paths.append(poly)
            dist.append(dist[pi] + polyline_length(poly))
            kp_at.append([])
            rmn.append(t_node[t])
            key_anc, chain = t, [t_node[t]]
        for c in reversed(t_kids[t].values()):
            stack2.append((c, key_anc, chain))
    # KPOI credit: the leader of the group passing the visit.
    owned: dict[int, list[tuple[float, int, int]]] = {}
    for t, lst in visit_at.items():
        ti = tree_of[t]
        for order, (_, k) in enumerate(lst):
            owned.setdefault(lo[t], []).append((dist[ti], order, k))
            kp_at[ti].append(k)
    D = closure.D
    robots: list[RobotPlan | None] = [None] * len(routes)
    for r, ids in enumerate(route_trie):
        i = robot_of[r]
        nodes = tuple(tree_of[t] for t in ids if is_key[t])
        path = _join([edge_paths[n] for n in nodes])
        path.setflags(write=False)
        items = sorted(owned.get(i, []))
        robots[i] = RobotPlan(index=i, kpois=tuple(k for _, _, k in items),
                              kpoi_distance=tuple(float(d) for d, _, _ in items), path=path,
                              cost=exact_mod.route_cost(D, routes[r]) if routes[r] else 0.0,
                              length=polyline_length(path), tree_nodes=nodes)
    tps = []
    for t in range(T):
        if len(t_kids[t]) + len(t_end[t]) < 2:
            continue
        ti = tree_of[t]
        branches = []
        for c in t_kids[t].values():
            cc = c
            while not is_key[cc]:
                (cc,) = t_kids[cc].values()
            child = tree_of[cc]
            wp = edge_paths[child][1] if len(edge_paths[child]) > 1 else positions[child]
            branches.append(Branch(next_waypoint=(float(wp[0]), float(wp[1])), robots=(lo[c], hi[c]),
                                   leader=lo[c], child=child))
        for r in t_end[t]:
            i = robot_of[r]
            p = positions[ti]
            branches.append(Branch(next_waypoint=(float(p[0]), float(p[1])), robots=(i, i + 1), leader=i,
                                   child=ti))
        p = positions[ti]
        tps.append(TurningPoint(node=ti, position=(float(p[0]), float(p[1])), distance=float(dist[ti]),
                                robots=(lo[t], hi[t]), branches=tuple(branches)))
    tps = merge_turning_points(tps, tp_merge_tol)
    pos_arr = np.array(positions, dtype=float)
    dist_arr = np.array(dist, dtype=float)
    for a in (pos_arr, dist_arr):
        a.setflags(write=False)
    robot_ranges = [(0, 0)] * len(parent)
    for t, ti in tree_of.items():
        robot_ranges[ti] = (lo[t], hi[t])
    tree = PlanTree(positions=pos_arr, parent=tuple(parent), edge_paths=tuple(edge_paths),
                    robots=tuple(robot_ranges), distance=dist_arr, kpois=tuple(tuple(k) for k in kp_at),
                    roadmap_node=tuple(rmn))
    c_p = max(rp.cost for rp in robots)
    return Plan(c_max=float(c_max), c_p=float(c_p), robots=tuple(robots), tree=tree,
                turning_points=tuple(tps), n_kpois=len(closure.kpoi_nodes), method=method,
                furthest_kpoi=int(furthest), n_leaves=int(n_leaves))

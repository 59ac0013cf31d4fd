"""PPCP planner benchmark: plan time vs number of KPOIs on generated maps, and the heuristic's gap
to the exact solver on random small instances.

    .venv/bin/python benchmarks/planner.py [--sizes 10 50 100 200 500] [--small 50] [--seed 0]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from shapely.geometry import box

from parcover_env.config import MapConfig
from parcover_env.planning.exact import exact_min_robots, exact_minmax, held_karp, route_cost
from parcover_env.planning.ppcp import merge_routes, metric_closure, minmax_routes, solve_ppcp, stage1_routes
from parcover_env.planning.roadmap import build_roadmap, planner_clearance
from parcover_env.planning.scenario_plan import make_simplifier
from parcover_env.world.map_model import MapModel

RADIUS, RES, KPOI_RADIUS = 0.15, 0.05, 0.25
CLEARANCE = planner_clearance(RADIUS, RES)


def random_map(rng: np.random.Generator, size: float, n_obstacles: int) -> MapConfig:
    obstacles = []
    for _ in range(n_obstacles):
        w, h = rng.uniform(0.4, 2.0, size=2)
        x, y = rng.uniform(1.0, size - 1.0 - w), rng.uniform(1.0, size - 1.0 - h)
        obstacles.append(((x, y), (x + w, y), (x + w, y + h), (x, y + h)))
    return MapConfig(size=(size, size), obstacles=tuple(obstacles))


def random_instance(rng, n_kpois: int):
    size = float(np.clip(np.sqrt(n_kpois) * 2.0, 8.0, 40.0))
    cfg = random_map(rng, size, int(size * size / 12))
    model = MapModel.from_config(cfg)
    region = model.free.buffer(-(RADIUS + 0.1))
    start_region = max(getattr(region, "geoms", [region]), key=lambda g: g.area)
    pts = []
    while len(pts) < n_kpois + 1:
        cand = rng.uniform(0, size, size=(4 * n_kpois + 8, 2))
        ok = [p for p in cand if start_region.contains(box(*p, *p).centroid)]
        pts.extend(ok)
    pts = np.array(pts[: n_kpois + 1])
    return model, pts[0], pts[1:]


def bench_sizes(sizes, seed):
    print("n_kpois  map_m  roadmap_s  solve_s  total_s  nodes  r  leaves  c_max_m")
    for n in sizes:
        rng = np.random.default_rng(seed + n)
        model, start, kpois = random_instance(rng, n)
        t0 = time.perf_counter()
        rm = build_roadmap(model, start, kpois, CLEARANCE, RES, "medial_axis", KPOI_RADIUS)
        t1 = time.perf_counter()
        plan = solve_ppcp(rm.graph, rm.start, rm.kpois, method="heuristic", start_point=start,
                          simplify=make_simplifier(model, RADIUS, RES))
        t2 = time.perf_counter()
        print(f"{n:7d}  {model.bounds[2]:5.1f}  {t1 - t0:9.3f}  {t2 - t1:7.3f}  {t2 - t0:7.3f}  "
              f"{rm.graph.number_of_nodes():5d}  {plan.r:2d}  {plan.n_leaves:6d}  {plan.c_max:7.2f}")


def bench_gap(n_small, seed):
    rng = np.random.default_rng(seed)
    r_gap, r_equal, mm_gap, t_exact = [], 0, [], []
    for _ in range(n_small):
        n = int(rng.integers(6, 13))
        model, start, kpois = random_instance(rng, n)
        rm = build_roadmap(model, start, kpois, CLEARANCE, RES, "medial_axis", KPOI_RADIUS)
        cl = metric_closure(rm.graph, rm.start, rm.kpois)
        D, c_max = cl.D, float(cl.D[0, 1:].max())
        base = stage1_routes(cl)
        heur = merge_routes(D, base, c_max)
        t = time.perf_counter()
        tables = held_karp(D)
        r_ex, _ = exact_min_robots(D, c_max, tables)
        t_exact.append((n, time.perf_counter() - t))
        r_gap.append(len(heur) - r_ex)
        r_equal += len(heur) == r_ex
        r_fix = max(1, r_ex - 1)
        c_ex, _ = exact_minmax(D, r_fix, tables)
        c_h = max(route_cost(D, rt) for rt in minmax_routes(D, base, r_fix, c_max) if rt)
        mm_gap.append(c_h / c_ex - 1.0)
    r_gap = np.array(r_gap)
    print(f"\nheuristic vs exact on {n_small} random instances (6..12 KPOIs):")
    print(f"  min r: equal in {r_equal}/{n_small}; extra robots mean {r_gap.mean():.2f}, max {r_gap.max()}")
    print(f"  min-max c_p (r = r_exact - 1): mean gap {100 * np.mean(mm_gap):.1f}%, "
          f"max {100 * np.max(mm_gap):.1f}%")
    t12 = [t for n, t in t_exact if n == 12]
    print(f"  exact min-r time: max {max(t for _, t in t_exact):.3f} s; 12 KPOIs max "
          f"{max(t12) if t12 else float('nan'):.3f} s")
    D = np.linalg.norm(np.random.default_rng(1).uniform(0, 10, (13, 2))[:, None] - np.random.default_rng(1)
                       .uniform(0, 10, (13, 2))[None], axis=-1)
    t = time.perf_counter()
    tables = held_karp(D)
    exact_min_robots(D, D[0, 1:].max(), tables)
    exact_minmax(D, 3, tables)
    print(f"  12 KPOIs, Held-Karp + min r + min-max(r=3): {time.perf_counter() - t:.3f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 50, 100, 200, 500])
    ap.add_argument("--small", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    bench_sizes(args.sizes, args.seed)
    bench_gap(args.small, args.seed)


if __name__ == "__main__":
    main()

"""How far the default (realistic) sonar ring departs from the ideal ray model on a scenario's map.

Random team poses in free space (the scenario's team size, robots apart by two radii); for every
beam, the realistic ring's reading (the scenario's sonar config as loaded, with noise and
cross-talk from the episode RNG) against the noise-free ideal ray along the beam axis. Prints the
share of in-range beams (ideal ray < range_max) that differ by more than ``--threshold``, and how
they differ (too long / too short / lost).

``--fast``: the ``fast`` training model (one ray per beam, noise, dropouts at ``--dropout``; the
scenario's noise parameters) against the realistic specular ring, both drawing from their own
generator at the same poses, on every shipped map (or ``--scenario``): per-beam ``|fast -
specular|`` median and p90 over all beams, the share of beams differing by more than 0.1 m, and
each model's no-echo rate (a reading of ``range_max``).

    .venv/bin/python benchmarks/sonar_realism.py [--scenario hallway] [--n 2000] [--seed 0]
    .venv/bin/python benchmarks/sonar_realism.py --fast [--n 500] [--dropout 0.0]
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from parcover_env.scenarios import load_scenario
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel


def team_poses(world: MapModel, n_robots: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """Free, non-overlapping poses for ``n_robots`` robots (rejection sampling)."""
    x0, y0, x1, y1 = world.bounds
    while True:
        pts = rng.uniform([x0, y0], [x1, y1], size=(64, 2))
        pts = pts[world.contains(pts, margin=radius)][:n_robots]
        if len(pts) < n_robots:
            continue
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(n_robots) * 1e9
        if d.min() > 2 * radius:
            return np.column_stack([pts, rng.uniform(-math.pi, math.pi, n_robots)])


SHIPPED = ("office", "tree", "hallway", "t_room", "triangle_room")
"""The scenarios shipped in ``configs/``."""


def fast_vs_specular(scenario: str, n: int, seed: int, dropout: float) -> dict:
    """Readings of the ``fast`` and the specular ring at ``n`` random team placements of ``scenario``."""
    sc = load_scenario(scenario)
    world = MapModel.from_config(sc.map, include_unknown=True)
    cfg = dataclasses.replace(sc.robot.sonar, model="specular")
    real = SonarRing(cfg)
    fast = SonarRing(dataclasses.replace(cfg, model="fast", dropout_prob=dropout))
    n_robots = sc.n_robots_fixed or 2
    rng, rng_real, rng_fast = (np.random.default_rng([seed, i]) for i in range(3))
    a, b = [], []
    for _ in range(n):
        poses = team_poses(world, n_robots, sc.robot.radius, rng)
        a.append(real.measure(poses, world.segments, sc.robot.radius, rng_real).astype(float))
        b.append(fast.measure(poses, world.segments, sc.robot.radius, rng_fast).astype(float))
    spec, fst = np.concatenate(a).ravel(), np.concatenate(b).ravel()
    diff = np.abs(fst - spec)
    top = cfg.range_max - 1e-6
    return {"scenario": scenario, "robots": n_robots, "beams": spec.size, "median": float(np.median(diff)),
            "p90": float(np.percentile(diff, 90)), "over_10cm": float(np.mean(diff > 0.1)),
            "no_echo_specular": float(np.mean(spec >= top)), "no_echo_fast": float(np.mean(fst >= top))}


def report_fast(scenarios, n: int, seed: int, dropout: float) -> None:
    print(f"fast (one ray, noise, dropout_prob={dropout}, no cross-talk) vs specular (scenario config), "
          f"{n} placements per map; |fast - specular| per beam")
    print(f"{'map':14s} {'robots':>6s} {'beams':>7s} {'median m':>9s} {'p90 m':>7s} {'> 0.1 m':>8s} "
          f"{'no echo spec':>12s} {'no echo fast':>12s}")
    for name in scenarios:
        r = fast_vs_specular(name, n, seed, dropout)
        print(f"{r['scenario']:14s} {r['robots']:6d} {r['beams']:7d} {r['median']:9.3f} {r['p90']:7.3f} "
              f"{r['over_10cm']:8.1%} {r['no_echo_specular']:12.1%} {r['no_echo_fast']:12.1%}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default=None, help="default: hallway (--fast: every shipped map)")
    ap.add_argument("--n", type=int, default=2000, help="team placements")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threshold", type=float, default=0.2, help="m")
    ap.add_argument("--fast", action="store_true", help="the fast model against the specular one, every shipped map")
    ap.add_argument("--dropout", type=float, default=0.0, help="dropout_prob of the fast model (--fast)")
    args = ap.parse_args()
    if args.fast:
        report_fast([args.scenario] if args.scenario else SHIPPED, args.n, args.seed, args.dropout)
        return
    args.scenario = args.scenario or "hallway"
    sc = load_scenario(args.scenario)
    world = MapModel.from_config(sc.map, include_unknown=True)
    cfg = sc.robot.sonar
    real = SonarRing(cfg)
    ideal = SonarRing(dataclasses.replace(cfg, model="ray", multipath=False, crosstalk_prob=0.0,
                                          below_min="clip"))
    n_robots = sc.n_robots_fixed or 2
    rng = np.random.default_rng(args.seed)
    got, want = [], []
    for _ in range(args.n):
        poses = team_poses(world, n_robots, sc.robot.radius, rng)
        got.append(real.measure(poses, world.segments, sc.robot.radius, rng).astype(float))
        want.append(ideal.measure(poses, world.segments, sc.robot.radius, None).astype(float))
    got, want = np.concatenate(got).ravel(), np.concatenate(want).ravel()
    in_range = want < cfg.range_max - 1e-6
    diff = got[in_range] - want[in_range]
    big = np.abs(diff) > args.threshold
    lost = got[in_range] >= cfg.range_max - 1e-6
    print(f"{args.scenario}: sonar model={cfg.model} multipath={cfg.multipath} crosstalk={cfg.crosstalk_prob} "
          f"below_min={cfg.below_min}, {n_robots} robots x {real.n_beams} beams x {args.n} placements")
    print(f"in-range beams (ideal ray < {cfg.range_max} m): {in_range.sum()} of {in_range.size}")
    print(f"differ from the ideal ray by > {args.threshold} m: {big.mean():.1%}  "
          f"(too long {np.mean(big & (diff > 0) & ~lost):.1%}, lost = max range {np.mean(big & lost):.1%}, "
          f"too short {np.mean(big & (diff < 0)):.1%})")
    print(f"|difference| median {np.median(np.abs(diff)):.3f} m, p90 {np.percentile(np.abs(diff), 90):.3f} m")


if __name__ == "__main__":
    main()

"""How far the default (realistic) sonar ring departs from the ideal ray model on a scenario's map.

Random team poses in free space (the scenario's team size, robots apart by two radii); for every
beam, the realistic ring's reading (the scenario's sonar config as loaded, with noise and
cross-talk from the episode RNG) against the noise-free ideal ray along the beam axis. Prints the
share of in-range beams (ideal ray < range_max) that differ by more than ``--threshold``, and how
they differ (too long / too short / lost).

    .venv/bin/python benchmarks/sonar_realism.py [--scenario hallway] [--n 2000] [--seed 0]
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="hallway")
    ap.add_argument("--n", type=int, default=2000, help="team placements")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threshold", type=float, default=0.2, help="m")
    args = ap.parse_args()
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

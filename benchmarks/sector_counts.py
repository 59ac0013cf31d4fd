"""Visibility sector counts (rules 0 / 1 / 2) of shipped maps and of scaled, turned, moved copies.

For each map: the count at unlimited range and at the sonar's range (scaled with the map), for the
shipped map and for copies scaled x0.5 / x1.37 / x3, turned 30 / 90 deg and translated; and the
median wall time of one ``compute_sectors`` call (exact geometry). A count that differs between
copies would show as more than one value in a row.

    PYTHONPATH=. .venv/bin/python benchmarks/sector_counts.py [--maps t_room triangle_room hallway]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from shapely import affinity

from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.sectors import compute_sectors
from parcover_env.scenarios import load_scenario
from parcover_env.world.map_model import MapModel, map_model

COPIES = {"shipped": (1.0, 0.0), "x0.5": (0.5, 0.0), "x1.37": (1.37, 0.0), "x3": (3.0, 0.0),
          "turn 30": (1.0, 30.0), "turn 90": (1.0, 90.0), "x1.37 turn 90": (1.37, 90.0)}


def copy_of(m: MapModel, scale: float, deg: float) -> MapModel:
    g = affinity.translate(affinity.rotate(affinity.scale(m.free, scale, scale, origin=(0, 0)), deg,
                                           origin=(0, 0)), 5.3, -2.9)
    return MapModel(free=g, bounds=tuple(float(b) for b in g.bounds))


def timed(m: MapModel, range_max: float, rule: int, repeats: int) -> tuple[int, float]:
    feats = map_features(m)
    times, n = [], 0
    for _ in range(repeats):
        t = time.perf_counter()
        n = len(compute_sectors(m, range_max, rule, feats))
        times.append(time.perf_counter() - t)
    return n, float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["t_room", "triangle_room", "hallway"])
    ap.add_argument("--repeats", type=int, default=5, help="calls per timing (median)")
    args = ap.parse_args()
    for name in args.maps:
        s = load_scenario(name)
        base = map_model(s.map, include_unknown=False)
        r_sonar = s.robot.sonar.range_max if s.robot.sonar else 2.54
        print(f"{name}: {len(map_features(base))} features")
        for label, r in (("inf", np.inf), (f"{r_sonar:g} m", r_sonar)):
            for rule in (0, 1, 2):
                counts = {}
                for copy, (scale, deg) in COPIES.items():
                    counts[copy] = timed(copy_of(base, scale, deg), r * scale, rule, 1)[0]
                n, dt = timed(base, r, rule, args.repeats)
                values = sorted(set(counts.values()))
                print(f"  range {label:>7}  rule {rule}: {n:3d} sectors  ({dt * 1e3:6.1f} ms)  "
                      f"copies {'/'.join(map(str, values))} over {len(counts)} copies")


if __name__ == "__main__":
    main()

"""Accuracy benchmark of the sonar feature localizer (seed B Fig. 6) on the hallway and t_room maps.

For each map, with and without unknown obstacles, and with and without seed B's Fig. 11 filter
(issue 14 item 4): random poses (clearance = robot radius) inside the relaxed sectors (where seed B
localizes: at least one feature in sensor range; ``--where anywhere`` for all free space), a noisy
72-reading scan of the world with the scenario's sonar (the realistic default: cone, incidence limit,
multipath, dropouts), an uncertainty ellipse around a perturbed estimate that contains the true
position, a heading estimate (true + N(0, 5 deg), as odometry gives), then ``localize`` with the known
map. Prints success rate and the position / heading
error distribution (median, p90) per scenario.

    .venv/bin/python benchmarks/sonar_localization.py --n 500 [--model specular|ray] [--seed 0]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np
import shapely

from parcover_env.geometry import wrap_angle
from parcover_env.localization.sonar.config import sonar_localizer_config
from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.localizer import Ellipse, localize
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.sectors import compute_sectors
from parcover_env.scenarios import load_scenario
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

HEADING_SIGMA_DEG = 5.0
"""Heading estimate handed to the localizer: the true heading plus N(0, 5 deg) (odometry drifts
several degrees per 10 m, issue 13)."""

UNKNOWN = {
    "hallway": (((3.6, 0.2), (4.2, 0.2), (4.2, 0.6), (3.6, 0.6)),
                ((9.9, 3.0), (10.4, 3.0), (10.15, 3.5)),
                ((7.6, 1.5), (8.1, 1.5), (8.1, 1.9), (7.6, 1.9))),
    "t_room": (((2.9, 3.5), (3.4, 3.5), (3.4, 3.9), (2.9, 3.9)),
               ((1.25, 0.5), (1.65, 0.5), (1.45, 0.85))),
}


def sample_poses(world: MapModel, n: int, clearance: float, rng: np.random.Generator,
                 region=None) -> np.ndarray:
    x0, y0, x1, y1 = world.bounds
    out = np.zeros((0, 3))
    while len(out) < n:
        pts = rng.uniform([x0, y0], [x1, y1], size=(4 * n, 2))
        pts = pts[world.contains(pts, margin=clearance)]
        if region is not None:
            pts = pts[shapely.contains_xy(region, pts[:, 0], pts[:, 1])]
        th = rng.uniform(-math.pi, math.pi, len(pts))
        out = np.concatenate([out, np.column_stack([pts, th])])
    return out[:n]


def run(name: str, unknown: bool, n: int, model: str | None, seed: int, params: SonarLocalizerParams,
        where: str = "sector", use_heading: bool = True):
    sc = load_scenario(name)
    map_cfg = dataclasses.replace(sc.map, unknown_obstacles=UNKNOWN[name] if unknown else ())
    world = MapModel.from_config(map_cfg, include_unknown=True)
    known = MapModel.from_config(map_cfg, include_unknown=False)
    sonar = sc.robot.sonar if model is None else dataclasses.replace(sc.robot.sonar, model=model)
    ring = SonarRing(sonar)
    feats = map_features(known)
    t0 = time.perf_counter()
    sectors = compute_sectors(known, sonar.range_max, rule=2, features=feats,
                              resolution=params.sector_resolution)
    t_sec = time.perf_counter() - t0
    rng = np.random.default_rng(seed)
    region = shapely.union_all([s.polygon for s in sectors]) if where == "sector" else None
    poses = sample_poses(world, n, sc.robot.radius, rng, region)
    pos_err, head_err, ok, correct, tried = [], [], 0, 0, []
    t0 = time.perf_counter()
    for pose in poses:
        scan = ring.scan(pose, world.segments, None, sc.robot.radius, rng)
        axes = rng.uniform(0.2, 0.4, 2)
        ang = rng.uniform(-math.pi, math.pi)
        rad, phi = 0.8 * math.sqrt(rng.random()), rng.uniform(0, 2 * math.pi)
        local = np.array([axes[0] * rad * math.cos(phi), axes[1] * rad * math.sin(phi)])
        c, s = math.cos(ang), math.sin(ang)
        centre = pose[:2] - np.array([c * local[0] - s * local[1], s * local[0] + c * local[1]])
        heading = pose[2] + math.radians(HEADING_SIGMA_DEG) * rng.standard_normal() if use_heading else None
        res = localize(scan, ring.scan_angles, known, sectors, Ellipse(tuple(centre), tuple(axes), ang),
                       params, sonar=sonar, features=feats, heading=heading)
        tried.append(res.candidates_tried)
        if res.pose is None:
            continue
        pe = float(np.linalg.norm(res.pose[:2] - pose[:2]))
        he = abs(float(wrap_angle(res.pose[2] - pose[2])))
        ok += res.success
        good = pe < 0.25 and he < math.radians(10)
        correct += good
        if res.success:
            pos_err.append(pe)
            head_err.append(math.degrees(he))
    dt = (time.perf_counter() - t0) / n
    pe, he = np.array(pos_err), np.array(head_err)

    def q(x, k):
        return float(np.percentile(x, k)) if len(x) else float("nan")

    print(f"{name:8s} unknown={unknown!s:5s} filter={params.filter!s:5s} grid={params.grid_step > 0!s:5s} "
          f"model={sonar.model:8s} n={n} "
          f"sectors={len(sectors)} "
          f"({t_sec:.2f} s) | success {100 * ok / n:5.1f}% correct(<25cm,<10deg) {100 * correct / n:5.1f}% | "
          f"pos err (success) median {100 * q(pe, 50):.1f} cm p90 {100 * q(pe, 90):.1f} cm | "
          f"heading median {q(he, 50):.2f} deg p90 {q(he, 90):.2f} deg | "
          f"wrong-but-confident {sum(1 for x in pos_err if x >= 0.25)} | "
          f"{1000 * dt:.0f} ms/localization, {np.mean(tried):.0f} synthetic scans")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", choices=["ray", "specular"], default=None,
                    help="override the scenario's sonar model")
    ap.add_argument("--maps", nargs="+", default=["t_room", "hallway"])
    ap.add_argument("--where", choices=["sector", "anywhere"], default="sector",
                    help="sample poses inside the relaxed sectors (seed B's premise) or anywhere free")
    ap.add_argument("--unknown", choices=["no", "yes", "both"], default="both",
                    help="with unknown obstacles in the world")
    ap.add_argument("--filter", choices=["on", "off", "both"], default="both", help="Fig. 11 filter")
    ap.add_argument("--no-heading", action="store_true", help="no heading estimate for the localizer")
    ap.add_argument("--no-grid", action="store_true",
                    help="feature poses only (no scan-matching fallback): the filter's own effect")
    args = ap.parse_args()
    unknowns = {"no": (False,), "yes": (True,), "both": (False, True)}[args.unknown]
    filters = {"on": (True,), "off": (False,), "both": (False, True)}[args.filter]
    for name in args.maps:
        for unknown in unknowns:
            for flt in filters:
                params = dataclasses.replace(sonar_localizer_config(load_scenario(name)), filter=flt)
                if args.no_grid:
                    params = dataclasses.replace(params, grid_step=0.0)
                run(name, unknown, args.n, args.model, args.seed, params, args.where, not args.no_heading)


if __name__ == "__main__":
    main()

"""Seed B §3.1 on the hallway: the eq. 1 bias B of the subgoal before and after scan-angle optimization.

The paper's example: the original subgoal (the last path node before the uncertainty ellipse grows
too large) has theta_1 = 15 deg, theta_2 = 75 deg, B = 60 deg; after optimization B is close to 0.
Here, along robot 0's plan path on ``hallway`` and for look-ahead windows of a few metres, the
bias at the farthest node of the window (the original choice; "none" = no feature available there)
and at the node the optimization chooses.

    .venv/bin/python benchmarks/scan_angle_bias.py [--windows 3 5 7]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.subgoals import choose_subgoal, densify, score_nodes
from parcover_env.scenarios import load_scenario, mission_for


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="hallway")
    ap.add_argument("--windows", type=float, nargs="+", default=[3.0, 5.0, 7.0])
    ap.add_argument("--tie-deg", type=float, default=5.0, help="biases within this count as equal (deg)")
    args = ap.parse_args()
    s = load_scenario(args.scenario)
    mission, sonar = mission_for(s), s.robot.sonar
    feats = map_features(mission.known_map)
    path = densify(mission.plan.paths[0], 0.05)
    inc = math.radians(sonar.incidence_max_deg) if sonar.model == "specular" else math.pi / 2
    sc = score_nodes(path.xy, mission.known_map, feats, sonar.range_min, sonar.range_max,
                     math.radians(sonar.scan_step_deg), inc)

    def deg(b: float) -> str:
        return f"{math.degrees(b):5.1f}" if np.isfinite(b) else " none"

    print(f"{args.scenario}: eq. 1 bias B (deg) of robot 0's subgoal, window = metres along its path")
    for hi in args.windows:
        far = int(np.nonzero(path.s <= hi)[0][-1])
        k = choose_subgoal(path.s, sc.bias, 0.0, hi, math.radians(args.tie_deg))
        print(f"window {hi:4.1f} m: farthest node B = {deg(sc.bias[far])}   optimized B = {deg(sc.bias[k])} "
              f"at ({path.xy[k, 0]:.2f}, {path.xy[k, 1]:.2f}), feature {int(sc.feature[k])}")


if __name__ == "__main__":
    main()

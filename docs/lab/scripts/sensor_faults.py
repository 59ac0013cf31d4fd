"""Expert under sensor faults: Kinect frame drop rates (and sonar garbage) on office and tree.

Prints, per scenario and fault level, the expert's success rate, KPOIs visited, RMS localization
error (m), makespan (s) and wall time over a few seeds.

    .venv/bin/python docs/lab/scripts/sensor_faults.py --seeds 3
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import parcover_env as pe
from parcover_env.config.typed import to_mapping
from parcover_env.expert import expert_for
from parcover_env.harness.rollout import run_episode


def faults(name: str, drop: float, garbage: float) -> dict:
    s = pe.load_scenario(name)
    out: dict = {"kinects": [{**to_mapping(k), "drop_rate": drop} for k in s.kinects]}
    if garbage:
        out["robot"] = {"sonar": {"garbage_rate": garbage}}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", nargs="+", default=["office", "tree"])
    p.add_argument("--drops", nargs="+", type=float, default=[0.0, 0.3, 0.7, 1.0])
    p.add_argument("--garbage", nargs="+", type=float, default=[0.3])
    p.add_argument("--seeds", type=int, default=3)
    args = p.parse_args(argv)
    levels = [(d, 0.0) for d in args.drops] + [(0.0, g) for g in args.garbage]
    print(f"{'scenario':<8} {'drop':>5} {'garb':>5} {'success':>8} {'kpois':>7} {'loc_err m':>10} "
          f"{'makespan s':>11} {'wall s':>7}")
    for name in args.scenarios:
        for drop, garbage in levels:
            env = pe.parallel_env(name, overrides=faults(name, drop, garbage))
            rows = [run_episode(env, expert_for(env), seed) for seed in range(args.seeds)]
            succ = np.mean([r["success"] for r in rows])
            kp = np.mean([r["kpois_visited"] for r in rows])
            err = np.mean([r["localization_error"] for r in rows])
            spans = [r["makespan"] for r in rows if r["makespan"] is not None]
            span = f"{np.mean(spans):11.1f}" if spans else f"{'-':>11}"
            wall = np.mean([r["wall_time"] for r in rows])
            print(f"{name:<8} {drop:5.1f} {garbage:5.1f} {succ:8.2f} {kp:4.1f}/{len(env.scenario.kpois):<2d} "
                  f"{err:10.3f} {span} {wall:7.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Scripted expert per scenario over many seeds: success, makespan ratio, messages, errors, time.

    python benchmarks/expert.py                      # 50 seeds on every shipped scenario
    python benchmarks/expert.py --seeds 5 --scenarios office tree

Prints one Markdown table (makespan ratio = makespan / (c_max / v_max): min / mean / p95 / max)
and, for the Kinect scenarios, the messages of formation mode vs every-robot-localized mode.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import parcover_env
from parcover_env.expert.policy import ScriptedExpert
from parcover_env.harness.rollout import run_episode


def episode(job: tuple[str, int, str]) -> dict:
    name, seed, mode = job
    env = parcover_env.parallel_env(name, overrides={"formation": {"mode": mode}})
    m = run_episode(env, ScriptedExpert.for_env(env), seed)
    m["n_messages"] = sum(m["messages"].values())
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--scenarios", nargs="+", default=["office", "tree", "hallway", "t_room"])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    jobs = [(s, k, "formation") for s in args.scenarios for k in range(args.seeds)]
    kinect = [s for s in args.scenarios if parcover_env.load_scenario(s).kinects]
    jobs += [(s, k, "individual") for s in kinect for k in range(min(args.seeds, 10))]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(episode, jobs))
    rows = {}
    for (name, _, mode), m in zip(jobs, results):
        rows.setdefault((name, mode), []).append(m)
    print(f"{len(jobs)} episodes in {time.perf_counter() - t0:.0f} s on {args.workers} workers\n")
    print("| scenario | seeds | success | KPOIs | makespan ratio min / mean / p95 / max | wall coll. | robot coll. "
          "| messages | formation err l (m) | loc. err (m) | wall time / ep (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        ms = rows[(name, "formation")]
        ratio = np.array([m["makespan_ratio"] for m in ms if m["makespan_ratio"] is not None])
        r = (f"{ratio.min():.2f} / {ratio.mean():.2f} / {np.percentile(ratio, 95):.2f} / {ratio.max():.2f}"
             if len(ratio) else "-")
        print(f"| {name} | {len(ms)} | {np.mean([m['success'] for m in ms]):.0%} "
              f"| {np.mean([m['kpois_visited'] / m['n_kpois'] for m in ms]):.1%} | {r} "
              f"| {sum(m['wall_collisions'] for m in ms)} | {np.mean([m['robot_collisions'] for m in ms]):.1f} avg "
              f"| {np.mean([m['n_messages'] for m in ms]):.0f} | {np.mean([m['formation_error_l'] for m in ms]):.3f} "
              f"| {np.mean([m['localization_error'] for m in ms]):.3f} | {np.mean([m['wall_time'] for m in ms]):.2f} |")
    if kinect:
        print("\nMessages per episode, leader-only formations vs every robot localized (no formations):\n")
        print("| scenario | formation: total (pose / waypoint / split / promotion) "
              "| individual: total (pose / waypoint) |")
        print("|---|---|---|")
        for name in kinect:
            f, i = rows[(name, "formation")], rows[(name, "individual")]

            def avg(ms, key):
                return np.mean([m["messages"].get(key, 0) for m in ms])

            print(f"| {name} | {np.mean([m['n_messages'] for m in f]):.0f} ({avg(f, 'pose'):.0f} / "
                  f"{avg(f, 'waypoint'):.0f} / {avg(f, 'split'):.0f} / {avg(f, 'promotion'):.0f}) "
                  f"| {np.mean([m['n_messages'] for m in i]):.0f} ({avg(i, 'pose'):.0f} / {avg(i, 'waypoint'):.0f}) |")


if __name__ == "__main__":
    main()

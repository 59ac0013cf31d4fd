"""Mission benchmark of the sonar NAVIGATOR (seed B Fig. 1) on the hallway (Figs. 8-10) and t_room maps.

For each seed: one episode driven by ``SonarNavigator``; prints whether every KPOI was visited, the
makespan, scans / fixes accepted / rejected, the navigator's belief error against the true pose
(read here from ``env.world`` for reporting only; the navigator never sees it) right after each
accepted fix and at the episode end, and the wall time.

    .venv/bin/python docs/lab/scripts/sonar_navigation.py --seeds 10 [--maps hallway t_room] [--max-axis 0.35]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import parcover_env
from parcover_env.envs.metrics import episode_metrics
from parcover_env.expert.config import NavigatorConfig
from parcover_env.expert.navigator import SonarNavigator


def episode(name: str, seed: int, params: NavigatorConfig) -> dict:
    env = parcover_env.parallel_env(name)
    nav = SonarNavigator.for_env(env, params=params)
    obs, _ = env.reset(seed=seed)
    nav.reset(obs)
    t0, steps, seen, fix_err, summary = time.perf_counter(), 0, 0, [], None
    while env.agents and steps < env.scenario.episode.max_steps:
        obs, _, _, _, infos = env.step(nav.act(obs))
        steps += 1
        while seen < len(nav.fixes):
            f = nav.fixes[seen]
            seen += 1
            if f["success"]:
                true = env.world.poses()[f["robot"]]
                fix_err.append(float(np.hypot(*(nav.belief()[f["robot"], :2] - true[:2]))))
        if not env.agents:
            summary = episode_metrics(next(iter(infos.values())))
    true = env.world.poses()
    end_err = np.hypot(*(nav.belief()[:, :2] - true[:, :2]).T)
    summary = summary or env.metrics.summary()
    return {"success": bool(summary["success"]), "makespan": summary["makespan"], "steps": steps,
            "fix_err": fix_err, "end_err": float(end_err.max()), "wall": time.perf_counter() - t0,
            "collisions": summary["collisions"], **nav.stats()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--maps", nargs="+", default=["hallway", "t_room"])
    ap.add_argument("--max-axis", type=float, default=None, help="override expert.navigator.max_axis (m)")
    args = ap.parse_args()
    params = NavigatorConfig() if args.max_axis is None else NavigatorConfig(max_axis=args.max_axis)
    for name in args.maps:
        rows = [episode(name, s, params) for s in range(args.seeds)]
        ok = [r for r in rows if r["success"]]
        fe = np.concatenate([r["fix_err"] for r in rows]) if any(r["fix_err"] for r in rows) else np.array([])
        ms = [r["makespan"] for r in ok]

        def q(x, k):
            return 100 * float(np.percentile(x, k)) if len(x) else float("nan")

        print(f"{name:8s} seeds={args.seeds} | mission success {100 * len(ok) / len(rows):5.1f}% | "
              f"makespan mean {np.mean(ms) if ms else float('nan'):.1f} s | "
              f"scans/episode {np.mean([r['sonar_scans'] for r in rows]):.1f} "
              f"accepted {sum(r['sonar_localized'] for r in rows)} "
              f"rejected {sum(r['sonar_failed'] for r in rows)} "
              f"| scan time/episode {np.mean([r['sonar_scan_time'] for r in rows]):.1f} s | "
              f"belief err after fix median {q(fe, 50):.1f} cm p90 {q(fe, 90):.1f} cm "
              f"max {q(fe, 100):.1f} cm | "
              f"end err (worst robot) mean {100 * np.mean([r['end_err'] for r in rows]):.1f} cm | "
              f"collisions {sum(r['collisions'] for r in rows)} | "
              f"wall {np.mean([r['wall'] for r in rows]):.1f} s/episode")


if __name__ == "__main__":
    main()

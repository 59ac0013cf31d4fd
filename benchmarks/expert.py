"""Scripted expert per scenario over many seeds: success, KPOIs, makespan ratio, failures by cause.

    python benchmarks/expert.py                                   # 50 seeds on every shipped scenario
    python benchmarks/expert.py --seeds 5 --scenarios office tree
    python benchmarks/expert.py --scenarios generated --seeds 200 --preset ideal
    python benchmarks/expert.py --scenarios generated --seeds 60 --first-seed 1000
    python benchmarks/expert.py --scenarios generated --seeds 200 --own-scan   # the expert's own sonar loop
    python benchmarks/expert.py --scenarios generated --seeds 100 --no-relocate   # without "scan from elsewhere"

``generated`` stands for the maps ``generated:SEED`` with SEED = the episode seed (one map per
seed). The env is built as ``parcover run --policy expert`` builds it: with the env's sonar
localization service (``observation.scan``), which does the experts' stop-and-scan fixes (they ask
for a scan and read the env's estimate and covariance). ``--own-scan``: without it; the experts then
turn, collect and localize their scans themselves (their former loop, kept for comparison). Prints
one Markdown table (makespan ratio = makespan / (c_max / v_max), c_max on the roadmap metric: min / mean / p95 /
max), the makespan ratio against the free-space lower bound c_free, failures by cause
(``parcover_env.harness.failures``) with their seeds, for the sonar navigator its rearrangements,
scan-angle bias and lateral offset, and, for the Kinect scenarios, the messages of formation mode
vs every-robot-localized mode (``--messages``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.harness.failures import CAUSES, run_diagnosed
from parcover_env.policies.registry import policy_overrides


def _name(scenario: str, seed: int) -> str:
    return f"generated:{seed}" if scenario == "generated" else scenario


NO_RELOCATE = {"observation": {"scan": {"enabled": True, "confirm_widened": False}},
               "expert": {"sonar_fix": {"relocate_distance": 0.0}}}
"""``--no-relocate``: the expert before 2026-11-26 (the env applies fixes found in a widened region at once,
``scan.confirm_widened`` off, and the expert rescans in place, ``expert.sonar_fix.relocate_distance`` 0)."""


def episode(job: tuple[str, int, str, str, bool, bool]) -> dict:
    scenario, seed, mode, preset, env_scan, no_relocate = job
    name = _name(scenario, seed)
    overrides = {"formation": {"mode": mode}}
    if env_scan:
        overrides.update(policy_overrides("expert", name))
    if no_relocate:
        overrides.update(NO_RELOCATE)
    try:
        env = parcover_env.parallel_env(name, overrides=overrides, preset=preset)
    except Exception as exc:  # noqa: BLE001 - a map that cannot be built is reported, not fatal
        return {"success": False, "cause": "error", "error": f"{type(exc).__name__}: {exc}", "seed": seed}
    m, diag = run_diagnosed(env, expert_for(env), seed)
    m["n_messages"] = sum(m["messages"].values())
    m["seed"] = seed
    m["error"] = diag.error
    return m


def _ratio(ms: list[dict]) -> str:
    ratio = np.array([m["makespan_ratio"] for m in ms if m.get("makespan_ratio") is not None])
    if not len(ratio):
        return "-"
    return f"{ratio.min():.2f} / {ratio.mean():.2f} / {np.percentile(ratio, 95):.2f} / {ratio.max():.2f}"


def _free_ratio(ms: list[dict]) -> str:
    ratio = np.array([m["makespan_ratio_free"] for m in ms if m.get("makespan_ratio_free") is not None])
    if not len(ratio):
        return "-"
    return f"{ratio.min():.2f} / {ratio.mean():.2f} / {np.percentile(ratio, 95):.2f} / {ratio.max():.2f}"


def _mean(ms: list[dict], key: str, default: float = float("nan")) -> float:
    vals = [m[key] for m in ms if key in m]
    return float(np.mean(vals)) if vals else default


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--scenarios", nargs="+", default=["office", "tree", "hallway", "t_room"],
                    help="shipped names, YAML paths, or 'generated' (generated:SEED, one map per seed)")
    ap.add_argument("--preset", choices=["realistic", "ideal"], default="realistic")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--messages", action="store_true",
                    help="also run 10 seeds per Kinect scenario in 'individual' mode and compare messages")
    ap.add_argument("--own-scan", action="store_true",
                    help="build the env without its sonar localization service: the experts localize their own scans")
    ap.add_argument("--no-relocate", action="store_true",
                    help="the expert before 2026-11-26: fixes of a widened region applied at once "
                         "(scan.confirm_widened off) and rescans in place (expert.sonar_fix.relocate_distance 0)")
    args = ap.parse_args()
    if args.no_relocate and args.own_scan:
        ap.error("--no-relocate needs the env's sonar service: drop --own-scan")
    args.env_scan = not args.own_scan
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    how = (args.preset, args.env_scan, args.no_relocate)
    jobs = [(s, k, "formation", *how) for s in args.scenarios for k in seeds]
    kinect = [s for s in args.scenarios if args.messages and s != "generated" and parcover_env.load_scenario(s).kinects]
    jobs += [(s, k, "individual", *how) for s in kinect for k in list(seeds)[:10]]
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(args.workers) as pool:
        for m in pool.map(episode, jobs):  # in order, as they finish: a running tally on stderr
            results.append(m)
            failed = [r["seed"] for r in results if not r["success"]]
            print(f"\r{len(results)}/{len(jobs)} episodes, failed seeds: {failed}", end="", file=sys.stderr,
                  flush=True)
    print(file=sys.stderr)
    rows: dict[tuple[str, str], list[dict]] = {}
    for (name, _, mode, *_), m in zip(jobs, results, strict=True):
        rows.setdefault((name, mode), []).append(m)
    print(f"{len(jobs)} episodes in {time.perf_counter() - t0:.0f} s on {args.workers} workers, "
          f"preset {args.preset}, seeds {seeds.start}..{seeds.stop - 1}, env scans {args.env_scan}, "
          f"no-relocate {args.no_relocate}\n")
    print("| scenario | seeds | success | KPOIs | makespan ratio min / mean / p95 / max | wall coll. | robot coll. "
          "| messages | formation err l (m) | loc. err (m) | wall time / ep (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        ms = rows[(name, "formation")]
        ok = [m for m in ms if "n_kpois" in m]
        print(f"| {name} | {len(ms)} | {np.mean([m['success'] for m in ms]):.1%} "
              f"| {np.mean([m['kpois_visited'] / m['n_kpois'] for m in ok]):.1%} | {_ratio(ok)} "
              f"| {sum(m['wall_collisions'] for m in ok)} | {_mean(ok, 'robot_collisions'):.1f} avg "
              f"| {_mean(ok, 'n_messages'):.0f} | {_mean(ok, 'formation_error_l'):.3f} "
              f"| {_mean(ok, 'localization_error'):.3f} | {_mean(ok, 'wall_time'):.2f} |")
    print("\nMakespan ratio against the free-space lower bound (makespan / (c_free / v_max); the table's ratio "
          "divides by the roadmap's c_max), min / mean / p95 / max:\n")
    for name in args.scenarios:
        ok = [m for m in rows[(name, "formation")] if "n_kpois" in m]
        cf = sorted({round(m["c_free"], 2) for m in ok if "c_free" in m})
        print(f"* {name}: {_free_ratio(ok)} (c_free {', '.join(f'{c:.2f}' for c in cf[:3])} m)")
    print("\nFailures by cause (seeds):\n")
    print("| scenario | " + " | ".join(c for c in CAUSES if c != "solved") + " |")
    print("|---|" + "---|" * (len(CAUSES) - 1))
    for name in args.scenarios:
        ms = rows[(name, "formation")]
        count = Counter(m["cause"] for m in ms)
        cells = []
        for c in CAUSES[1:]:
            seeds_c = [m["seed"] for m in ms if m["cause"] == c]
            shown = ", ".join(map(str, seeds_c[:12])) + (", ..." if len(seeds_c) > 12 else "")
            cells.append(f"{count[c]} ({shown})" if count[c] else "0")
        print(f"| {name} | " + " | ".join(cells) + " |")
    sonar = [name for name in args.scenarios if any("sonar_rearranged" in m for m in rows[(name, "formation")])]
    if sonar:
        print("\nSonar navigator (Kim, Pearce & Amato §3): rearranged subgoal pairs per episode, eq. 1 bias at the "
              "original algorithm's subgoal vs the optimized one (mean over subgoals), median lateral offset "
              "between the robots while both drive (per episode, then median over episodes):\n")
        print("| scenario | rearranged / episode (mean, min-max) | of them by the proximity trigger (mean, min-max) "
              "| reactions to a done teammate (total) | episodes with >= 1 | pairs in different sectors "
              "| bias before / after (deg) | lateral offset (m) |")
        print("|---|---|---|---|---|---|---|---|")
    for name in sonar:
        ms = [m for m in rows[(name, "formation")] if "sonar_rearranged" in m]
        n_re = np.array([m["sonar_rearranged"] for m in ms])
        counted = [m for m in ms if m["sonar_bias_subgoals"] > 0]

        def biased(key, counted=counted):  # mean over all subgoals: episode means weighted by their count
            total = sum(m["sonar_bias_subgoals"] for m in counted)
            return sum(m[key] * m["sonar_bias_subgoals"] for m in counted) / total if total else float("nan")

        lat = np.array([m["sonar_lateral_offset"] for m in ms])
        n_cl = np.array([m.get("sonar_rearranged_close", 0) for m in ms])
        print(f"| {name} | {n_re.mean():.2f} ({n_re.min()}-{n_re.max()}) "
              f"| {n_cl.mean():.2f} ({n_cl.min()}-{n_cl.max()}) "
              f"| {sum(m.get('sonar_reacted', 0) for m in ms)} | {(n_re > 0).sum()} / {len(ms)} "
              f"| {sum(m['sonar_separate_sectors'] for m in ms)} "
              f"| {biased('sonar_bias_before_deg'):.1f} / {biased('sonar_bias_after_deg'):.1f} "
              f"| {np.nanmedian(lat):.2f} (min {np.nanmin(lat):.2f}) |")
        print(f"\n{name}: rearranged pairs by seed: " + " ".join(f"{m['seed']}:{m['sonar_rearranged']}" for m in ms))
    errors = [(m["seed"], m["error"]) for (n, _), ms in rows.items() for m in ms if m.get("error")]
    for seed, err in errors[:10]:
        print(f"\nseed {seed}: {err}")
    if kinect:
        print("\nMessages per episode, leader-only formations vs every robot localized (no formations):\n")
        print("| scenario | formation: total (pose / waypoint / split / promotion) "
              "| individual: total (pose / waypoint) | makespan (s) formation / individual, same seeds "
              "| success formation / individual |")
        print("|---|---|---|---|---|")
        for name in kinect:
            f, i = rows[(name, "formation")], rows[(name, "individual")]

            def avg(ms, key):
                return np.mean([m["messages"].get(key, 0) for m in ms])

            f = f[:len(i)]  # the seeds both modes ran
            both = [(a["makespan"], b["makespan"]) for a, b in zip(f, i, strict=True)
                    if a.get("makespan") is not None and b.get("makespan") is not None]
            span = np.mean(both, axis=0) if both else (float("nan"),) * 2
            print(f"| {name} | {np.mean([m['n_messages'] for m in f]):.0f} ({avg(f, 'pose'):.0f} / "
                  f"{avg(f, 'waypoint'):.0f} / {avg(f, 'split'):.0f} / {avg(f, 'promotion'):.0f}) "
                  f"| {np.mean([m['n_messages'] for m in i]):.0f} ({avg(i, 'pose'):.0f} / {avg(i, 'waypoint'):.0f}) "
                  f"| {span[0]:.1f} / {span[1]:.1f} ({len(both)} seeds) "
                  f"| {np.mean([m['success'] for m in f]):.0%} / {np.mean([m['success'] for m in i]):.0%} |")


if __name__ == "__main__":
    main()

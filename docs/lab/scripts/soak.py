"""Soak test: millions of env steps with resets; prints RSS over time (it must stay flat).

Random actions (seeded) on one scenario; an episode that ends is reset without a seed, and every
``--reseed-every`` episodes with a new seed. RSS (resident set size, from /proc/self/statm) is
sampled every ``--every`` steps after a warm-up; the last line compares the end with the post-warm-up
level and prints the slope of a least-squares fit.

    .venv/bin/python docs/lab/scripts/soak.py --steps 1000000 --scenario office
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

import parcover_env as pe


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1_000_000)
    p.add_argument("--scenario", default="office")
    p.add_argument("--every", type=int, default=50_000, help="print RSS every N steps (default: 50000)")
    p.add_argument("--warmup", type=int, default=20_000,
                   help="steps before the RSS baseline (default: 20000)")
    p.add_argument("--reseed-every", type=int, default=10, help="reset with a new seed every N episodes")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    env = pe.parallel_env(args.scenario)
    rng = np.random.default_rng(args.seed)
    env.reset(seed=args.seed)
    episodes, t0 = 0, time.perf_counter()
    samples: list[tuple[int, float]] = []
    print(f"soak: {args.scenario}, {env.n_robots} robots, {args.steps} steps; RSS at start {rss_mb():.1f} MB",
          flush=True)
    print(f"{'step':>10} {'episodes':>9} {'RSS MB':>8} {'ms/step':>8}", flush=True)
    t_last = t0
    for k in range(1, args.steps + 1):
        if not env.agents:
            episodes += 1
            env.reset(seed=args.seed + episodes if episodes % args.reseed_every == 0 else None)
        env.step({a: rng.uniform(-1.0, 1.0, 2) for a in env.agents})
        if k % args.every == 0 or k == args.steps:
            now = time.perf_counter()
            ms = (now - t_last) / (k - (samples[-1][0] if samples else 0)) * 1e3
            t_last = now
            samples.append((k, rss_mb()))
            print(f"{k:10d} {episodes:9d} {samples[-1][1]:8.1f} {ms:8.2f}", flush=True)
    base = [s for s in samples if s[0] >= args.warmup]
    if len(base) >= 2:
        x, y = np.array(base, dtype=float).T
        slope = np.polyfit(x, y, 1)[0] * 1e6
        print(f"RSS after warm-up {base[0][1]:.1f} MB -> end {base[-1][1]:.1f} MB "
              f"({base[-1][1] - base[0][1]:+.1f} MB); fitted slope {slope:+.2f} MB per 10^6 steps; "
              f"{episodes} episodes, {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

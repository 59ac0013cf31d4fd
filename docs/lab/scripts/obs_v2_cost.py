"""Cost of env version 2: step time of v1 vs v2 (ParallelEnv and batched worlds) and of ``state()``.

Median of ``--repeats`` chunks of ``--steps`` steps with seeded random actions, resets excluded.

    .venv/bin/python docs/lab/scripts/obs_v2_cost.py                # office, tree, generated:7; batched tree K = 16
    .venv/bin/python docs/lab/scripts/obs_v2_cost.py --steps 100 --repeats 3
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import parcover_env
from parcover_env import parcover_v2
from parcover_env.envs.batched import BatchedVecEnv
from parcover_env.parcover_v2 import V2_SETTINGS


def _env_step_ms(make, steps: int, repeats: int) -> tuple[float, float]:
    """Median ms per ``step`` and per ``state()`` of a ParallelEnv."""
    env = make()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    step_t, state_t = [], []
    for _ in range(repeats):
        acts = rng.uniform(-1, 1, (steps, env.n_robots, 2)).astype(np.float32)
        t0 = time.perf_counter()
        for a in acts:
            if not env.agents:
                env.reset()
            env.step(dict(zip(env.possible_agents, a, strict=True)))
        step_t.append((time.perf_counter() - t0) / steps)
        t0 = time.perf_counter()
        for _ in range(steps):
            env.state()
        state_t.append((time.perf_counter() - t0) / steps)
    return 1e3 * float(np.median(step_t)), 1e3 * float(np.median(state_t))


def _batched_ms(overrides: dict, k: int, steps: int, repeats: int) -> float:
    venv = BatchedVecEnv("tree", n_envs=k, overrides=overrides)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    times = []
    for _ in range(repeats):
        acts = rng.uniform(-1, 1, (steps, venv.num_envs, 2)).astype(np.float32)
        t0 = time.perf_counter()
        for a in acts:
            venv.step(a)
        times.append((time.perf_counter() - t0) / steps)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--k", type=int, default=16)
    args = ap.parse_args()
    print("| scenario | v1 step ms | v2 step ms | v2 / v1 | v1 state() ms | v2 state() ms | obs size v1 / v2 |")
    print("|---|---|---|---|---|---|---|")
    for name in ("office", "tree", "generated:7"):
        s1, st1 = _env_step_ms(lambda name=name: parcover_env.parallel_env(name), args.steps, args.repeats)
        s2, st2 = _env_step_ms(lambda name=name: parcover_v2.parallel_env(name), args.steps, args.repeats)
        d1 = parcover_env.parallel_env(name).layout.size
        d2 = parcover_v2.parallel_env(name).layout.size
        print(f"| {name} | {s1:.3f} | {s2:.3f} | {s2 / s1:.2f} | {st1:.3f} | {st2:.3f} | {d1} / {d2} |")
    b1 = _batched_ms({}, args.k, args.steps // 4, args.repeats)
    b2 = _batched_ms(V2_SETTINGS, args.k, args.steps // 4, args.repeats)
    print(f"\nbatched tree, K = {args.k}: v1 {b1:.2f} ms / world-step batch, v2 {b2:.2f} ms ({b2 / b1:.2f}x)")


if __name__ == "__main__":
    main()

"""RSS of the batched backend (``office``, K = 16) over a run, then after ``malloc_trim(0)``: tells
allocator slack (returned by the trim) from live objects (counted: worlds, pymunk bodies).

    PYTHONPATH=. python docs/lab/scripts/memory_slack.py --steps 6000     # 96 000 world-steps
"""

from __future__ import annotations

import argparse
import ctypes
import gc

import numpy as np


def rss_mb() -> float:
    """Resident set size of this process (MiB), from /proc (Linux)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=6000, help="VecEnv steps after a 300-step warm-up")
    p.add_argument("--k", type=int, default=16, help="worlds")
    args = p.parse_args(argv)

    import pymunk

    from parcover_env.envs.vec_env import make_vec_env
    from parcover_env.world.physics import World

    v = make_vec_env("office", args.k, backend="batched", monitor=False)
    v.seed(0)
    v.reset()
    acts = np.random.default_rng(1).uniform(-1, 1, (64, v.num_envs, 2)).astype(np.float32)
    for k in range(300):
        v.step(acts[k % 64])
    gc.collect()
    r0 = rss_mb()
    growth = []
    every = max(args.steps // 8, 1)
    for k in range(args.steps):
        v.step(acts[k % 64])
        if (k + 1) % every == 0:
            gc.collect()
            growth.append(round(rss_mb() - r0, 1))
    ctypes.CDLL("libc.so.6").malloc_trim(0)
    objs = gc.get_objects()
    worlds, bodies = sum(isinstance(o, World) for o in objs), sum(isinstance(o, pymunk.Body) for o in objs)
    print(f"RSS {r0:.1f} MiB after the warm-up; growth over {args.steps} VecEnv steps ({args.k * args.steps} "
          f"world-steps), {len(growth)} samples: {growth} MiB; after malloc_trim(0): {rss_mb() - r0:+.1f} MiB; "
          f"live World {worlds}, pymunk Body {bodies}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

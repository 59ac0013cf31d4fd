"""Where the realistic sonar ring spends its time per world in a batch, and what a static-wall grid
could save (issue 31 item 3).

K batched ``tree`` worlds are stepped with random actions; then, on their poses, each part is timed
alone (median of ``--repeats`` runs of ``--calls`` calls, microseconds per world): the rings' draws
(each world's own generator), the whole compiled ring (:meth:`SonarRing.readings`), the noise-free
cone echoes with and without the robots as discs and with neither walls nor robots, i.e. the
casting's overhead (:func:`simulate_beams`), the near-wall lists
(:func:`near_segments`, what a grid of wall indices would replace) and the ``fast`` ring. Also
prints how many walls lie within ``range_max`` of a robot (the walls a sub-ray tests).

    .venv/bin/python docs/lab/scripts/sonar_parts.py [--k 64] [--calls 100] [--repeats 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from parcover_env.envs.vec_env import make_vec_env
from parcover_env.geometry.ray_kernels import near_segments
from parcover_env.sensors.sonar import SonarRing, simulate_beams


def per_world(fn, k: int, calls: int, repeats: int) -> float:
    """Median microseconds per world of ``fn()`` (one call covers ``k`` worlds)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - t0) / calls)
    return float(np.median(times)) / k * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=int, default=64)
    ap.add_argument("--calls", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    k = args.k
    venv = make_vec_env("tree", n_envs=k, backend="batched", monitor=False)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    for _ in range(30):
        venv.step(rng.uniform(-1, 1, (venv.num_envs, 2)).astype(np.float32))
    first = venv.worlds[0]
    ring, segs, radius = first.sonar, first.map.segments, first.scenario.robot.radius
    poses = np.stack([w.world.poses() for w in venv.worlds])
    venv.close()
    n, cfg = poses.shape[1], ring.cfg
    rngs = [np.random.default_rng(i) for i in range(k)]
    draws = [ring.draw(n, g) for g in rngs]
    flat = poses.reshape(k * n, 3)
    axes = flat[:, 2:3] + ring.beam_angles[None, :]
    centres = np.broadcast_to(poses[:, None, :, :2], (k, n, n, 2)).reshape(k * n, n, 2)
    owner = np.tile(np.arange(n), k)
    ox, oy = np.ascontiguousarray(flat[:, 0]), np.ascontiguousarray(flat[:, 1])
    idx, cnt = np.empty((k * n, len(segs)), dtype=np.int64), np.empty(k * n, dtype=np.int64)
    fast = SonarRing(dataclasses.replace(cfg, model="fast"))
    fast_draws = [fast.draw(n, g) for g in rngs]
    parts = {
        "draws (K generator calls)": lambda: [ring.draw(n, g) for g in rngs],
        "whole realistic ring (readings)": lambda: ring.readings(poses, segs, radius, draws),
        "cone echoes + corners, robots as discs": lambda: simulate_beams(cfg, flat[:, :2], axes, segs, centres,
                                                                         radius, owner),
        "cone echoes + corners, no robots": lambda: simulate_beams(cfg, flat[:, :2], axes, segs, np.zeros((0, 2)),
                                                                   radius, np.full(k * n, -1)),
        "cone rays, no walls, no robots (overhead)": lambda: simulate_beams(cfg, flat[:, :2], axes, np.zeros((0, 4)),
                                                                            np.zeros((0, 2)), radius,
                                                                            np.full(k * n, -1)),
        "near-wall lists (range_max)": lambda: near_segments(ox, oy, segs, cfg.range_max + 1e-6, idx, cnt),
        "whole fast ring (readings)": lambda: fast.readings(poses, segs, radius, fast_draws),
    }
    print(f"tree, K = {k} worlds x {n} robots x {ring.n_beams} beams, {len(segs)} wall segments; "
          f"us per world (median of {args.repeats} x {args.calls} calls)")
    for label, fn in parts.items():
        print(f"  {label:40s} {per_world(fn, k, args.calls, args.repeats):8.1f}", flush=True)
    near_segments(ox, oy, segs, cfg.range_max + 1e-6, idx, cnt)
    print(f"walls within range_max of a robot: mean {cnt.mean():.1f}, max {cnt.max()} of {len(segs)}")


if __name__ == "__main__":
    main()

"""CPU time (not wall time) of one ``tree`` step and of its sonar parts: a before/after measure that
a loaded, shared machine disturbs less than wall-clock rates. Run it on two checkouts, one after
the other, and compare:

    PYTHONPATH=. python docs/lab/scripts/step_cpu.py            # this checkout
    PYTHONPATH=/path/to/other python docs/lab/scripts/step_cpu.py
    PYTHONPATH=. python docs/lab/scripts/step_cpu.py --frames   # Kinect frames mode

Prints the minimum over chunks (the least disturbed) of the process CPU time per call.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: an idle BLAS thread's spinning is process time

import numpy as np


def _best(fn, calls: int, chunks: int) -> float:
    fn()
    best = float("inf")
    for _ in range(chunks):
        t0 = time.process_time()
        for _ in range(calls):
            fn()
        best = min(best, (time.process_time() - t0) / calls)
    return best * 1e3


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="tree")
    p.add_argument("--steps", type=int, default=100, help="steps per chunk")
    p.add_argument("--chunks", type=int, default=3)
    p.add_argument("--frames", action="store_true", help="Kinect frames mode (render + full pipeline)")
    args = p.parse_args(argv)

    import parcover_env
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.sensors import sonar as sn

    env = ParallelCoverageEnv(args.scenario, overrides={"observation": {"kinect": "frames"}} if args.frames else None)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(20):
        env.step({a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents})
    poses, seg, radius = env.world.poses(), env.map.segments, env.scenario.robot.radius
    ring = env.sonar
    axes = poses[:, 2:3] + ring.beam_angles[None, :]
    owner = np.arange(len(poses))
    ring_ms = _best(lambda: sn.simulate_beams(ring.cfg, poses[:, :2], axes, seg, poses[:, :2], radius, owner,
                                              ring.n_subrays), 100, 5)
    talk_ms = _best(lambda: sn.crosstalk(ring.cfg, poses, ring.beam_angles, seg), 100, 5)
    acts = rng.uniform(-1, 1, (args.steps * args.chunks, env.n_robots, 2)).astype(np.float32)
    step_ms = float("inf")
    for c in range(args.chunks):
        t0 = time.process_time()
        for k in range(args.steps):
            if not env.agents:
                env.reset()
            env.step({a: acts[c * args.steps + k, i] for i, a in enumerate(env.agents)})
        step_ms = min(step_ms, (time.process_time() - t0) / args.steps * 1e3)
    print(f"{parcover_env.__file__}")
    label = args.scenario + (" frames" if args.frames else "")
    print(f"{label}: step {step_ms:.3f} ms CPU, sonar ring (noise-free, all robots) {ring_ms:.3f} ms, "
          f"cross-talk {talk_ms:.3f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""CPU time (not wall time) of the stepper's act phase and of a whole batched step, per world-step:
batched ``tree`` at ``K`` worlds (``make_vec_env(..., backend="batched")``), random actions. A
before/after measure that a loaded, shared machine disturbs less than wall-clock rates: run it on
two checkouts in turn and compare the minimum over chunks (the least disturbed).

    PYTHONPATH=. python benchmarks/act_cpu.py --ks 1,64             # this checkout
    PYTHONPATH=/path/to/other python benchmarks/act_cpu.py --ks 1,64
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: an idle BLAS thread's spinning is process time

import numpy as np


def measure(k: int, model: str, steps: int, chunks: int) -> tuple[float, float]:
    """Microseconds of CPU per world-step: the act phase alone, and the whole ``VecEnv.step``."""
    from parcover_env.envs import act_phase
    from parcover_env.envs.vec_env import make_vec_env

    venv = make_vec_env("tree", n_envs=k, overrides={"robot": {"sonar": {"model": model}}}, backend="batched",
                        monitor=False)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps * chunks + 10, venv.num_envs, *venv.action_space.shape)).astype(np.float32)
    for i in range(10):  # compile and warm up
        venv.step(acts[i])
    worlds, n = venv.worlds, venv.n_robots
    best_act = best_step = float("inf")
    for c in range(chunks):
        block = acts[10 + c * steps: 10 + (c + 1) * steps]
        t0 = time.process_time()
        for a in block:
            act_phase.act(worlds, a.reshape(k, n, -1))
        best_act = min(best_act, time.process_time() - t0)
        t0 = time.process_time()
        for a in block:
            venv.step(a)
        best_step = min(best_step, time.process_time() - t0)
    venv.close()
    per = 1e6 / (steps * k)
    return best_act * per, best_step * per


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ks", default="1,64", help="worlds per batch, comma separated")
    p.add_argument("--model", default="fast", help="sonar model: fast or specular")
    p.add_argument("--steps", type=int, default=0, help="steps per chunk (default: about 600 world-steps)")
    p.add_argument("--chunks", type=int, default=8)
    args = p.parse_args(argv)

    import parcover_env

    print(parcover_env.__file__)
    for k in (int(x) for x in args.ks.split(",")):
        act_us, step_us = measure(k, args.model, args.steps or max(600 // k, 8), args.chunks)
        print(f"tree batched {args.model} K={k:4d}: act phase {act_us:7.1f} us CPU per world-step, whole step "
              f"{step_us:7.1f} us (min of {args.chunks} chunks)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

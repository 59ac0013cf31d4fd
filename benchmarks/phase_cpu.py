"""CPU time (not wall time) per world-step of each stepper phase and of a whole batched step: batched
``tree`` at ``K`` worlds (``make_vec_env(..., backend="batched")``), random actions, the phases called as
``stepper.step`` calls them (act, score, observe, outputs) and the auto-resets, then ``VecEnv.step``
whole (``step``). A before/after measure for a loaded, shared machine: run it on two checkouts in turn
and compare the minimum over chunks (the least disturbed) phase by phase.

    PYTHONPATH=. python benchmarks/phase_cpu.py --ks 1,64 --model fast
    PYTHONPATH=/path/to/other python benchmarks/phase_cpu.py --ks 1,64 --model fast
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: an idle BLAS thread's spinning is process time

import numpy as np

PHASES = ("act", "score", "observe", "outputs", "resets")
"""The stepper's phases, timed one by one; the whole ``VecEnv.step`` is reported as ``step``."""


def measure(k: int, model: str, steps: int, chunks: int) -> dict[str, float]:
    """Microseconds of CPU per world-step of each phase and of a whole step (the minimum over ``chunks``
    of ``steps`` steps each)."""
    from parcover_env.envs import stepper
    from parcover_env.envs.vec_env import make_vec_env

    venv = make_vec_env("tree", n_envs=k, overrides={"robot": {"sonar": {"model": model}}}, backend="batched",
                        monitor=False)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps * chunks + 10, venv.num_envs, *venv.action_space.shape)).astype(np.float32)
    for a in acts[:10]:  # compile and warm up
        venv.step(a)
    worlds, n, clock = venv.worlds, venv.n_robots, time.process_time
    best = dict.fromkeys(PHASES, float("inf"))
    for c in range(chunks):
        total = dict.fromkeys(PHASES, 0.0)
        for a in acts[10 + c * steps: 10 + (c + 1) * steps]:
            t0 = clock()
            before, true = stepper.act(worlds, a.reshape(k, n, -1))
            t1 = clock()
            scores = stepper.score(worlds, before, true)
            t2 = clock()
            stepper.observe(worlds, true, scores)
            t3 = clock()
            getattr(stepper, "slot_outputs", stepper.outputs)(worlds, true, scores, active=True)  # what a VecEnv calls
            t4 = clock()
            for w in worlds:
                if not w.agents:
                    w.reset()
            t5 = clock()
            for name, dt in zip(PHASES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                total[name] += dt
        best = {name: min(best[name], total[name]) for name in PHASES}
        t0 = clock()
        for a in acts[10 + c * steps: 10 + (c + 1) * steps]:
            venv.step(a)
        best["step"] = min(best.get("step", float("inf")), clock() - t0)
    venv.close()
    return {name: v * 1e6 / (steps * k) for name, v in best.items()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ks", default="1,64", help="worlds per batch, comma separated")
    p.add_argument("--model", default="fast", help="sonar model: fast or specular")
    p.add_argument("--steps", type=int, default=0, help="steps per chunk (default: about 1200 world-steps)")
    p.add_argument("--chunks", type=int, default=6)
    args = p.parse_args(argv)

    import parcover_env

    print(parcover_env.__file__)
    for k in (int(x) for x in args.ks.split(",")):
        us = measure(k, args.model, args.steps or max(1200 // k, 20), args.chunks)
        parts = "  ".join(f"{name} {v:6.1f}" for name, v in us.items())
        print(f"tree batched {args.model} K={k:4d}: {parts}  (us CPU per world-step, min of {args.chunks} chunks)",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

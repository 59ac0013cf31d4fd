"""CPU time (not wall time) per world-step of each stepper phase and of a whole batched step: batched
``tree`` at ``K`` worlds (``make_vec_env(..., backend="batched")``), random actions, the phases called as
``stepper.step`` calls them (act, score, observe, outputs) and the auto-resets, then ``VecEnv.step``
whole (``step``). A before/after measure for a loaded, shared machine: run it on two checkouts in turn
and compare the minimum over chunks (the least disturbed) phase by phase, or let it run both at once
with ``--against``: one child process per checkout, their chunks taken in turn (A, B, A, B, ...), so
that both see the same minutes of a machine whose speed drifts.

    PYTHONPATH=. python docs/lab/scripts/phase_cpu.py --ks 1,64 --model fast
    PYTHONPATH=/path/to/other python docs/lab/scripts/phase_cpu.py --ks 1,64 --model fast
    python docs/lab/scripts/phase_cpu.py --ks 64 --model fast --against /path/to/other   # this checkout vs other
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: an idle BLAS thread's spinning is process time

import numpy as np

PHASES = ("act", "score", "observe", "outputs", "resets")
"""The stepper's phases, timed one by one; the whole ``VecEnv.step`` is reported as ``step``."""


def chunks(k: int, model: str, steps: int, count: int):
    """Set up batched ``tree`` at ``k`` worlds, then yield ``count`` chunks of ``steps`` steps each: per
    chunk, the seconds of CPU of each phase and of the whole ``VecEnv.step`` (``step``)."""
    from parcover_env.envs.vec_env import make_vec_env
    from parcover_env.sim import act_phase, outputs_phase, pipeline, score_phase

    venv = make_vec_env("tree", n_envs=k, overrides={"robot": {"sonar": {"model": model}}}, backend="batched",
                        monitor=False)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps * count + 10, venv.num_envs, *venv.action_space.shape)).astype(np.float32)
    for a in acts[:10]:  # compile and warm up
        venv.step(a)
    worlds, n, clock = venv.worlds, venv.n_robots, time.process_time
    for c in range(count):
        total = dict.fromkeys(PHASES, 0.0)
        for a in acts[10 + c * steps: 10 + (c + 1) * steps]:
            t0 = clock()
            acted = act_phase.act(worlds, a.reshape(k, n, -1))
            t1 = clock()
            scores = score_phase.score(worlds, acted)
            t2 = clock()
            pipeline.observe(worlds, acted.true, scores)
            t3 = clock()
            outputs_phase.slot_outputs(worlds, acted.true, scores, active=True)  # what a VecEnv calls
            t4 = clock()
            for w in worlds:
                if not w.agents:
                    w.reset()
            t5 = clock()
            for name, dt in zip(PHASES, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                total[name] += dt
        t0 = clock()
        for a in acts[10 + c * steps: 10 + (c + 1) * steps]:
            venv.step(a)
        total["step"] = clock() - t0
        yield total
    venv.close()


def measure(k: int, model: str, steps: int, count: int) -> dict[str, float]:
    """Microseconds of CPU per world-step of each phase and of a whole step (the minimum over ``count``
    chunks of ``steps`` steps each)."""
    best: dict[str, float] = {}
    for total in chunks(k, model, steps, count):
        best = {name: min(best.get(name, float("inf")), v) for name, v in total.items()}
    return {name: v * 1e6 / (steps * k) for name, v in best.items()}


def _serve(k: int, model: str, steps: int, count: int) -> None:
    """The child of ``--against``: one chunk per line read from stdin, its totals as a JSON line."""
    import json

    for total in chunks(k, model, steps, count):
        sys.stdin.readline()
        print(json.dumps(total), flush=True)


def against(other: str, k: int, model: str, steps: int, count: int) -> dict[str, dict[str, float]]:
    """:func:`measure` of this checkout and of the checkout at ``other`` in two child processes whose
    chunks run in turn; per checkout path, microseconds of CPU per world-step by phase."""
    import json
    import subprocess

    here = str(Path(__file__).resolve().parents[3])
    kids = {}
    for path in (here, other):
        env = dict(os.environ, PYTHONPATH=path)
        kids[path] = subprocess.Popen([sys.executable, __file__, "--serve", "--ks", str(k), "--model", model,
                                       "--steps", str(steps), "--chunks", str(count)], env=env,
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    best: dict[str, dict[str, float]] = {path: {} for path in kids}
    for _ in range(count):
        for path, kid in kids.items():
            kid.stdin.write("go\n")
            kid.stdin.flush()
            total = json.loads(kid.stdout.readline())
            best[path] = {name: min(best[path].get(name, float("inf")), v) for name, v in total.items()}
    for kid in kids.values():
        kid.stdin.close()
        kid.wait()
    return {path: {name: v * 1e6 / (steps * k) for name, v in b.items()} for path, b in best.items()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ks", default="1,64", help="worlds per batch, comma separated")
    p.add_argument("--model", default="fast", help="sonar model: fast or specular")
    p.add_argument("--steps", type=int, default=0, help="steps per chunk (default: about 1200 world-steps)")
    p.add_argument("--chunks", type=int, default=6)
    p.add_argument("--against", default="", help="another checkout: both measured, their chunks in turn")
    p.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    ks = [int(x) for x in args.ks.split(",")]
    if args.serve:
        _serve(ks[0], args.model, args.steps, args.chunks)
        return 0

    import parcover_env

    print(parcover_env.__file__)
    for k in ks:
        steps = args.steps or max(1200 // k, 20)
        runs = against(args.against, k, args.model, steps, args.chunks) if args.against else \
            {"": measure(k, args.model, steps, args.chunks)}
        for path, us in runs.items():
            parts = "  ".join(f"{name} {v:6.1f}" for name, v in us.items())
            print(f"tree batched {args.model} K={k:4d}: {parts}  (us CPU per world-step, min of {args.chunks} chunks)"
                  + (f"  {path}" if path else ""), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""How many package files run Python code in one ``env.step`` (issue 41's measure of the engine's spread).

A ``sys.setprofile`` hook records the file of every Python function called while the env steps
(compiled numba kernels and C functions have no Python frame, so they do not count; the file that
calls them does). The env is stepped a few times first (numba compiles, caches fill), then each of
``--steps`` steps is counted on its own; the table lists every package file that ran in any of
them with the number of Python calls per step, and the summary gives the union and the largest
single step. ``tests/architecture/test_step_files.py`` keeps the union from growing (a ratchet).

    PYTHONPATH=. python benchmarks/step_files.py                 # tree, 5 counted steps
    PYTHONPATH=. python benchmarks/step_files.py --scenario office --steps 20
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

import parcover_env

PACKAGE = Path(parcover_env.__file__).resolve().parent


def _package_file(filename: str) -> str | None:
    """``filename`` as ``parcover_env/envs/parallel.py`` when it is a file of the package, else None."""
    path = Path(filename)
    if path.suffix != ".py" or not path.is_absolute():  # <string>, <frozen ...>: not a package file
        return None
    try:  # relative to the package itself: a virtualenv inside the checkout (.venv/lib/...) is not the package
        return (PACKAGE.name / path.resolve().relative_to(PACKAGE)).as_posix()
    except ValueError:
        return None


def count_step_files(scenario: str = "tree", steps: int = 5, warmup: int = 3, seed: int = 0) -> list[Counter]:
    """Per counted step: the package files whose Python code ran in ``env.step``, with their call counts.

    The env is ``parcover_env.parallel_env(scenario)`` reset with ``seed``; every step takes the
    same moderate forward command for all robots (the count is about the code path, not the policy)."""
    env = parcover_env.parallel_env(scenario)
    env.reset(seed=seed)
    space = env.action_space(env.possible_agents[0])
    action = np.zeros(space.shape, dtype=space.dtype)
    action[:2] = (0.5, 0.1)
    actions = dict.fromkeys(env.possible_agents, action)
    for _ in range(warmup):
        env.step(actions)
    files_of: dict[str, str | None] = {}
    per_step = []
    for _ in range(steps):
        calls: Counter = Counter()

        def hook(frame, event, arg, calls=calls):
            if event == "call":
                name = frame.f_code.co_filename
                if name not in files_of:
                    files_of[name] = _package_file(name)
                if files_of[name] is not None:
                    calls[files_of[name]] += 1

        sys.setprofile(hook)
        try:
            env.step(actions)
        finally:
            sys.setprofile(None)
        per_step.append(calls)
    return per_step


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="tree")
    p.add_argument("--steps", type=int, default=5, help="steps counted (after the warm-up)")
    p.add_argument("--warmup", type=int, default=3, help="steps taken before counting")
    args = p.parse_args(argv)
    per_step = count_step_files(args.scenario, args.steps, args.warmup)
    files = sorted(set().union(*per_step))
    print(f"# package files running Python code in one env.step of {args.scenario} "
          f"({args.steps} steps counted after {args.warmup})\n")
    print("| file | calls per step (min-max) |")
    print("|---|---|")
    for f in files:
        counts = [c.get(f, 0) for c in per_step]
        print(f"| {f} | {min(counts)}-{max(counts)} |")
    print(f"\nfiles in any counted step: {len(files)}; most in one step: {max(len(c) for c in per_step)}")


if __name__ == "__main__":
    main()

"""Shared pieces of the throughput benchmarks: timing, memory readings, and the runners that step our env
and its peers (MPE2, VMAS) with pre-drawn random actions (used by ``throughput.py``, ``batching.py``,
``memory_soak.py`` and the lab script ``docs/lab/scripts/profile_step.py``)."""

from __future__ import annotations

import functools
import gc
import os
import resource
import time
from collections.abc import Callable

import numpy as np

__all__ = ["Timers", "rss_mb", "peak_rss_mb", "timed_chunks", "ParallelRunner", "measure_parallel", "our_env", "merge",
           "peer_mpe", "VmasRunner", "VecRunner", "VmasBatchedRunner"]


def rss_mb() -> float:
    """Current resident set size (MiB)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far (MiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def timed_chunks(step: Callable[[int], None], steps: int, repeats: int, warmup: int = 20) -> float:
    """Median seconds per call of ``step(k)`` over ``repeats`` chunks of ``steps`` calls."""
    for k in range(warmup):
        step(k)
    times = []
    for _ in range(repeats):
        gc.collect()
        t0 = time.perf_counter()
        for k in range(steps):
            step(k)
        times.append((time.perf_counter() - t0) / steps)
    return float(np.median(times))


class ParallelRunner:
    """Steps a PettingZoo ParallelEnv with pre-drawn random actions; resets are not timed."""

    def __init__(self, env, rng: np.random.Generator, n_actions: int = 4096):
        self.env = env
        self.env.reset(seed=0)
        self.agents = list(env.possible_agents)
        self.reset_time = 0.0
        space = env.action_space(self.agents[0])
        if hasattr(space, "n"):
            self.actions = rng.integers(0, space.n, (n_actions, len(self.agents)))
        else:
            self.actions = rng.uniform(space.low, space.high, (n_actions, len(self.agents), *space.shape))
            self.actions = self.actions.astype(space.dtype)

    def __call__(self, k: int) -> None:
        env = self.env
        if not env.agents:
            t0 = time.perf_counter()
            env.reset()
            self.reset_time += time.perf_counter() - t0
        a = self.actions[k % len(self.actions)]
        env.step({name: a[i] for i, name in enumerate(self.agents) if name in env.agents})


def measure_parallel(env, steps: int, repeats: int, seed: int = 0) -> dict:
    run = ParallelRunner(env, np.random.default_rng(seed))
    t0 = time.perf_counter()
    sec = timed_chunks(run, steps, repeats)
    total = time.perf_counter() - t0
    # resets happen inside the chunks: take their share out of the per-step figure
    n_calls = steps * repeats + 20
    sec = max(sec - run.reset_time / n_calls, 1e-9)
    n = len(run.agents)
    return {"n_agents": n, "sec_per_step": sec, "env_steps_s": 1.0 / sec, "agent_steps_s": n / sec,
            "wall": total}

def our_env(scenario: str, overrides: dict | None):
    from parcover_env.envs import ParallelCoverageEnv

    return ParallelCoverageEnv(scenario, overrides=overrides or None)


def merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out

def peer_mpe(n: int):
    from mpe2 import simple_spread_v3

    return simple_spread_v3.parallel_env(N=n, max_cycles=25, continuous_actions=False)


class VmasRunner:
    """VMAS ``navigation``: one env on the CPU, random continuous actions (torch tensors)."""

    def __init__(self, n_agents: int, seed: int = 0):
        import torch
        import vmas

        torch.manual_seed(seed)
        self.env = vmas.make_env("navigation", num_envs=1, device="cpu", continuous_actions=True,
                                 n_agents=n_agents, seed=seed)
        self.env.reset()
        self.n_agents = n_agents
        g = torch.Generator().manual_seed(seed)
        self.actions = [[torch.rand((1, 2), generator=g) * 2 - 1 for _ in range(n_agents)]
                        for _ in range(256)]

    def __call__(self, k: int) -> None:
        _, _, done, _ = self.env.step(self.actions[k % len(self.actions)])
        if bool(done.any()):
            self.env.reset()

class VecRunner:
    """Steps an SB3 VecEnv with pre-drawn random actions (auto-resets inside, as in training)."""

    def __init__(self, venv, seed: int = 0):
        self.venv = venv
        venv.seed(seed)
        venv.reset()
        rng = np.random.default_rng(seed)
        self.actions = rng.uniform(-1, 1, (32, venv.num_envs, 2)).astype(np.float32)

    def __call__(self, k: int) -> None:
        self.venv.step(self.actions[k % len(self.actions)])


class VmasBatchedRunner:
    """VMAS ``navigation`` with ``num_envs`` vectorized worlds on the CPU, random actions."""

    def __init__(self, num_envs: int, n_agents: int = 4, seed: int = 0):
        import torch
        import vmas

        torch.manual_seed(seed)
        self.env = vmas.make_env("navigation", num_envs=num_envs, device="cpu", continuous_actions=True,
                                 n_agents=n_agents, seed=seed)
        self.env.reset()
        self.n_agents, self.num_envs = n_agents, num_envs
        g = torch.Generator().manual_seed(seed)
        self.actions = [[torch.rand((num_envs, 2), generator=g) * 2 - 1 for _ in range(n_agents)]
                        for _ in range(32)]

    def __call__(self, k: int) -> None:
        _, _, done, _ = self.env.step(self.actions[k % len(self.actions)])
        if bool(done.any()):  # reset only the finished worlds, as VMAS training loops do
            for i in done.nonzero().flatten().tolist():
                self.env.reset_at(i)


class Timers:
    """Wall-clock totals of wrapped callables (nested parts are counted in their parents too)."""

    def __init__(self):
        self.total: dict[str, float] = {}

    def wrap(self, obj, attr: str, label: str) -> None:
        fn = getattr(obj, attr)

        @functools.wraps(fn)
        def timed(*a, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                self.total[label] = self.total.get(label, 0.0) + time.perf_counter() - t0

        setattr(obj, attr, timed)

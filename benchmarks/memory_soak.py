"""The memory section of ``throughput.py``: RSS sampled over a long soak of one ParallelEnv (``office``) and
of the batched backend (``office``, K = 16), with a linear fit and the RSS after ``malloc_trim``."""

from __future__ import annotations

import gc
import time
from collections.abc import Callable

import numpy as np
from runners import ParallelRunner, VecRunner, our_env, peak_rss_mb, rss_mb


def soak(step: Callable[[int], None], total: int) -> dict:
    """RSS sampled 10 times over ``total`` calls of ``step`` (after a warm-up) and its linear fit."""
    for k in range(min(500, max(total // 10, 1))):
        step(k)
    gc.collect()
    samples = []
    chunk = max(total // 10, 1)
    t0 = time.perf_counter()
    for i in range(10):
        for k in range(chunk):
            step(i * chunk + k)
        samples.append(rss_mb())
        print(f"    soak sample {i + 1}/10 after {(i + 1) * chunk} calls: RSS {samples[-1]:.1f} MiB "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    x = np.arange(len(samples)) * chunk
    slope = float(np.polyfit(x, samples, 1)[0]) * 1e6 if len(samples) > 1 else 0.0
    gc.collect()
    return {"soak_steps": chunk * 10, "rss_start_mb": samples[0], "rss_end_mb": samples[-1],
            "slope_mb_per_1e6_steps": slope, "rss_trimmed_mb": trimmed_rss()}


def trimmed_rss() -> float:
    """RSS (MiB) after glibc's ``malloc_trim(0)`` returned the allocator's free pages (NaN elsewhere):
    what is left is memory in use, the rest of a growth was allocator slack."""
    import ctypes
    import ctypes.util

    try:
        ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        return float("nan")
    return rss_mb()


def section_memory(args, results: dict) -> None:
    r: dict = {}
    if not args.soak_batched_only:
        run = ParallelRunner(our_env("office", {}), np.random.default_rng(1))
        r = soak(run, args.soak)
        print(f"  office soak {r['soak_steps']} steps: RSS {r['rss_start_mb']:.1f} -> {r['rss_end_mb']:.1f} MiB "
              f"(fit {r['slope_mb_per_1e6_steps']:+.2f} MiB per 10^6 steps)", flush=True)
    from parcover_env.envs.vec_env import make_vec_env

    k = 16
    venv = make_vec_env("office", k, backend="batched", monitor=False)
    b = soak(VecRunner(venv), max(args.soak // k, 10))
    b["K"], b["world_steps"] = k, b["soak_steps"] * k
    venv.close()
    print(f"  office batched K={k} soak {b['world_steps']} world-steps: RSS {b['rss_start_mb']:.1f} -> "
          f"{b['rss_end_mb']:.1f} MiB (fit {b['slope_mb_per_1e6_steps'] / k:+.2f} MiB per 10^6 world-steps), "
          f"{b['rss_trimmed_mb']:.1f} MiB after malloc_trim", flush=True)
    r["batched"] = b
    r["peak_rss_mb"] = peak_rss_mb()
    print(f"  peak RSS of this whole run {r['peak_rss_mb']:.0f} MiB", flush=True)
    results["memory"] = r

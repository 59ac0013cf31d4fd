"""The ``batching`` section of ``benchmarks/throughput.py`` (issue 31): does batching pay?

For both sonar models (``specular``, the realistic default, and ``fast``) and each K of ``--ks``:
``make_vec_env("tree", n_envs=K, backend="batched")`` with random actions, world-steps/s and
agent-steps/s, then VMAS ``navigation`` (4 agents, CPU, ``--torch-threads`` torch threads) at the
same K right after (ratios side by side in time: the machine's load moves). The memory per world is
measured in a fresh process per model and K (so that no freed memory of an earlier run is reused):
its RSS growth from building, resetting and stepping the K worlds 5 times, over K, after a K = 1
run loaded the imports and compiled kernels. Per model at the largest K, the breakdown of a
world-step (physics = each world's ``World.step``, sonar = the rings' draws and their one compiled
call, act = the stepper's act phase of all worlds (of it physics, the drives and the pose estimators),
score and outputs = those stepper phases of all worlds, the rest = everything else), timed in a
separate run with wrapped calls. The issue's K = 64
targets are printed beside the figures, met or not, from a paired run (specular K = 1 and 64, fast
K = 64 and VMAS 64 built together and timed in turn, at least 3 times, every timed chunk about
``PAIRED_CHUNK_S`` long whatever ``--steps`` says); a single ``tree`` env and
MPE2 ``simple_spread`` N = 10 are measured here, alternately, for the single-env target.

    .venv/bin/python benchmarks/throughput.py --sections batching --ks 1,4,16,64,256
    .venv/bin/python benchmarks/throughput.py --sections batching --ks 1,64 --steps 60 --repeats 1
"""

from __future__ import annotations

import gc
import time

from runners import Timers, VecRunner, VmasBatchedRunner, measure_parallel, our_env, peer_mpe, rss_mb, timed_chunks

MODELS = ("specular", "fast")
"""Sonar models compared; ``specular`` is the shipped default."""
REALISTIC_SELF = 2.0
"""Target: realistic sonar, K = 64 >= 2x K = 1 in agent-steps/s."""
REALISTIC_VMAS = 1.0
"""Target: realistic sonar, K = 64 >= 1x VMAS navigation 64 envs (CPU) in agent-steps/s."""
FAST_VMAS = 2.0
"""Target: fast sonar, K = 64 >= 2x VMAS navigation 64 envs."""
SINGLE_MPE = 5.0
"""Target: single env ``tree`` >= 5x MPE2 simple_spread N = 10 in agent-steps/s."""
PAIRED_CHUNK_S = 0.5
"""Seconds of each timed chunk of the paired run, the same for every set-up: a chunk of a few steps right
after another set-up's chunk would weigh the switch (caches, the collector) more for the faster set-ups."""


def _chunk_steps(run, seconds: float) -> int:
    """Steps of ``run`` that take about ``seconds`` (timed on a quarter of that, at least 3 steps)."""
    t0, n = time.perf_counter(), 0
    while n < 3 or time.perf_counter() - t0 < seconds / 4:
        run(n)
        n += 1
    return max(round(seconds * n / (time.perf_counter() - t0)), 3)


def _venv(model: str, k: int):
    from parcover_env.envs.vec_env import make_vec_env

    return make_vec_env("tree", n_envs=k, overrides={"robot": {"sonar": {"model": model}}}, backend="batched",
                        monitor=False)


def _stepped(model: str, k: int, steps: int) -> None:
    venv = _venv(model, k)
    run = VecRunner(venv)
    for i in range(steps):
        run(i)
    venv.close()


def mib_per_world(model: str, k: int) -> float:
    """RSS growth (MiB) per world of building and stepping ``k`` worlds, in this (fresh) process."""
    _stepped(model, 1, 5)
    gc.collect()
    before = rss_mb()
    venv = _venv(model, k)
    run = VecRunner(venv)
    for i in range(5):
        run(i)
    return (rss_mb() - before) / k


def _memory(model: str, k: int) -> float:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(mib_per_world, model, k).result()


def _row(model: str, k: int, steps: int, repeats: int) -> dict:
    gc.collect()
    venv = _venv(model, k)
    try:
        sec = timed_chunks(VecRunner(venv), steps, repeats, warmup=5)
    finally:
        venv.close()
    r = {"model": model, "K": k, "slots": venv.num_envs, "world_steps_s": k / sec, "agent_steps_s": venv.num_envs / sec,
         "mib_per_world": _memory(model, k)}
    print(f"  tree batched {model:8s} K={k:4d}  {r['world_steps_s']:9.1f} world-steps/s  {r['agent_steps_s']:9.0f} "
          f"agent-steps/s  {1e6 / r['world_steps_s']:7.1f} us/world-step  {r['mib_per_world']:6.2f} MiB/world",
          flush=True)
    del venv
    gc.collect()
    return r


def breakdown(model: str, k: int, steps: int) -> dict:
    """Microseconds per world-step of the stepper's act phase (physics, drives, pose estimators in
    it), sonar, the score and outputs phases (all worlds at once) and the rest, batched ``tree`` at
    ``k`` worlds."""
    from parcover_env.sim import act_phase, outputs_phase, score_phase

    # the phases a VecEnv step makes (parcover_env.sim.pipeline.step calls them through their modules)
    calls = {"act": (act_phase, "act"), "score": (score_phase, "score"), "outputs": (outputs_phase, "slot_outputs")}
    phases = {name: getattr(module, call) for name, (module, call) in calls.items()}
    inner = {name: getattr(act_phase, name) for name in ("step_all", "command_steps_rows", "update_all")}
    venv = _venv(model, k)
    try:
        run = VecRunner(venv)
        for i in range(5):
            run(i)
        clock, seen = Timers(), set()
        clock.wrap(act_phase, "step_all", "physics")  # every world's pymunk substeps
        for w in venv.worlds:
            if w.sonar is not None and id(w.sonar) not in seen:
                seen.add(id(w.sonar))
                clock.wrap(w.sonar, "draw", "sonar")
                clock.wrap(w.sonar, "readings", "sonar")
        for name, (module, call) in calls.items():
            clock.wrap(module, call, name)
        clock.wrap(act_phase, "command_steps_rows", "drives")
        clock.wrap(act_phase, "update_all", "estimators")
        t0 = time.perf_counter()
        for i in range(steps):
            run(i)
        total = time.perf_counter() - t0
    finally:
        for name, fn in phases.items():
            setattr(*calls[name], fn)
        for name, fn in inner.items():
            setattr(act_phase, name, fn)
        venv.close()
    per = 1e6 / (steps * k)
    out = {"model": model, "K": k, "total_us": total * per}
    for part in ("sonar", *phases):
        out[f"{part}_us"] = clock.total.get(part, 0.0) * per
    out["rest_us"] = out["total_us"] - sum(out[f"{part}_us"] for part in ("sonar", *phases))
    print(f"  breakdown {model:8s} K={k:4d}: {out['total_us']:7.1f} us/world-step "
          f"= act {out['act_us']:6.1f} + sonar {out['sonar_us']:6.1f} + score {out['score_us']:6.1f} "
          f"+ outputs {out['outputs_us']:6.1f} + rest {out['rest_us']:6.1f} (wrapped calls)", flush=True)
    for part in ("physics", "drives", "estimators"):
        out[f"{part}_us"] = clock.total.get(part, 0.0) * per
    print(f"    act phase: physics {out['physics_us']:6.1f}, drives {out['drives_us']:6.1f}, pose estimators "
          f"(odometry, Kinect systems, fixes) {out['estimators_us']:6.1f}", flush=True)
    return out


def _vmas(k: int, steps: int, repeats: int) -> dict | None:
    try:
        run = VmasBatchedRunner(k)
    except ImportError as exc:
        print(f"  VMAS navigation: not installed ({exc}); pip install vmas", flush=True)
        return None
    sec = timed_chunks(run, steps, repeats, warmup=5)
    v = {"K": k, "world_steps_s": k / sec, "agent_steps_s": k * run.n_agents / sec}
    print(f"  vmas navigation 4 agents  K={k:4d}  {v['world_steps_s']:9.1f} world-steps/s  "
          f"{v['agent_steps_s']:9.0f} agent-steps/s", flush=True)
    return v


def _single_and_mpe(args) -> tuple[dict, dict | None]:
    """A single ``tree`` env and MPE2 simple_spread N = 10, measured alternately ``--repeats`` times
    (chunks of ``--steps``; the median of each)."""
    try:
        mpe_env = peer_mpe(10)
    except ImportError as exc:
        print(f"  MPE2: not installed ({exc}); pip install mpe2", flush=True)
        mpe_env = None
    tree = our_env("tree", None)
    ours, peer = [], []
    for _ in range(args.repeats):
        ours.append(measure_parallel(tree, args.steps, 1))
        if mpe_env is not None:
            peer.append(measure_parallel(mpe_env, args.steps * 2, 1))
    single = sorted(ours, key=lambda r: r["agent_steps_s"])[len(ours) // 2]
    print(f"  single env tree (specular)     {single['agent_steps_s']:9.0f} agent-steps/s", flush=True)
    if not peer:
        return single, None
    mpe = sorted(peer, key=lambda r: r["agent_steps_s"])[len(peer) // 2]
    print(f"  mpe2 simple_spread N=10        {mpe['agent_steps_s']:9.0f} agent-steps/s", flush=True)
    return single, mpe


def _paired(repeats: int) -> dict[str, float]:
    """Agent-steps/s of the target pairs (specular K = 1 and 64, fast K = 64, VMAS 64), all built
    first, then timed in turn ``max(repeats, 3)`` times in chunks of about :data:`PAIRED_CHUNK_S` each:
    the median of each. Side by side in time, so a change of the machine's load moves them alike."""
    runners = {"specular 1": _venv("specular", 1), "specular 64": _venv("specular", 64), "fast 64": _venv("fast", 64)}
    calls = {name: VecRunner(v) for name, v in runners.items()}
    slots = {name: v.num_envs for name, v in runners.items()}
    try:
        vmas = VmasBatchedRunner(64)
        calls["vmas 64"], slots["vmas 64"] = vmas, 64 * vmas.n_agents
    except ImportError:
        pass
    n_steps = {name: _chunk_steps(run, PAIRED_CHUNK_S) for name, run in calls.items()}
    seen: dict[str, list[float]] = {name: [] for name in calls}
    for _ in range(max(repeats, 3)):
        for name, run in calls.items():
            seen[name].append(slots[name] / timed_chunks(run, n_steps[name], 1, warmup=2))
    for v in runners.values():
        v.close()
    out = {name: float(sorted(v)[len(v) // 2]) for name, v in seen.items()}
    print("  paired (timed in turn, median agent-steps/s): "
          + ", ".join(f"{name} {value:.0f}" for name, value in out.items()), flush=True)
    return out


def _target(label: str, value: float, target: float) -> None:
    print(f"  TARGET {label}: {value:.2f}x (target >= {target:g}x)  {'MET' if value >= target else 'NOT MET'}",
          flush=True)


def section_batching(args, results: dict) -> None:
    ks = [int(x) for x in args.ks.split(",") if x.strip()]
    steps = max(args.steps // 10, 5)
    out: dict = {"rows": [], "vmas": [], "breakdown": []}
    for model in MODELS:  # imports, compiled kernels and caches first
        _stepped(model, 1, 5)
    for k in ks:
        for model in MODELS:
            out["rows"].append(_row(model, k, max(steps * 16 // k, 3), args.repeats))
        v = _vmas(k, max(steps * 16 // k, 3) * 4, args.repeats)
        if v:
            out["vmas"].append(v)
    for model in MODELS:
        out["breakdown"].append(breakdown(model, max(ks), max(steps * 16 // max(ks), 3) * args.repeats))
    single, mpe = _single_and_mpe(args)
    rows = {(r["model"], r["K"]): r for r in out["rows"]}
    vmas = {v["K"]: v for v in out["vmas"]}
    print("  per-world speed-up over K=1 (world-steps/s): " + "; ".join(
        f"{m} " + ", ".join(f"K={k}: {rows[m, k]['world_steps_s'] / rows[m, ks[0]]['world_steps_s']:.2f}x"
                            for k in ks) for m in MODELS), flush=True)
    for k in ks:
        if k in vmas:
            print(f"  K={k:4d} ours / VMAS agent-steps/s: " + ", ".join(
                f"{m} {rows[m, k]['agent_steps_s'] / vmas[k]['agent_steps_s']:.2f}x" for m in MODELS), flush=True)
    if 1 in ks and 64 in ks:
        paired = _paired(args.repeats)
        out["paired"] = paired
        _target("realistic K=64 / K=1 agent-steps/s", paired["specular 64"] / paired["specular 1"], REALISTIC_SELF)
        if "vmas 64" in paired:
            _target("realistic K=64 / VMAS navigation 64", paired["specular 64"] / paired["vmas 64"], REALISTIC_VMAS)
            _target("fast K=64 / VMAS navigation 64", paired["fast 64"] / paired["vmas 64"], FAST_VMAS)
    if mpe:
        _target("single env tree / MPE2 simple_spread N=10", single["agent_steps_s"] / mpe["agent_steps_s"],
                SINGLE_MPE)
    out["single_tree"], out["mpe10"] = single, mpe
    results["batching"] = out

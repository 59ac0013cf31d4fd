"""Env throughput: env-steps/s and agent-steps/s of parcover_env next to its peers and its floor.

All figures come from ONE run on one machine, so the ratios are side by side (absolute numbers
move with the machine and its load; the ratios much less). Every timing is the median of
``--repeats`` chunks of ``--steps`` steps with random actions (drawn up front, seeded); episode
resets are excluded from the timed chunks.

Sections (``--sections``, comma separated; default all):

* ``ours``    - scenarios ``office``, ``tree`` and a generated 30-robot map (``generated:1``), in three
  modes: ``default`` (as shipped: Kinect estimate model, 16-beam ring), ``frames`` (every Kinect
  renders depth + IR at its rate and the full marker pipeline runs), ``sonar72`` (72-beam ring,
  specular model: the seed-B 360-degree scan on every robot, every step). ``x RT`` = simulated
  seconds per wall-clock second.
* ``peers``   - PettingZoo MPE2 ``simple_spread`` (N=3, N=10) and VMAS ``navigation`` (4 agents,
  lidar, 1 env, CPU), when installed (``pip install mpe2 vmas``); ratios ours (``tree``) / peer
  in agent-steps/s.
* ``floor``   - per scenario: pymunk ``space.step`` alone (same walls and robots, no callbacks,
  ``substeps`` steps per control step) plus the vectorized ray casting alone (same beams, walls
  and robot discs); ours / floor in time per step (1.0 = no overhead at all).
* ``scaling`` - a 20 m x 20 m open box with 2, 8, 16, 32, 64 robots (env-steps/s, time per robot).
* ``vec``     - the SB3 adapter (``parcover_env.envs.vec_env``): 1 env in-process vs 2 worker processes.
* ``batched`` - ``make_vec_env("tree", n_envs=K, backend="batched")`` for K = 1, 4, 16, 64 (agent-steps/s
  and the speed-up over K separate in-process worlds, measured at K = 4), team-size scaling of the
  batched backend (open box, K = 16), and VMAS ``navigation`` batched (``num_envs`` 64, 4 agents,
  CPU) for the K = 64 ratio.
* ``batching`` - issue 31 in one run (``benchmarks/batching.py``): batched ``tree`` at K of ``--ks``
  (default 1, 4, 16, 64, 256) for the specular and the ``fast`` sonar model, VMAS ``navigation`` at the
  same K, memory per world, the physics / sonar / rest breakdown of a world-step, and the issue's
  targets beside the figures.
* ``memory``  - peak RSS, and RSS sampled over ``--soak`` env-steps on ``office`` (one ParallelEnv) and
  over ``--soak`` world-steps of the batched backend (``office``, K = 16); ``--soak 1000000`` for
  the 10^6-step soak (``--soak-batched-only``: the batched one alone).

    .venv/bin/python benchmarks/throughput.py                 # everything (~5 min on 2 cores)
    .venv/bin/python benchmarks/throughput.py --quick         # short chunks, a smoke run
    .venv/bin/python benchmarks/throughput.py --sections ours,peers --json out.json
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable

import numpy as np
from memory_soak import section_memory
from runners import (
    VecRunner,
    VmasBatchedRunner,
    VmasRunner,
    measure_parallel,
    merge,
    our_env,
    peer_mpe,
    timed_chunks,
)

TREE_TARGET_MPE = 5.0
"""Target: tree agent-steps/s >= 5x MPE2 simple_spread N=10."""
TREE_TARGET_FLOOR = 4.0
"""Target: tree within 4x of the physics + ray-casting floor."""
FRAMES_TARGET_RT = 20.0
"""Target: Kinect frames mode on tree >= 20x real time."""
BATCHED_TARGET_VMAS = 2.0
"""Target: batched tree, K = 64, >= 2x VMAS navigation (num_envs 64, CPU) in agent-steps/s."""
BATCHED_KS = (1, 4, 16, 64)
"""Worlds per process of the batched section."""

MODES: dict[str, dict] = {
    "default": {},
    "frames": {"observation": {"kinect": "frames"}},
    "sonar72": {"robot": {"sonar": {"layout": "ring", "n_beams": 72, "model": "specular"}}},
}


# ---------------------------------------------------------------------------------------- timing

# ---------------------------------------------------------------------------------------- ours

SCENARIOS: dict[str, tuple[str, dict]] = {
    "office": ("office", {}),
    "tree": ("tree", {}),
    # the generated queue is too short for 30 robots at the default 0.4 m spacing: 0.32 m fits it
    "generated-30": ("generated:1", {"n_robots": 30, "formation": {"spacing": 0.32}}),
}


def section_ours(args, results: dict) -> None:
    rows = []
    for label, (scen, base) in SCENARIOS.items():
        for mode, extra in MODES.items():
            try:
                env = our_env(scen, merge(base, extra))
            except Exception as exc:  # noqa: BLE001 - report and go on
                print(f"  {label:13s} {mode:8s} unavailable: {exc}", flush=True)
                continue
            steps = args.steps if mode != "frames" else max(args.steps // 4, 20)
            r = measure_parallel(env, steps, args.repeats)
            dt = env.scenario.physics.control_dt
            r.update(scenario=label, mode=mode, realtime=dt / r["sec_per_step"],
                     n_kinects=len(env.scenario.kinects), n_beams=env.sonar.n_beams if env.sonar else 0)
            rows.append(r)
            print(f"  {label:13s} {mode:8s} N={r['n_agents']:3d}  {r['env_steps_s']:8.1f} env-steps/s  "
                  f"{r['agent_steps_s']:9.0f} agent-steps/s  {1e3 * r['sec_per_step']:7.2f} ms/step  "
                  f"{r['realtime']:7.1f} x RT", flush=True)
            del env
            gc.collect()
    results["ours"] = rows


# ---------------------------------------------------------------------------------------- peers

def print_peer(r: dict) -> None:
    print(f"  {r['peer']:28s} {r['env_steps_s']:9.1f} env-steps/s  {r['agent_steps_s']:9.0f} agent-steps/s",
          flush=True)


def section_peers(args, results: dict) -> None:
    rows = []
    for n in (3, 10):
        try:
            env = peer_mpe(n)
        except ImportError as exc:
            print(f"  MPE2 simple_spread N={n}: not installed ({exc}); pip install mpe2", flush=True)
            continue
        r = measure_parallel(env, args.steps * 2, args.repeats)
        r.update(peer=f"mpe2 simple_spread N={n}")
        rows.append(r)
        print_peer(r)
    try:
        run = VmasRunner(4)
    except ImportError as exc:
        print(f"  VMAS navigation: not installed ({exc}); pip install vmas", flush=True)
    else:
        sec = timed_chunks(run, args.steps, args.repeats)
        r = {"peer": "vmas navigation 4 agents", "n_agents": 4, "sec_per_step": sec,
             "env_steps_s": 1 / sec, "agent_steps_s": 4 / sec}
        rows.append(r)
        print_peer(r)
    results["peers"] = rows
    ours = {(r["scenario"], r["mode"]): r for r in results.get("ours", [])}
    tree = ours.get(("tree", "default"))
    if tree:
        for r in rows:
            ratio = tree["agent_steps_s"] / r["agent_steps_s"]
            r["ratio_tree"] = ratio
            target = f"  (target >= {TREE_TARGET_MPE:.0f}x)" if r["peer"].endswith("N=10") else ""
            print(f"  tree / {r['peer']:28s} = {ratio:6.2f}x agent-steps/s{target}", flush=True)


# ---------------------------------------------------------------------------------------- floor
def floor_step(scenario: str, overrides: dict | None):
    """A step function doing only the physics (pymunk, no callbacks) and ray casting of ``scenario``."""
    import pymunk

    from parcover_env.geometry import cast_rays, cast_rays_discs
    from parcover_env.world.physics import World

    env = our_env(scenario, overrides)
    env.reset(seed=0)
    s = env.scenario
    world = World(env.map, s.robot.radius, s.physics, env.world.poses())
    for b in world.bodies:
        b.velocity_func = pymunk.Body.update_velocity
    space, bodies, dt, sub = world.space, world.bodies, s.physics.dt, s.physics.substeps
    segments = env.map.segments
    beams = env.sonar.beam_angles if env.sonar else np.zeros(0)
    rmax = s.robot.sonar.range_max
    n, b = len(bodies), len(beams)
    owner = np.repeat(np.arange(n), b)
    rng = np.random.default_rng(0)
    cmds = rng.uniform(-1, 1, (256, n, 2)) * (s.robot.max_speed, s.robot.max_turn_rate)

    def step(k: int) -> None:
        c = cmds[k % len(cmds)]
        for body, (v, w) in zip(bodies, c.tolist(), strict=True):
            a = body.angle
            body.velocity = (v * math.cos(a), v * math.sin(a))
            body.angular_velocity = w
        for _ in range(sub):
            space.step(dt)
        if b:
            xy = np.array([tuple(bd.position) for bd in bodies])
            th = np.array([bd.angle for bd in bodies])
            ang = (th[:, None] + beams[None, :]).ravel()
            d = np.stack([np.cos(ang), np.sin(ang)], axis=1)
            o = np.repeat(xy, b, axis=0)
            dist = cast_rays(o, d, segments, rmax).distance
            np.minimum(dist, cast_rays_discs(o, d, xy, s.robot.radius, owner, rmax))

    return step, n


def section_floor(args, results: dict) -> None:
    ours = {(r["scenario"], r["mode"]): r for r in results.get("ours", [])}
    rows = []
    for label, (scen, base) in SCENARIOS.items():
        step, n = floor_step(scen, base)
        sec = timed_chunks(step, args.steps, args.repeats)
        r = {"scenario": label, "n_agents": n, "sec_per_step": sec, "env_steps_s": 1 / sec}
        mine = ours.get((label, "default"))
        if mine:
            r["ours_over_floor"] = mine["sec_per_step"] / sec
        rows.append(r)
        tail = f"  ours/floor = {r['ours_over_floor']:5.2f}x" if mine else ""
        if label == "tree" and mine:
            tail += f"  (target <= {TREE_TARGET_FLOOR:.0f}x)"
        print(f"  floor {label:13s} N={n:3d}  {r['env_steps_s']:8.1f} steps/s  "
              f"{1e3 * sec:6.2f} ms/step{tail}", flush=True)
    results["floor"] = rows


# ---------------------------------------------------------------------------------------- scaling
def open_box(n_robots: int) -> dict:
    """Overrides turning ``office`` into a 20 m x 20 m open box for ``n_robots`` (sonar, no Kinects)."""
    return {
        "map": {"size": [20.0, 20.0], "walls": [], "obstacles": [], "unknown_obstacles": []},
        "start": {"x": 4.0, "y": 10.0, "theta_deg": 0.0},
        "start_queue": [],
        "kpois": [[18.0, 3.0], [18.0, 10.0], [18.0, 17.0], [10.0, 18.0], [10.0, 2.0]],
        "kinects": [],
        "n_robots": n_robots,
        "episode": {"max_steps": 2000},
    }


def section_scaling(args, results: dict) -> None:
    rows = []
    for n in (2, 8, 16, 32, 64):
        try:
            env = our_env("office", open_box(n))
        except Exception as exc:  # noqa: BLE001
            print(f"  open box N={n}: unavailable: {exc}", flush=True)
            continue
        r = measure_parallel(env, args.steps, args.repeats)
        r["n_robots"] = n
        rows.append(r)
        print(f"  open box N={n:3d}  {r['env_steps_s']:8.1f} env-steps/s  "
              f"{r['agent_steps_s']:9.0f} agent-steps/s  {1e3 * r['sec_per_step']:6.2f} ms/step  "
              f"{1e6 * r['sec_per_step'] / n:6.1f} us/robot", flush=True)
    results["scaling"] = rows


# ---------------------------------------------------------------------------------------- vec env
def section_vec(args, results: dict) -> None:
    try:
        from parcover_env.envs.vec_env import make_vec_env
    except ImportError as exc:
        print(f"  SB3 adapter unavailable: {exc}", flush=True)
        return
    rows = []
    for n_envs, multi in ((1, False), (2, True)):
        venv = make_vec_env("tree", n_envs=n_envs, multiprocess=multi, monitor=False)
        try:
            venv.reset()
            rng = np.random.default_rng(0)
            acts = rng.uniform(-1, 1, (64, venv.num_envs, 2)).astype(np.float32)

            def step(k: int, venv=venv, acts=acts) -> None:
                venv.step(acts[k % len(acts)])

            sec = timed_chunks(step, args.steps, args.repeats)
        finally:
            venv.close()
        r = {"n_envs": n_envs, "processes": n_envs if multi else 0, "slots": venv.num_envs,
             "env_steps_s": n_envs / sec, "agent_steps_s": venv.num_envs / sec}
        rows.append(r)
        print(f"  SB3 VecEnv tree x{n_envs} ({'2 worker processes' if multi else 'in-process'}): "
              f"{r['env_steps_s']:8.1f} env-steps/s  {r['agent_steps_s']:9.0f} agent-steps/s", flush=True)
    if len(rows) == 2:
        speedup = rows[1]["env_steps_s"] / rows[0]["env_steps_s"]
        print(f"  speed-up of 2 processes: {speedup:.2f}x", flush=True)
    results["vec"] = rows


# ---------------------------------------------------------------------------------------- batched

def _vec_row(label: str, venv_fn: Callable[[], object], steps: int, repeats: int, k: int) -> dict:
    t0 = time.perf_counter()
    venv = venv_fn()
    build = time.perf_counter() - t0
    try:
        run = VecRunner(venv)
        sec = timed_chunks(run, steps, repeats, warmup=5)
        r = {"label": label, "K": k, "slots": venv.num_envs, "sec_per_step": sec,
             "world_steps_s": k / sec, "agent_steps_s": venv.num_envs / sec, "build_s": build}
    finally:
        venv.close()
    print(f"  {label:34s} K={k:3d} {r['slots']:5d} slots  {r['world_steps_s']:8.1f} world-steps/s  "
          f"{r['agent_steps_s']:9.0f} agent-steps/s  {1e3 * sec:8.1f} ms/step  (built in {build:.1f} s)",
          flush=True)
    return r


def section_batched(args, results: dict) -> None:
    from parcover_env.envs.vec_env import make_vec_env

    out: dict = {"k": [], "team": [], "vmas": None}
    steps = max(args.steps // 10, 5)
    for k in BATCHED_KS:
        out["k"].append(_vec_row("tree batched", lambda k=k: make_vec_env("tree", k, backend="batched",
                                                                          monitor=False),
                                 max(steps * 4 // k, 3), args.repeats, k))
    base = out["k"][0]
    for r in out["k"]:  # > 1: a world steps faster in a batch of K than alone (batching pays)
        r["per_world_speedup"] = r["world_steps_s"] / base["world_steps_s"]
    print("  world-steps/s relative to K=1: "
          + ", ".join(f"K={r['K']}: {r['per_world_speedup']:.2f}x" for r in out["k"]), flush=True)
    ref = _vec_row("tree in-process (K separate)", lambda: make_vec_env("tree", 4, backend="inprocess",
                                                                         monitor=False),
                   max(steps, 3), args.repeats, 4)
    four = next(r for r in out["k"] if r["K"] == 4)
    out["inprocess_4"] = ref
    print(f"  batched / in-process at K=4: {four['agent_steps_s'] / ref['agent_steps_s']:.2f}x", flush=True)
    for n in (2, 8, 16, 32):
        r = _vec_row(f"open box N={n} batched", lambda n=n: make_vec_env("office", 16, overrides=open_box(n),
                                                                         backend="batched", monitor=False),
                     max(steps // 2, 3), args.repeats, 16)
        r["n_robots"] = n
        out["team"].append(r)
    try:
        run = VmasBatchedRunner(64)
    except ImportError as exc:
        print(f"  VMAS navigation batched: not installed ({exc}); pip install vmas", flush=True)
    else:
        sec = timed_chunks(run, steps * 4, args.repeats, warmup=5)
        v = {"peer": "vmas navigation num_envs=64, 4 agents, cpu", "sec_per_step": sec,
             "agent_steps_s": 64 * 4 / sec, "world_steps_s": 64 / sec}
        out["vmas"] = v
        print(f"  {v['peer']:34s}        {v['world_steps_s']:8.1f} world-steps/s  {v['agent_steps_s']:9.0f} "
              f"agent-steps/s  {1e3 * sec:8.1f} ms/step", flush=True)
        k64 = next((r for r in out["k"] if r["K"] == 64), None)
        if k64:
            ratio = k64["agent_steps_s"] / v["agent_steps_s"]
            out["ratio_vmas_64"] = ratio
            print(f"  tree batched K=64 / VMAS navigation 64 = {ratio:.2f}x agent-steps/s "
                  f"(target >= {BATCHED_TARGET_VMAS:.0f}x)", flush=True)
    results["batched"] = out


def section_batching(args, results: dict) -> None:
    from batching import section_batching as run

    run(args, results)


SECTIONS = {"ours": section_ours, "peers": section_peers, "floor": section_floor, "scaling": section_scaling,
            "vec": section_vec, "batched": section_batched, "batching": section_batching,
            "memory": section_memory}


def summary(results: dict) -> None:
    ours = {(r["scenario"], r["mode"]): r for r in results.get("ours", [])}
    tree, frames = ours.get(("tree", "default")), ours.get(("tree", "frames"))
    mpe10 = next((r for r in results.get("peers", []) if r.get("peer", "").endswith("N=10")), None)
    floor = next((r for r in results.get("floor", []) if r["scenario"] == "tree"), None)
    print("\nTargets (tree, this run):")
    if tree and mpe10:
        v = tree["agent_steps_s"] / mpe10["agent_steps_s"]
        print(f"  agent-steps/s vs MPE2 simple_spread N=10: {v:.2f}x  (target >= {TREE_TARGET_MPE:.0f}x)  "
              f"{'MET' if v >= TREE_TARGET_MPE else 'NOT MET'}")
    if floor and "ours_over_floor" in floor:
        v = floor["ours_over_floor"]
        print(f"  ours / physics+rays floor: {v:.2f}x  (target <= {TREE_TARGET_FLOOR:.0f}x)  "
              f"{'MET' if v <= TREE_TARGET_FLOOR else 'NOT MET'}")
    if frames:
        v = frames["realtime"]
        print(f"  Kinect frames mode: {v:.1f}x real time  (target >= {FRAMES_TARGET_RT:.0f}x)  "
              f"{'MET' if v >= FRAMES_TARGET_RT else 'NOT MET'}")
    b = results.get("batched") or {}
    if b.get("ratio_vmas_64") is not None:
        v = b["ratio_vmas_64"]
        print(f"  batched K=64 vs VMAS navigation num_envs=64: {v:.2f}x  (target >= {BATCHED_TARGET_VMAS:.0f}x)  "
              f"{'MET' if v >= BATCHED_TARGET_VMAS else 'NOT MET'}")
    if "memory" in results:
        m = results["memory"]
        if "soak_steps" in m:
            print(f"  memory: {m['slope_mb_per_1e6_steps']:+.2f} MiB per 10^6 steps over {m['soak_steps']} steps")
        if "batched" in m:
            mb = m["batched"]
            print(f"  memory, batched K={mb['K']}: {mb['slope_mb_per_1e6_steps'] / mb['K']:+.2f} MiB per 10^6 "
                  f"world-steps over {mb['world_steps']} world-steps")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=300, help="steps per timed chunk (default 300)")
    p.add_argument("--repeats", type=int, default=3, help="timed chunks per measurement; the median is kept")
    p.add_argument("--sections", default=",".join(SECTIONS), help=f"comma separated of {', '.join(SECTIONS)}")
    p.add_argument("--soak", type=int, default=20000,
                   help="env-steps of the memory soaks (default 20000; 1000000 for the 10^6-step soak)")
    p.add_argument("--soak-batched-only", action="store_true",
                   help="memory section: only the batched soak (the long batched soak without the single-env one)")
    p.add_argument("--ks", default="1,4,16,64,256", help="worlds per process of the batching section")
    p.add_argument("--quick", action="store_true", help="short chunks (smoke run)")
    p.add_argument("--json", help="also write the figures to this JSON file")
    p.add_argument("--torch-threads", type=int, default=1,
                   help="torch threads of the VMAS peers (default 1: our env is single-threaded too, and "
                        "on a shared machine more threads only contend)")
    args = p.parse_args(argv)
    if args.quick:
        args.steps, args.repeats, args.soak = 30, 1, 500
    chosen = [s.strip() for s in args.sections.split(",") if s.strip()]
    unknown = [s for s in chosen if s not in SECTIONS]
    if unknown:
        p.error(f"unknown sections {unknown}; choose from {', '.join(SECTIONS)}")
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    print(f"# parcover_env throughput  python {platform.python_version()}  {os.cpu_count()} cores  "
          f"load {load:.1f}  steps/chunk {args.steps} x {args.repeats}", flush=True)
    results: dict = {"steps": args.steps, "repeats": args.repeats, "load": load}
    try:
        import torch

        torch.set_num_threads(args.torch_threads)
    except ImportError:
        pass
    for name in chosen:
        print(f"\n## {name}", flush=True)
        SECTIONS[name](args, results)
    summary(results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Where ``env.step`` spends its time: a per-component breakdown and a function profile.

The breakdown wraps the parts of one step (physics, odometry + Kinect, mission, team, rewards,
metrics, observation assembly with the sonar and the follower camera) with wall-clock timers; the
profile is cProfile (or pyinstrument with ``--pyinstrument``) over the same random-action run.

    .venv/bin/python docs/lab/scripts/profile_step.py --scenario tree --steps 500
    .venv/bin/python docs/lab/scripts/profile_step.py --scenario tree --mode frames --steps 100
    .venv/bin/python docs/lab/scripts/profile_step.py --scenario tree --mode sonar72 --pyinstrument
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))
from runners import Timers, merge  # noqa: E402
from throughput import MODES, SCENARIOS, open_box  # noqa: E402

from parcover_env.sim import pipeline  # noqa: E402


def make_env(scenario: str, mode: str, n_robots: int | None):
    from parcover_env.envs import ParallelCoverageEnv

    if scenario == "open":
        name, base = "office", open_box(n_robots or 16)
    elif scenario in SCENARIOS:
        name, base = SCENARIOS[scenario]
    else:
        name, base = scenario, {}
    if n_robots and scenario != "open":
        base = merge(base, {"n_robots": n_robots})
    return ParallelCoverageEnv(name, overrides=merge(base, MODES[mode]) or None)


def run(env, steps: int, seed: int = 0) -> float:
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, (steps, env.n_robots, 2)).astype(np.float32)
    t0 = time.perf_counter()
    for k in range(steps):
        if not env.agents:
            env.reset()
        env.step({a: acts[k, i] for i, a in enumerate(env.agents)})
    return time.perf_counter() - t0


def breakdown(env, steps: int) -> None:
    env.reset(seed=0)
    run(env, 10)
    tm = Timers()
    env_mod = sys.modules[type(env).__module__]
    tm.wrap(env_mod, "to_commands", "actions (validation)")
    tm.wrap(env.world, "step", "physics (pymunk + velocity callbacks)")
    tm.wrap(env.world, "poses", "poses read-back")
    tm.wrap(env.estimator, "update", "estimator: odometry + Kinect system")
    if env.kinects is not None:
        tm.wrap(env.kinects, "update", "  Kinect system update")
    tm.wrap(env.progress, "update", "mission: KPOIs + route progress")
    tm.wrap(env.team, "update", "team: splits at TPs")
    tm.wrap(env, "_rewards", "rewards")
    tm.wrap(env, "_record", "metrics")
    tm.wrap(pipeline, "observe", "observation assembly (all)")
    if env.sonar is not None:
        tm.wrap(env.sonar, "sense", "  sonar ring")
    tm.wrap(env.camera.__class__, "measure", "  follower camera")
    total = run(env, steps)
    print(f"\n{steps} steps: {1e3 * total / steps:.3f} ms/step ({steps / total:.0f} steps/s), "
          f"{env.n_robots} robots (the timers add a little overhead)")
    for label, sec in sorted(tm.total.items(), key=lambda kv: -kv[1]):
        print(f"  {label:42s} {1e3 * sec / steps:7.3f} ms  {100 * sec / total:5.1f} %")


def profile(env, steps: int, top: int, use_pyinstrument: bool) -> None:
    env.reset(seed=0)
    run(env, 10)
    if use_pyinstrument:
        try:
            from pyinstrument import Profiler
        except ImportError:
            print("pyinstrument is not installed; using cProfile")
        else:
            prof = Profiler(interval=0.0005)
            prof.start()
            run(env, steps)
            prof.stop()
            print(prof.output_text(unicode=False, color=False, show_all=False))
            return
    prof = cProfile.Profile()
    prof.enable()
    run(env, steps)
    prof.disable()
    out = io.StringIO()
    st = pstats.Stats(prof, stream=out)
    st.sort_stats("tottime").print_stats(top)
    print(f"\ncProfile, {steps} steps, by own time (top {top}):")
    print("\n".join(line for line in out.getvalue().splitlines() if line.strip())[:6000])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="tree", help="office | tree | generated-30 | open | a scenario name")
    p.add_argument("--mode", default="default", choices=sorted(MODES))
    p.add_argument("--n-robots", type=int, default=None, help="team size (for 'open': the box's robots)")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--top", type=int, default=25)
    p.add_argument("--pyinstrument", action="store_true", help="statistical profile with pyinstrument")
    args = p.parse_args(argv)
    env = make_env(args.scenario, args.mode, args.n_robots)
    print(f"# profile of env.step: {args.scenario} ({env.n_robots} robots), mode {args.mode}")
    breakdown(env, args.steps)
    profile(make_env(args.scenario, args.mode, args.n_robots), args.steps, args.top, args.pyinstrument)
    return 0


if __name__ == "__main__":
    sys.exit(main())

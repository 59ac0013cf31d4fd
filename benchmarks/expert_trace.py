"""One expert episode on a generated map, traced: every scan (start, outcome, the env's estimate error)
and every change of a robot's relocation state (the expert's "scan from elsewhere"), per robot.

    python benchmarks/expert_trace.py 57                # generated:57, seed 57, the registered expert
    python benchmarks/expert_trace.py 57 --relocate     # the variant's settings forced (default since 2026-11-26)
    python benchmarks/expert_trace.py 154 --robots 4

The true poses are read here only, to print the errors ("err": the env's estimate, "belerr": the
pose the expert steers by); the expert never sees them. The episode and its map use the same seed,
as in ``benchmarks/expert.py --scenarios generated``.
"""

from __future__ import annotations

import argparse

import numpy as np

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.policies.registry import policy_overrides

RELOCATE = {"observation": {"scan": {"enabled": True, "confirm_widened": True}},
            "expert": {"sonar_fix": {"relocate_distance": 0.5}}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seed", type=int)
    ap.add_argument("--robots", type=int, nargs="*", help="only these robot indices (default: all)")
    ap.add_argument("--relocate", action="store_true", help="scan.confirm_widened and relocate_distance 0.5")
    args = ap.parse_args()
    overrides = {"formation": {"mode": "formation"}, **policy_overrides("expert", f"generated:{args.seed}")}
    if args.relocate:
        overrides.update(RELOCATE)
    env = parcover_env.parallel_env(f"generated:{args.seed}", overrides=overrides, preset="realistic")
    expert = expert_for(env)
    obs, _ = env.reset(seed=args.seed)
    expert.reset(obs)
    g, dt = env.layout.get, env.scenario.physics.control_dt
    fixer = getattr(expert, "fixer", None)
    scanning, state, step = {}, {}, 0
    while env.agents:
        actions = expert.act(obs)
        obs, _, _, _, infos = env.step(actions)
        step += 1
        t, true, belief = step * dt, env.true_poses(), expert.belief()
        for a, o in obs.items():
            i = int(a.rsplit("_", 1)[1])
            if args.robots and i not in args.robots:
                continue
            est = np.array([g(o, "x")[0], g(o, "y")[0]])
            err, belerr = np.hypot(*(est - true[i, :2])), np.hypot(*(belief[i, :2] - true[i, :2]))
            now = bool(g(o, "scanning")[0] > 0.5)
            if len(actions[a]) > 2 and actions[a][2] > 0 and not scanning.get(a, False):
                print(f"t={t:7.1f} {a} scan start  est=({est[0]:.2f}, {est[1]:.2f}) "
                      f"true=({true[i, 0]:.2f}, {true[i, 1]:.2f}) err={err:.2f} belerr={belerr:.2f}")
            if scanning.get(a, False) and not now:
                print(f"t={t:7.1f} {a} scan end    result={g(o, 'scan_result')[0]:+.1f} err={err:.2f}")
            scanning[a] = now
            st = fixer.states.get(a) if fixer is not None else None
            if st is not None:
                key = (st.relocate, st.move, st.spaced, a in expert.detours, a in expert.escaping)
                if key != state.get(a):
                    print(f"t={t:7.1f} {a}   relocate={st.relocate} move={st.move} spaced={st.spaced} "
                          f"escaping={a in expert.escaping} detour={expert.detours.get(a)} "
                          f"true=({true[i, 0]:.2f}, {true[i, 1]:.2f}) err={err:.2f}")
                    state[a] = key
    print("KPOIs visited", env.progress.visited.astype(int), "steps", step)
    print("final error of the pose each robot steers by (m)",
          np.round(np.hypot(*(expert.belief()[:, :2] - env.true_poses()[:, :2]).T), 2))


if __name__ == "__main__":
    main()

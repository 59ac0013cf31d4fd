"""Credit under env version 2, measured on the expert's episodes (realistic preset).

Per scenario and seed: success, the share of an agent's KPOI reward (``own_kpoi`` + ``kpoi``) that
comes from its own visits (v1's team reward: 1 / n_kpois of it at best), whether every robot's
``own_kpoi`` sum equals 10 x its own KPOIs (each owner visited its own KPOIs), and the fraction of
agent-steps whose ``route_done`` is 1 (what death masking removes from the losses).

    .venv/bin/python docs/lab/scripts/v2_credit.py
    .venv/bin/python docs/lab/scripts/v2_credit.py --scenarios office,tree --seeds 1000,1001
"""

from __future__ import annotations

import argparse

import numpy as np

from parcover_env import parcover_v2
from parcover_env.expert import expert_for


def episode(scenario: str, seed: int) -> dict:
    env = parcover_v2.parallel_env(scenario)
    obs, _ = env.reset(seed=seed)
    policy = expert_for(env)
    agents = list(env.possible_agents)
    own = dict.fromkeys(agents, 0.0)
    team = dict.fromkeys(agents, 0.0)
    done_steps = steps = 0
    info = {}
    while env.agents:
        obs, _, _, _, info = env.step(policy.act(obs))
        steps += 1
        for a in agents:
            own[a] += info[a]["reward_own_kpoi"]
            team[a] += info[a]["reward_kpoi"]
            done_steps += info[a]["route_done"]
    w = env.scenario.rewards.own_kpoi
    owners_paid = all(own[a] == w * len(env.plan.robots[i].kpois) for i, a in enumerate(agents))
    share = np.mean([own[a] / (own[a] + team[a]) if own[a] + team[a] else 0.0 for a in agents])
    return {"success": info[agents[0]]["metrics/success"], "own_share": float(share), "owners_paid": owners_paid,
            "done_fraction": done_steps / (steps * len(agents)), "steps": steps}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="office,tree,generated:1000,generated:1001,generated:1002")
    ap.add_argument("--seeds", default="1000")
    args = ap.parse_args()
    print("| scenario | seed | success | steps | own share of KPOI reward | owners paid their own "
          "| route_done agent-steps |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            r = episode(name, seed)
            print(f"| {name} | {seed} | {r['success']:.0f} | {r['steps']} | {r['own_share']:.2f} | "
                  f"{r['owners_paid']} | {r['done_fraction']:.2f} |")


if __name__ == "__main__":
    main()

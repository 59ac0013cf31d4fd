"""How much of the return each reward term carries, per agent-step, under a policy on training maps.

Runs ``POLICY`` (deterministic, as evaluated) for one episode per map with the ``contact`` term on at
weight -1 (so its info holds minus the contact flag) and prints, per term: its sum per robot and
episode, and the standard deviation over agent-steps of its discounted return to go (``--gamma``),
scaled by the weights given (``--weights progress=5,contact=-0.1``: the terms are linear in their
weights, so one episode serves every weighting). The spread of a term's return to go is what it adds
to the spread of the returns the critic fits and the advantages are standardized by; also the
fraction of agent-steps in contact and of those whose own route is done.

    PYTHONPATH=. python docs/lab/scripts/reward_signal.py \
        torchrl:baselines/checkpoints/ippo_generated_scaled/policy.pt \
        --maps 17,42 --seed 7 --weights progress=5,contact=-0.1

Training maps only (seeds < 1000).
"""

from __future__ import annotations

import argparse

import numpy as np

from parcover_env import parallel_env
from parcover_env.policies.torchrl_policy import TorchRLPolicy, checkpoint_overrides


def _to_go(r: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted return to go of every step of ``r (T, N)``."""
    out = np.zeros_like(r)
    acc = np.zeros(r.shape[1])
    for t in range(len(r) - 1, -1, -1):
        acc = r[t] + gamma * acc
        out[t] = acc
    return out


def run(policy: str, map_seed: int, seed: int, gamma: float, weights: dict[str, float]) -> None:
    path = policy.split(":", 1)[1]
    over = dict(checkpoint_overrides(path) or {})
    over["rewards"] = {**over.get("rewards", {}), "contact": -1.0}
    env = parallel_env(f"generated:{map_seed}", overrides=over, preset="realistic")
    obs, _ = env.reset(seed=seed)
    pol = TorchRLPolicy(path)
    base = {t: float(getattr(env.scenario.rewards, t)) for t in env.terms}
    base["contact"] = -1.0
    rows: dict[str, list] = {t: [] for t in env.terms}
    done_rows = []
    while env.agents:
        obs, _, _, _, infos = env.step(pol.act(obs))
        for t in env.terms:
            rows[t].append([infos[a][f"reward_{t}"] for a in env.possible_agents])
        done_rows.append([infos[a].get("route_done", 0.0) for a in env.possible_agents])
    info = infos[env.possible_agents[0]]
    print(f"generated:{map_seed}: {len(done_rows)} steps, KPOIs {info['metrics/kpois_visited']:.0f}/"
          f"{info['metrics/n_kpois']:.0f}, collisions {info['metrics/collisions']:.0f}; agent-steps in contact "
          f"{-np.mean(rows['contact']):.2f}, route done {np.mean(done_rows):.2f}")
    for t in env.terms:
        r = np.array(rows[t]) / base[t] * weights.get(t, base[t]) if base[t] else np.array(rows[t])
        per_robot = r.sum(axis=0)
        print(f"  {t:9s} w {weights.get(t, base[t]):6.2f}: per robot {per_robot.min():7.1f} .. {per_robot.max():7.1f}; "
              f"std of return to go {_to_go(r, gamma).std():6.2f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy")
    p.add_argument("--maps", default="17,42")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--weights", default="", help="term=weight,... (default: the checkpoint's weights)")
    a = p.parse_args()
    weights = {k: float(v) for k, v in (kv.split("=") for kv in a.weights.split(",") if kv)}
    for m in (int(s) for s in a.maps.split(",")):
        run(a.policy, m, a.seed, a.gamma, weights)


if __name__ == "__main__":
    main()

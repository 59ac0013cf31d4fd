"""Per-robot diagnosis of a policy on generated maps: what each robot does and what it is paid.

Prints, per map, the episode's outcome and, per robot: the fraction of steps with its own route's
KPOIs done (``done_mask``) and as leader, mean encoder speed and commanded speed, mean |turn
command|, mean |bearing| of its route goal (``goal_dx, goal_dy``) and of its own KPOI, and the sums
of its reward terms (``info["reward_*"]``). For a ``torchrl:`` policy also the input scale of
the goal entries (standard deviation of the scaled input over the episode) and how much the turn
command moves per metre of ``goal_dy`` (mean |d tanh(w) / d goal_dy|), against the ``waypoint``
controller's ``k_w / lookahead``.

    PYTHONPATH=. python docs/lab/scripts/learned_diagnosis.py \
        torchrl:baselines/checkpoints/ippo_generated_scratch/policy.pt \
        --maps 3,17,42 --seed 7
    PYTHONPATH=. python docs/lab/scripts/learned_diagnosis.py waypoint --maps 3,17,42 --seed 7 \
        --overrides-from baselines/checkpoints/ippo_generated_scratch/run.json

Training maps only (seeds < 1000): this is for finding what goes wrong, not for scoring.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from parcover_env import parallel_env
from parcover_env.policies.simple import WaypointPolicy
from parcover_env.policies.torchrl_policy import SIDECAR_FILE, TorchRLPolicy

COLUMNS = ("done", "leader", "v", "cmd_v", "abs_w", "bear_goal", "bear_kpoi")
TERMS = ("own_kpoi", "kpoi", "progress", "time", "collision")


def _overrides(policy: str, given: str | None) -> dict | None:
    if given is None and policy.startswith("torchrl:"):
        given = str(Path(policy.split(":", 1)[1]).parent / SIDECAR_FILE)
    path = given
    return json.loads(Path(path).read_text()).get("env_overrides") if path else None


def _sensitivity(pol: TorchRLPolicy, layout, obs_rows: list[np.ndarray]) -> str:
    import torch

    x = torch.tensor(np.array(obs_rows), dtype=torch.float32, requires_grad=True)
    scale = pol.net[0]
    scaled = ((x - scale.centre) / scale.half_width).detach().numpy()
    turn = torch.tanh(pol.net(x)[:, 1])
    grad = torch.autograd.grad(turn.sum(), x)[0].numpy()
    gx, gy = layout.slices["goal_dx"], layout.slices["goal_dy"]
    return (f"  scaled input std: goal_dx {scaled[:, gx].std():.3f}, goal_dy {scaled[:, gy].std():.3f}; "
            f"mean |d turn / d goal_dy| {np.abs(grad[:, gy]).mean():.2f} per m")


def diagnose(policy: str, map_seed: int, seed: int, overrides: dict | None) -> None:
    env = parallel_env(f"generated:{map_seed}", overrides=overrides, preset="realistic")
    obs, infos = env.reset(seed=seed)
    lay = env.layout
    pol = TorchRLPolicy(policy.split(":", 1)[1]) if policy.startswith("torchrl:") else WaypointPolicy(lay)
    n = env.n_robots
    sums = {k: np.zeros(n) for k in COLUMNS + TERMS}
    rows, steps = [], 0
    while env.agents:
        act = pol.act(obs)
        for i, a in enumerate(env.possible_agents):
            o = obs[a]
            rows.append(o)
            dx, dy = lay.get(o, "goal_dx")[0], lay.get(o, "goal_dy")[0]
            for key, value in (("done", lay.get(o, "done_mask")[0]), ("leader", lay.get(o, "leader")[0]),
                               ("v", lay.get(o, "v")[0]), ("cmd_v", act[a][0]), ("abs_w", abs(act[a][1])),
                               ("bear_goal", abs(np.degrees(np.arctan2(dy, dx)))),
                               ("bear_kpoi", abs(np.degrees(np.arctan2(lay.get(o, "own_kpoi_sin")[0],
                                                                       lay.get(o, "own_kpoi_cos")[0]))))):
                sums[key][i] += value
        obs, _, _, _, infos = env.step(act)
        steps += 1
        for i, a in enumerate(env.possible_agents):
            for t in TERMS:
                sums[t][i] += infos[a].get(f"reward_{t}", 0.0)
    m = infos[env.possible_agents[0]]
    print(f"generated:{map_seed} ({n} robots, {steps} steps): KPOIs {m['metrics/kpois_visited']:.0f}/"
          f"{m['metrics/n_kpois']:.0f}, success {m['metrics/success']:.0f}, collisions {m['metrics/collisions']:.0f} "
          f"(robots {m['metrics/robot_collisions']:.0f}, walls {m['metrics/wall_collisions']:.0f}), "
          f"localization error {m['metrics/localization_error']:.2f} m")
    print("  robot " + " ".join(f"{c:>9s}" for c in COLUMNS) + " | " + " ".join(f"{t:>9s}" for t in TERMS))
    for i in range(n):
        print(f"  {i:5d} " + " ".join(f"{sums[c][i] / steps:9.2f}" for c in COLUMNS) + " | "
              + " ".join(f"{sums[t][i]:9.2f}" for t in TERMS))
    if isinstance(pol, TorchRLPolicy):
        print(_sensitivity(pol, lay, rows))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("policy", help="torchrl:PATH/policy.pt or waypoint")
    ap.add_argument("--maps", default="3,17,42", help="training map seeds (< 1000), comma separated")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--overrides-from", default=None, help="a run.json whose env_overrides build the env")
    args = ap.parse_args()
    overrides = _overrides(args.policy, args.overrides_from)
    for s in (int(x) for x in args.maps.split(",")):
        if s >= 1000:
            raise SystemExit(f"map {s}: seeds >= 1000 are evaluation maps")
        diagnose(args.policy, s, args.seed, overrides)


if __name__ == "__main__":
    main()

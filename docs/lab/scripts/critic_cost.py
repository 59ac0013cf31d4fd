"""What MAPPO's critic costs per minibatch: ``critic: mlp`` on ``cat(state, obs_i)`` against
``critic: attention`` (the token critic), both on the version-2 state of a real env.

For ``--scenario`` (default ``tree``, 15 robots) one reset's state and observations are tiled into a
minibatch of ``--batch`` env steps; each critic of the sizes in ``configs/train/mappo.yaml`` and
``docs/lab/train_configs/mappo_attention.yaml`` runs forward + backward ``--repeats`` times on one torch
thread; prints the median ms per minibatch and the parameter counts.

    PYTHONPATH=. nice -n 10 .venv/bin/python docs/lab/scripts/critic_cost.py --scenario tree --batch 256
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    import torch
    from tensordict import TensorDict

    from parcover_env import parallel_env
    from parcover_env.harness.marl import GROUP, build_critic
    from parcover_env.harness.marl_config import load_marl_config

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="tree")
    p.add_argument("--batch", type=int, default=256)
    p.add_argument("--repeats", type=int, default=20)
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    env = parallel_env(a.scenario, overrides={"observation": {"version": 2}})
    obs, _ = env.reset(seed=0)
    obs_t = torch.as_tensor(np.stack([obs[r] for r in env.possible_agents])).float()
    state = torch.as_tensor(env.state()).float()
    td = TensorDict({"state": state.expand(a.batch, -1).clone(),
                     GROUP: {"observation": obs_t.expand(a.batch, -1, -1).clone()}}, batch_size=[a.batch])
    print(f"{a.scenario}: {env.n_robots} robots, minibatch {a.batch} env steps, forward + backward, 1 thread")
    for name, cfg in (("mlp", load_marl_config("mappo")),
                      ("attention", load_marl_config("mappo", "docs/lab/train_configs/mappo_attention.yaml"))):
        critic = build_critic("mappo", env.observation_space("robot_0"), env.state_space, cfg)
        times = []
        for _ in range(a.repeats + 2):
            t0 = time.perf_counter()
            critic(td.clone())[GROUP, "state_value"].sum().backward()
            times.append(time.perf_counter() - t0)
        n_params = sum(q.numel() for q in critic.parameters())
        print(f"  critic {name:9s}: {1e3 * statistics.median(times[2:]):7.1f} ms per minibatch, {n_params} parameters")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Collection throughput of ``parcover train``'s env paths: real-robot agent-steps per second.

The shared policy of a fresh actor (``hidden`` of the config) collects ``--frames`` env steps
through TorchRL's ``Collector`` (as ``parcover train`` does) from the env of each path:

* ``pettingzoo``: TorchRL's ``PettingZooWrapper`` around the ParallelEnv (the trainer until
  this change: one ``torch.tensor`` per agent, per info key and per step);
* ``robots``: :class:`~parcover_env.harness.marl_env.RobotsEnv` (arrays), one world;
* ``robots xK``: K RobotsEnvs in TorchRL's ``SerialEnv`` (``MarlConfig.worlds``), one policy call for all.

Map builds of a pool are included (each world builds a map when it first draws it). Prints agent-steps/s
(padding excluded) per path; the PPO update is not included (see ``parcover train``'s own figures).

    PYTHONPATH=. nice -n 10 .venv/bin/python benchmarks/train_throughput.py generated:0-499 --frames 4096
"""

from __future__ import annotations

import argparse
import time
import warnings


def main(argv: list[str] | None = None) -> int:
    import torch
    from torchrl.collectors import Collector
    from torchrl.envs import PettingZooWrapper

    from parcover_env.harness.marl import EnvMaker, build_actor
    from parcover_env.harness.marl_config import load_marl_config

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="generated:0-499")
    p.add_argument("--config", default="docs/lab/train_configs/ippo_generated_worlds.yaml")
    p.add_argument("--frames", type=int, default=4096, help="env steps collected per path (all worlds)")
    p.add_argument("--worlds", type=int, nargs="+", default=[8])
    p.add_argument("--paths", nargs="+", default=["pettingzoo", "robots", "worlds"])
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    cfg = load_marl_config("ippo", a.config)

    def maker(worlds: int) -> EnvMaker:
        return EnvMaker(a.scenario, cfg.preset, cfg.episode_steps, seed=0, overrides=cfg.env,
                        max_robots=cfg.max_robots, worlds=worlds, state=False)

    def wrapped():
        env = maker(1).parallel()
        env.reset(seed=0)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="PettingZoo in TorchRL is tested", category=UserWarning)
            return PettingZooWrapper(env, return_state=False, categorical_actions=False)

    base = maker(1).parallel()
    obs_space = base.observation_space(base.possible_agents[0])
    actor = build_actor(obs_space.low, obs_space.high, base.action_space("robot_0").shape[0], cfg.hidden)
    paths = []
    if "pettingzoo" in a.paths:
        paths.append(("pettingzoo", wrapped))
    if "robots" in a.paths:
        paths.append(("robots", maker(1)))
    if "worlds" in a.paths:
        paths += [(f"robots x{k}", maker(k)) for k in a.worlds]
    print(f"{a.scenario}: {a.frames} env steps per path, {cfg.max_robots} agents (padding excluded), 1 thread")
    for name, make in paths:
        torch.manual_seed(0)
        t0 = time.perf_counter()
        collector = Collector(make, actor, frames_per_batch=a.frames, total_frames=a.frames,
                              auto_register_policy_transforms=False)
        built = time.perf_counter()
        real = 0
        for batch in collector:
            pad = batch.get(("robot", "info", "pad"))
            real = int((1.0 - pad).sum().item())
        wall = time.perf_counter() - built
        collector.shutdown()
        print(f"{name:>12}: {real} agent-steps in {wall:.1f} s = {real / wall:.0f} agent-steps/s "
              f"({1e3 * wall / a.frames:.2f} ms per env step; env built in {built - t0:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

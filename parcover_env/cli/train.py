"""``parcover train ALGO SCENARIO --steps N --out DIR``: IPPO / MAPPO through TorchRL (see
:mod:`parcover_env.harness.marl`); writes ``policy.pt``, ``run.json`` (the sidecar) and ``curve.csv``."""

from __future__ import annotations

import shlex
from pathlib import Path

from parcover_env.cli.checks import check_writable_dir, non_negative_int, positive_int
from parcover_env.errors import ParcoverError

__all__ = ["add_train_parser"]

ALGOS = ("ippo", "mappo")  # parcover_env.harness.marl_config.ALGOS (not imported: keeps --help light)


def add_train_parser(sub) -> None:
    """Register ``parcover train`` on an argparse subparsers object."""
    t = sub.add_parser("train", help="train IPPO or MAPPO with TorchRL (local or on Ray); writes a policy for "
                       "run/bench")
    t.add_argument("algo", choices=ALGOS, help="ippo (per-robot critic) or mappo (critic on env.state())")
    t.add_argument("scenario", help="scenario name, YAML path, generated:SEED, or generated:A-B (a pool of "
                   "generated maps, seeds A..B < 1000, one drawn per episode)")
    t.add_argument("--steps", type=positive_int, required=True,
                   help="agent-steps to collect (env steps x robots; rounded up to whole batches)")
    t.add_argument("--out", required=True, help="output directory: policy.pt, run.json, curve.csv")
    t.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: TorchRL Collector in this process; ray: TorchRL RayCollector on Ray core")
    t.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local Ray)")
    t.add_argument("--seed", type=non_negative_int, default=0, help="torch and env seed (default: 0)")
    t.add_argument("--config", default=None, help="settings YAML (default: configs/train/ALGO.yaml)")
    t.set_defaults(func=cmd_train)


def cmd_train(args) -> int:
    from parcover_env.errors import require
    from parcover_env.harness.marl_config import default_config_path, load_marl_config
    from parcover_env.scenarios import load_scenario

    if args.ray_address and args.backend != "ray":
        raise ParcoverError("--ray-address needs --backend ray")
    config_path = str(args.config or default_config_path(args.algo))
    config = load_marl_config(args.algo, config_path)
    from parcover_env.harness.map_pool import is_pool, parse_pool

    if is_pool(args.scenario):  # generated:A-B, a map pool (seeds < 1000)
        parse_pool(args.scenario)
    else:
        load_scenario(args.scenario, preset=config.preset)  # an unknown scenario fails here, before any import
    for module in ("torch", "torchrl", *(("ray",) if args.backend == "ray" else ())):
        require(module, "train", f"parcover train --backend {args.backend}")
    check_writable_dir(args.out, "--out")
    command = ["parcover", "train", args.algo, args.scenario, "--steps", str(args.steps), "--out", args.out,
               "--backend", args.backend, *(["--ray-address", args.ray_address] if args.ray_address else []),
               "--seed", str(args.seed), *(["--config", args.config] if args.config else [])]
    import logging

    from parcover_env.harness.marl import TrainRequest, train

    logging.getLogger("torchrl").setLevel(logging.WARNING)  # no INFO lines about buffer storage
    print(f"training {args.algo} on {args.scenario} for {args.steps} agent-steps with TorchRL ({args.backend})")
    record = train(TrainRequest(args.algo, args.scenario, args.steps, Path(args.out), config, config_path,
                                backend=args.backend, ray_address=args.ray_address, seed=args.seed,
                                command=shlex.join(command)))
    print(f"{record['agent_steps']} agent-steps, {record['episodes']} episodes ended, {record['wall_time']:.1f} s; "
          f"wrote {Path(args.out) / 'run.json'}")
    maps = "generated:1000,generated:1001,..." if is_pool(args.scenario) else args.scenario  # unseen maps
    print(f"evaluate: parcover bench {maps} --policies {record['policy']}")
    return 0

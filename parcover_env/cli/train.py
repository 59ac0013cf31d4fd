"""``parcover train ALGO SCENARIO --steps N --out DIR``: IPPO / MAPPO through TorchRL (see
:mod:`parcover_env.harness.marl`); writes ``policy.pt``, ``critic.pt``, ``run.json`` (the sidecar), ``curve.csv`` and
``curve.png``. ``--init PATH`` starts from a previous run (:mod:`parcover_env.harness.marl_init`).
``parcover train bc SCENARIO --steps N --out DIR``: behaviour cloning / DAgger of the expert into the same
actor (:mod:`parcover_env.train.imitation`); writes ``policy.pt`` and ``run.json``."""

from __future__ import annotations

import shlex
from pathlib import Path

from parcover_env.cli.checks import check_writable_dir, non_negative_int, positive_int
from parcover_env.errors import ParcoverError

__all__ = ["add_train_parser"]

ALGOS = ("ippo", "mappo", "bc")  # marl_config.ALGOS and bc (not imported: keeps --help light)
IMITATION = "bc"
IMITATION_ALGOS = ("bc", "dagger")
"""The sidecar ``algo`` of a ``parcover train bc`` run (no critic)."""
BC_CONFIG = "ippo"
"""The config file ``bc`` reads by default: the actor ``parcover train ippo`` builds."""


def add_train_parser(sub) -> None:
    """Register ``parcover train`` on an argparse subparsers object."""
    t = sub.add_parser("train", help="train IPPO or MAPPO with TorchRL (local or on Ray); writes a policy for "
                       "run/bench")
    t.add_argument("algo", choices=ALGOS, help="ippo (per-robot critic) or mappo (critic on env.state())")
    t.add_argument("scenario", help="scenario name, YAML path, generated:SEED, or generated:A-B (a pool of "
                   "generated maps, seeds A..B < 1000, one drawn per episode)")
    t.add_argument("--steps", type=positive_int, required=True,
                   help="agent-steps of real robots to collect at least (whole batches; a map pool's "
                        "padding robots do not count); bc: gradient steps per fit")
    t.add_argument("--out", required=True, help="output directory: policy.pt, run.json, curve.csv")
    t.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: TorchRL Collector in this process; ray: TorchRL RayCollector on Ray core")
    t.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local Ray)")
    t.add_argument("--seed", type=non_negative_int, default=0, help="torch and env seed (default: 0)")
    t.add_argument("--config", default=None, help="settings YAML (default: configs/train/ALGO.yaml; bc: "
                   "configs/train/ippo.yaml, whose actor it fits)")
    t.add_argument("--episodes", type=int, default=None,
                   help="bc: expert episodes recorded before the first fit and in each DAgger round (default: 10)")
    t.add_argument("--dagger-rounds", type=int, default=None,
                   help="bc: DAgger rounds after behaviour cloning (the actor drives, the expert labels; default: 0)")
    t.add_argument("--init", default=None, metavar="PATH",
                   help="start the actor (and the critic, when it fits) from a previous run's directory or policy.pt")
    t.set_defaults(func=cmd_train)


def cmd_train(args) -> int:
    from parcover_env.errors import ArgumentError, require

    if args.algo == IMITATION:
        return cmd_imitate(args)
    for option, value in (("--episodes", args.episodes), ("--dagger-rounds", args.dagger_rounds)):
        if value is not None:
            raise ArgumentError(f"{option} is for parcover train bc, not {args.algo}")
    from parcover_env.harness.marl_config import default_config_path, load_marl_config
    from parcover_env.scenarios import load_scenario

    if args.ray_address and args.backend != "ray":
        raise ParcoverError("--ray-address needs --backend ray")
    config_path = str(args.config or default_config_path(args.algo))
    config = load_marl_config(args.algo, config_path)
    from parcover_env.harness.map_pool import is_pool, parse_pool

    # an unknown scenario or a bad pool fails here, before any heavy import (a pool: its first map's settings)
    first = f"generated:{parse_pool(args.scenario)[0]}" if is_pool(args.scenario) else args.scenario
    scenario = load_scenario(first, overrides=config.env or None, preset=config.preset)
    config.check_critic(args.algo, scenario.observation.version, config_path)
    for module in ("torch", "torchrl", *(("ray",) if args.backend == "ray" else ())):
        require(module, "train", f"parcover train --backend {args.backend}")
    if args.init:
        from parcover_env.harness.marl_init import find_init

        find_init(args.init)  # a bad path is one line now (an incompatible network: once the env is built)
    check_writable_dir(args.out, "--out")
    command = ["parcover", "train", args.algo, args.scenario, "--steps", str(args.steps), "--out", args.out,
               "--backend", args.backend, *(["--ray-address", args.ray_address] if args.ray_address else []),
               "--seed", str(args.seed), *(["--config", args.config] if args.config else []),
               *(["--init", args.init] if args.init else [])]
    import logging

    from parcover_env.harness.marl import TrainRequest, train

    logging.getLogger("torchrl").setLevel(logging.WARNING)  # no INFO lines about buffer storage
    print(f"training {args.algo} on {args.scenario} for {args.steps} agent-steps with TorchRL ({args.backend})")
    record = train(TrainRequest(args.algo, args.scenario, args.steps, Path(args.out), config, config_path,
                                backend=args.backend, ray_address=args.ray_address, seed=args.seed,
                                command=shlex.join(command), init=args.init))
    if record["init"]:
        print(init_line(record["init"]))
    print(f"{record['agent_steps']} agent-steps, {record['episodes']} episodes ended, {record['wall_time']:.1f} s; "
          f"wrote {Path(args.out) / 'run.json'}")
    maps = "generated:1000,generated:1001,..." if is_pool(args.scenario) else args.scenario  # unseen maps
    print(f"evaluate: parcover bench {maps} --policies {record['policy']}")
    return 0


def cmd_imitate(args) -> int:
    """``parcover train bc``: record the expert, fit the TorchRL actor (:mod:`parcover_env.train.imitation`)."""
    from parcover_env.errors import ArgumentError, require
    from parcover_env.harness.marl_config import default_config_path, load_marl_config
    from parcover_env.scenarios import load_scenario

    for option, bad in (("--init", args.init), ("--backend ray", args.backend != "local"),
                        ("--ray-address", args.ray_address)):
        if bad:
            raise ArgumentError(f"{option} is for parcover train ippo|mappo, not bc")
    config_path = str(args.config or default_config_path(BC_CONFIG))
    config = load_marl_config(BC_CONFIG, config_path)
    from parcover_env.harness.map_pool import is_pool, parse_pool
    from parcover_env.train.imitation import ImitationRequest

    req = ImitationRequest(args.scenario, args.steps, Path(args.out), config, config_path,
                           episodes=10 if args.episodes is None else args.episodes,
                           dagger_rounds=args.dagger_rounds or 0, seed=args.seed)
    req.check()  # bad counts, evaluation seeds or an evaluation pool: one line, before any heavy import
    first = f"generated:{parse_pool(args.scenario)[0]}" if is_pool(args.scenario) else args.scenario
    load_scenario(first, overrides=config.env or None, preset=config.preset)
    for module in ("torch", "torchrl"):
        require(module, "train", "parcover train bc")
    check_writable_dir(args.out, "--out")
    command = ["parcover", "train", "bc", args.scenario, "--steps", str(args.steps), "--out", args.out,
               "--episodes", str(req.episodes), "--dagger-rounds", str(req.dagger_rounds), "--seed", str(args.seed),
               *(["--config", args.config] if args.config else [])]
    import dataclasses
    import logging

    from parcover_env.train.imitation import imitate

    logging.getLogger("torchrl").setLevel(logging.WARNING)
    print(f"imitating the expert on {args.scenario}: {req.episodes} episodes, {req.dagger_rounds} DAgger round(s), "
          f"{args.steps} gradient steps per fit")
    record = imitate(dataclasses.replace(req, command=shlex.join(command)))
    print(f"{record['data']['samples']} samples, {record['wall_time']:.1f} s; wrote {Path(args.out) / 'run.json'}")
    maps = "generated:1000,generated:1001,..." if is_pool(args.scenario) else args.scenario
    print(f"evaluate: parcover bench {maps} --policies expert,{record['policy']}")
    print(f"fine-tune: parcover train ippo {args.scenario} --steps N --out DIR --init {args.out}")
    return 0


def init_line(init: dict) -> str:
    """What the sidecar's ``init`` record says, as one line: the run started from, whether the critic
    came along, and the entries the actor was grown by (``init_grow``)."""
    if init["critic"]:
        critic = "and its critic"
    elif init.get("algo") in IMITATION_ALGOS:
        critic = f"(a {init['algo']} run: the critic from scratch)"
    else:
        critic = "(critic from scratch: another kind or size)"
    line = f"started from {init['path']} {critic}"
    grown = init.get("grown")
    if grown:
        parts = [f"{kind} {', '.join(names)}" for kind, names in grown.items() if names]
        line += f"; actor grown by {'; '.join(parts)} (new weights zero)"
    return line

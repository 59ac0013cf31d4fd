"""``parcover bench`` and ``parcover collect``."""

from __future__ import annotations

from parcover_env.cli.checks import (
    check_writable_dir,
    check_writable_file,
    int_at_most,
    non_negative_int,
    positive_int,
)
from parcover_env.errors import ParcoverError
from parcover_env.policies.registry import check_policy_spec, policy_specs

__all__ = ["add_bench_parser", "add_collect_parser"]


def add_bench_parser(sub) -> None:
    """Register ``parcover bench`` on an argparse subparsers object."""
    b = sub.add_parser("bench", help="benchmark policies over scenarios and seeds (table, CSV, plots)")
    b.add_argument(
        "scenarios",
        nargs="?",
        default="office",
        help="comma-separated scenario names/paths/generated:SEED (default: office)",
    )
    b.add_argument(
        "--policies",
        default="expert,random",
        help=f"comma-separated, each one of: {policy_specs()} (default: expert,random)",
    )
    b.add_argument("--seeds", type=int_at_most(100_000), default=10,
                   help="episodes per (scenario, policy): seeds OFFSET..OFFSET+N-1 (default: 10)")
    b.add_argument("--seed-offset", type=non_negative_int, default=1000,
                   help="first evaluation seed (default: 1000, disjoint from the trainers' seeds, which are < 1000)")
    b.add_argument("--preset", choices=("realistic", "ideal"), default="realistic",
                   help="error models: realistic (default) or ideal (all off)")
    b.add_argument("--json", default=None, metavar="FILE", help="also write the per-episode records as JSON")
    b.add_argument("--workers", type=positive_int, default=2, help="parallel episodes (default: 2)")
    b.add_argument("--backend", choices=("local", "ray"), default="local")
    b.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local Ray)")
    b.add_argument("--max-steps", type=positive_int, default=None, help="override the scenarios' step limit")
    b.add_argument("--out", default="runs/bench", help="output directory (default: runs/bench)")
    b.add_argument("--no-plots", action="store_true")
    b.add_argument("--quiet", action="store_true", help="no progress bar")
    b.set_defaults(func=cmd_bench)


def cmd_bench(args) -> int:
    from parcover_env.harness.bench import run_sweep, write_report

    scenarios = [s for s in args.scenarios.split(",") if s]
    policies = [p for p in args.policies.split(",") if p]
    if not scenarios or not policies:
        raise ParcoverError("give at least one scenario and one policy")
    for p in policies:
        check_policy_spec(p)
    if not args.no_plots:
        from parcover_env.errors import require

        require("matplotlib", "viz", "bench plots (or pass --no-plots)")
    check_writable_dir(args.out, "--out")
    if args.json:
        from pathlib import Path

        check_writable_dir(str(Path(args.json).resolve().parent), "--json")
        check_writable_file(args.json, "--json")  # not a directory, writable: checked before the sweep
    seeds = list(range(args.seed_offset, args.seed_offset + args.seeds))
    rows = run_sweep(
        scenarios,
        policies,
        seeds,
        args.workers,
        args.backend,
        args.max_steps,
        progress=not args.quiet,
        ray_address=args.ray_address,
        preset=args.preset,
    )
    paths = write_report(rows, args.out, plots=not args.no_plots)
    if args.json:
        from parcover_env.harness.bench import write_json

        paths["json"] = write_json(rows, args.json)
    print(paths["table"].read_text(), end="")
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


def add_collect_parser(sub) -> None:
    """Register ``parcover collect`` on an argparse subparsers object."""
    c = sub.add_parser("collect", help="record expert episodes as a Minari dataset (needs the [data] extra)")
    c.add_argument("scenario", nargs="?", default="office")
    c.add_argument("--episodes", type=positive_int, default=10)
    c.add_argument("--seed", type=non_negative_int, default=0, help="first episode seed (default: 0)")
    c.add_argument("--out", default="runs/datasets", help="dataset root (MINARI_DATASETS_PATH)")
    c.add_argument("--dataset-id", default=None, help="default: parcover/<scenario>-expert-v0")
    c.add_argument("--policy", default="expert", help="who acts and labels (default: expert)")
    c.add_argument("--driver", default=None, metavar="SPEC",
                   help="DAgger: this policy (ppo:PATH ...) drives on --driver-prob of the steps, --policy only labels")
    c.add_argument("--driver-prob", type=float, default=1.0, help="fraction of steps the driver acts (default: 1)")
    c.add_argument("--max-steps", type=positive_int, default=None, help="override the scenario's step limit")
    c.set_defaults(func=cmd_collect)


def cmd_collect(args) -> int:
    from parcover_env.harness.datasets import collect

    check_policy_spec(args.policy)
    if args.driver:
        check_policy_spec(args.driver)
    if not 0.0 <= args.driver_prob <= 1.0:
        raise ParcoverError(f"--driver-prob must be in [0, 1], got {args.driver_prob}")
    check_writable_dir(args.out, "--out")
    dataset_id, n = collect(args.scenario, args.episodes, args.out, args.seed, args.dataset_id, args.policy,
                            driver=args.driver, driver_prob=args.driver_prob, max_steps=args.max_steps)
    print(
        f"wrote Minari dataset '{dataset_id}' ({n} robot episodes from {args.episodes} missions) under "
        f"{args.out}; load with MINARI_DATASETS_PATH={args.out} minari.load_dataset('{dataset_id}')"
    )
    return 0

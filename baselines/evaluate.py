"""Evaluate any policy on a scenario over seeds; print the success rate and IQMs with 95 % bootstrap CIs.

    python baselines/evaluate.py --policy ppo:runs/ppo_office --scenario office --seeds 20
    python baselines/evaluate.py --policy expert        # also: random, waypoint, bc:runs/bc_office

For tables with confidence intervals over several policies use ``parcover bench``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Args:
    policy: str = "expert"
    """expert | waypoint | random | ppo:PATH | bc:PATH"""
    scenario: str = "office"
    seeds: int = 10
    seed_offset: int = 1000
    """First evaluation seed (the trainers use seeds < 1000)."""
    preset: str = "realistic"
    max_steps: int = 0
    """Override the scenario's step limit (0 = keep)."""
    json: str = ""
    """Also write the per-episode rows here."""


def parse_args(argv=None) -> Args:
    """``Args`` from the command line (``--help`` lists every field with its docstring)."""
    import tyro

    return tyro.cli(Args, args=argv, description=__doc__)


def evaluate(args: Args) -> list[dict]:
    from parcover_env.harness.bench import check_policy_spec, run_job

    check_policy_spec(args.policy)
    return [
        run_job(args.scenario, args.policy, s, args.max_steps or None, args.preset)
        for s in range(args.seed_offset, args.seed_offset + args.seeds)
    ]


def main(argv=None) -> int:
    from parcover_env.harness.bench import markdown_table, summarize, write_json

    args = parse_args(argv)
    rows = evaluate(args)
    print(f"{args.policy} on {args.scenario} ({args.preset}), {len(rows)} episodes:")
    print(markdown_table(summarize(rows)), end="")
    if args.json:
        write_json(rows, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

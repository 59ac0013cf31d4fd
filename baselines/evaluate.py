"""Evaluate any policy on a scenario over seeds and print the mean metrics.

    python baselines/evaluate.py --policy ppo:runs/ppo_office --scenario office --seeds 20
    python baselines/evaluate.py --policy expert        # also: random, waypoint, bc:runs/bc_office

For tables with confidence intervals over several policies use ``parcover bench``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass


@dataclass
class Args:
    policy: str = "expert"
    """expert | waypoint | random | ppo:PATH | bc:PATH"""
    scenario: str = "office"
    seeds: int = 10
    seed_offset: int = 0
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
        run_job(args.scenario, args.policy, s, args.max_steps or None)
        for s in range(args.seed_offset, args.seed_offset + args.seeds)
    ]


def main(argv=None) -> int:
    import numpy as np

    args = parse_args(argv)
    rows = evaluate(args)
    print(f"{args.policy} on {args.scenario}, {len(rows)} episodes:")
    for key in ("success", "makespan_ratio", "kpoi_fraction", "collisions", "messages", "wall_time"):
        vals = np.array([r[key] for r in rows], dtype=float)
        print(f"  {key:<15} {np.nanmean(vals) if np.isfinite(vals).any() else float('nan'):.3f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Config fuzzing report: N hypothesis-generated mutated scenario files through the oracle.

Every file must either load (``load_scenario`` + env constructor + reset + steps) or raise the
package's ``ConfigError`` naming the file and a key. Prints outcome counts, the most frequent error
keys, and every failure (with its mutations) — the acceptance figure is ``FAIL = 0``.

    .venv/bin/python docs/lab/scripts/fuzz_report.py --cases 1000
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests" / "reliability"))

from config_mutations import apply_mutations, base_mapping, cases_strategy, check_file  # noqa: E402
from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=1000, help="number of mutated files (default: 1000)")
    p.add_argument("--seed", type=int, default=0, help="hypothesis seed (default: 0)")
    p.add_argument("--max-mutations", type=int, default=3, help="mutations per file (default: 3)")
    args = p.parse_args(argv)

    bases = {}
    counts: collections.Counter = collections.Counter()
    keys: collections.Counter = collections.Counter()
    kinds: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    failures: list[tuple] = []
    tmp = Path(tempfile.mkdtemp(prefix="parcover_fuzz_"))
    t0 = time.perf_counter()

    @settings(max_examples=args.cases, deadline=None, database=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(cases_strategy(args.max_mutations))
    def run(case):
        name, mutations = case
        base = bases.setdefault(name, base_mapping(name))
        path = tmp / f"case_{sum(counts.values()):05d}.yaml"
        path.write_text(apply_mutations(base, mutations))
        outcome, detail = check_file(path)
        counts[outcome] += 1
        for kind, _, _ in mutations:
            kinds[kind][outcome] += 1
        if outcome == "config_error":
            keys[detail.split(":", 1)[0].split("[", 1)[0]] += 1
        elif outcome == "FAIL":
            failures.append((name, mutations, detail))

    seed(args.seed)(run)()
    wall = time.perf_counter() - t0
    total = sum(counts.values())
    print(f"config fuzzing: {total} mutated scenario files in {wall:.0f} s (hypothesis seed {args.seed})")
    for outcome in ("loaded", "config_error", "huge", "FAIL"):
        print(f"  {outcome:<13} {counts[outcome]:6d}")
    print("  most frequent ConfigError keys:")
    for key, n in keys.most_common(15):
        print(f"    {key:<32} {n}")
    print("  outcome by mutation kind (loaded / config_error / huge / FAIL):")
    for kind in sorted(kinds):
        c = kinds[kind]
        print(f"    {kind:<15} {c['loaded']:5d} {c['config_error']:5d} {c['huge']:5d} {c['FAIL']:5d}")
    if failures:
        print(f"  {len(failures)} FAILURES:")
        for name, mutations, detail in failures[:50]:
            print(f"    [{name}] {mutations!r}\n      -> {detail}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

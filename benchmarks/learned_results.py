"""One comparison table from several ``parcover bench --json`` files, plus learning-curve figures.

    PYTHONPATH=. python benchmarks/learned_results.py runs/bench/*.json --out docs/learned \
        --curves runs/ppo_office_ft,runs/ppo_tree,runs/ppo_generated

Prints the Markdown table (success rate with a 95 % stratified-bootstrap CI and its Wilson interval,
IQM [95 % CI] of the other metrics; a ``generated:*`` row aggregates the procedural maps, its bootstrap
stratified by map) and writes ``OUT/table.md``, ``OUT/summary.png`` and ``OUT/curves_<run>.png``.
``--rename old=new,...`` relabels policy specs (checkpoint paths) in the table. ``FILE@P1,P2`` reads
only the records of policies P1, P2 (their specs before renaming) from FILE.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from parcover_env.harness.bench import family, markdown_table, plot_summary, read_episodes, summarize
from parcover_env.viz.curves import plot_learning_curves


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("episodes", nargs="+", help="bench --json files (or episodes.csv); FILE@P1,P2 keeps policies P1, P2")
    p.add_argument("--out", default="runs/learned_results")
    p.add_argument("--curves", default="", help="comma-separated train_ppo.py run directories")
    p.add_argument("--rename", default="", help="policy relabels: spec=label,...")
    a = p.parse_args(argv)
    rows = []
    for spec in a.episodes:
        path, _, keep = spec.partition("@")
        wanted = {k for k in keep.split(",") if k}
        rows += [r for r in read_episodes(path) if not wanted or r["policy"] in wanted]
    names = dict(kv.split("=", 1) for kv in a.rename.split(",") if kv)
    for r in rows:
        r["policy"] = names.get(r["policy"], r["policy"])
        preset = r.get("preset", "realistic")
        r["scenario"] = str(r["scenario"]) + ("" if preset == "realistic" else f" ({preset})")
    order = {s: i for i, s in enumerate(dict.fromkeys(r["scenario"] for r in rows))}
    summary = sorted(summarize(rows), key=lambda s: (order.get(s["scenario"], len(order)), s["scenario"]))
    # the generated:* aggregates, and a single map's row for a policy that ran on one map only
    aggregated = {(s["scenario"], s["policy"]) for s in summary if s["scenario"].startswith("generated:*")}
    summary = [s for s in summary if not s["scenario"].startswith("generated:")
               or s["scenario"].startswith("generated:*") or (family(s["scenario"]), s["policy"]) not in aggregated]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    table = markdown_table(summary)
    (out / "table.md").write_text(table)
    plot_summary(summary, out / "summary.png")
    for run in [r for r in a.curves.split(",") if r]:
        plot_learning_curves([run], out / f"curves_{Path(run).name}.png")
    print(table, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

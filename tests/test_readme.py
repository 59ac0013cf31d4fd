"""The README's API example runs as printed (keeps the README true to the code)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path


def test_readme_is_short():
    """The README is the front page for users (at most 150 lines); the manual is the docs site."""
    lines = (Path(__file__).resolve().parents[1] / "README.md").read_text().splitlines()
    assert len(lines) <= 150


def test_readme_api_example_runs():
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = re.search(r"## The API in 15 lines\n\n```python\n(.*?)```", text, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["infos"]["robot_0"]["metrics/success"] == 1.0
    assert namespace["frame"].ndim == 3


# Results row (scenario, policy) of docs/results.md and the README -> the benchmark records it summarizes: (file in
# docs/learned/episodes/, policy spec prefix in those records)
RECORDS = {
    ("office", "expert"): [("office20_expert_r3", "expert")],
    ("office", "`ippo_office_scratch`"): [("office20_ippo_scratch",
                                            "torchrl:baselines/checkpoints/ippo_office_scratch")],
    ("office", "`ppo_office`"): [("office20", "ppo:baselines/checkpoints/ppo_office.zip")],
    ("office", "waypoint"): [("office_base", "waypoint")],
    ("office", "random"): [("office_base", "random")],
    ("tree", "expert"): [("tree10_expert_r3", "expert")],
    ("tree", "`ippo_tree_scratch`"): [("tree10_ippo_scratch", "torchrl:baselines/checkpoints/ippo_tree_scratch")],
    ("tree", "`ppo_tree`"): [("tree10_ppo", "ppo:baselines/checkpoints/ppo_tree.zip")],
    ("tree", "waypoint"): [("tree_base", "waypoint")],
    ("tree", "random"): [("tree_base", "random")],
    ("generated:*", "expert"): [("gen_expert20_envscan", "expert")],
    ("generated:*", "`mappo_generated_scan_sigma`"): [
        ("gen20_mappo_scan_sigma", "torchrl_sampled:runs/snap/mappo_generated_scan_sigma_1633701")],
    ("generated:*", "`ppo_generated`"): [("gen_dagger_waypoint", "ppo:runs/dagger_generated/round_0")],
    ("generated:*", "waypoint"): [("gen_waypoint_scan_r2", "waypoint"), ("gen_waypoint_scan_heldout", "waypoint")],
    ("generated:*", "random"): [("gen_base", "random")],
}


def _cell(est: float, lo: float, hi: float, digits: int = 2) -> str:
    if not math.isfinite(est):
        return "-"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"{est:.{digits}f}"
    return f"{est:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _table(text: str, header: str) -> list[list[str]]:
    """The rows (cells stripped) of the markdown table whose header line starts with ``header``."""
    lines = text[text.index(header):].split("\n\n")[0].splitlines()[2:]
    return [[c.strip() for c in line.strip("|").split("|")] for line in lines]


def _summary(root: Path, scenario: str, policy: str) -> tuple[str, ...]:
    """(episodes, success, KPOI fraction, makespan ratio, collisions) cells of one row, recomputed from
    its stored ``parcover bench`` records (the same summary ``parcover bench`` prints)."""
    from parcover_env.harness.bench import summarize

    records = []
    for name, prefix in RECORDS[scenario, policy]:
        data = json.loads((root / "docs" / "learned" / "episodes" / f"{name}.json").read_text())
        records += [r for r in data if r["policy"].startswith(prefix)]
    s = next(x for x in summarize(records) if x["scenario"] == scenario)
    return (str(s["episodes"]), _cell(s["success"], s["success_lo"], s["success_hi"]),
            _cell(s["kpoi_fraction"], s["kpoi_fraction_lo"], s["kpoi_fraction_hi"]),
            _cell(s["makespan_ratio"], s["makespan_ratio_lo"], s["makespan_ratio_hi"]),
            _cell(s["collisions"], s["collisions_lo"], s["collisions_hi"], 1))


def test_results_page_table_is_the_benchmark_records():
    """Every row of the results page's table (docs/results.md) is recomputed from the stored
    ``parcover bench`` records, and no record-less row is left."""
    root = Path(__file__).resolve().parents[1]
    rows = _table((root / "docs" / "results.md").read_text(), "| scenario | policy | how it was made (budget) |")
    assert {(r[0], r[1]) for r in rows} == set(RECORDS)
    for scenario, policy, _how, *cells in rows:
        assert tuple(cells) == _summary(root, scenario, policy), (scenario, policy)


def test_readme_results_table_is_the_benchmark_records():
    """The README's short table: rows of the results page, each recomputed from its records."""
    root = Path(__file__).resolve().parents[1]
    rows = _table((root / "README.md").read_text(), "| scenario | policy | episodes |")
    assert len(rows) >= 6 and {(r[0], r[1]) for r in rows} <= set(RECORDS)
    assert {r[0] for r in rows} == {"office", "tree", "generated:*"}
    for scenario, policy, *cells in rows:
        assert tuple(cells) == _summary(root, scenario, policy), (scenario, policy)

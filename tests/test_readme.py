"""The README's API example runs as printed (keeps the README true to the code)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path


def test_readme_api_example_runs():
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = re.search(r"## The API in 15 lines\n\n```python\n(.*?)```", text, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["infos"]["robot_0"]["metrics/success"] == 1.0
    assert namespace["frame"].ndim == 3


# README results row (scenario, policy) -> the benchmark records it summarizes: (file in
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


def test_readme_results_table_is_the_benchmark_records():
    """Every row of the README's results table is recomputed from the stored ``parcover bench``
    records (the same summary ``parcover bench`` prints), and no record-less row is left."""
    from parcover_env.harness.bench import summarize

    root = Path(__file__).resolve().parents[1]
    text = (root / "README.md").read_text()
    table = text[text.index("| scenario | policy | how it was made (budget) |"):].split("\n\n")[0].splitlines()[2:]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in table]
    assert {(r[0], r[1]) for r in rows} == set(RECORDS)
    for scenario, policy, _how, episodes, success, kpoi, makespan, collisions in rows:
        records = []
        for name, prefix in RECORDS[scenario, policy]:
            data = json.loads((root / "docs" / "learned" / "episodes" / f"{name}.json").read_text())
            records += [r for r in data if r["policy"].startswith(prefix)]
        s = next(x for x in summarize(records) if x["scenario"] == scenario)
        got = (str(s["episodes"]), _cell(s["success"], s["success_lo"], s["success_hi"]),
               _cell(s["kpoi_fraction"], s["kpoi_fraction_lo"], s["kpoi_fraction_hi"]),
               _cell(s["makespan_ratio"], s["makespan_ratio_lo"], s["makespan_ratio_hi"]),
               _cell(s["collisions"], s["collisions_lo"], s["collisions_hi"], 1))
        assert got == (episodes, success, kpoi, makespan, collisions), (scenario, policy)

"""docs/tutorials/compare_your_policy.md: its code blocks are the script beside it, and they run
(tiny budgets: the agents are untrained, the plumbing is what is tested)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

TUTORIALS = Path(__file__).resolve().parents[1] / "docs" / "tutorials"


def _code(page: Path) -> str:
    blocks = re.findall(r"```python\n(.*?)```", page.read_text(), re.S)
    return "\n\n".join(b.rstrip("\n") + "\n" for b in blocks)


def test_compare_your_policy_page_is_the_script_and_runs():
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("torchrl")
    code = _code(TUTORIALS / "compare_your_policy.md")
    assert code == (TUTORIALS / "compare_your_policy.py").read_text()  # the script is the page's code
    namespace: dict = {"__name__": "compare_your_policy"}  # not "__main__": define, don't run with defaults
    exec(compile(code, "compare_your_policy.md", "exec"), namespace)
    result = namespace["main"](sb3_steps=128, torchrl_iterations=1, torchrl_frames=32, seeds=[1000, 1001],
                               max_steps=60)
    assert [(r["policy"], r["seed"]) for r in result.episodes] == [
        ("expert", 1000), ("expert", 1001), ("sb3_ppo", 1000), ("sb3_ppo", 1001),
        ("torchrl_ppo", 1000), ("torchrl_ppo", 1001)]
    assert all(r["steps"] == 60 and r["success"] == 0.0 for r in result.episodes)  # 60 steps: nobody finishes
    table = str(result).splitlines()
    assert [line.split(" | ")[1] for line in table[2:]] == ["expert", "sb3_ppo", "torchrl_ppo"]
    sb3, torchrl = namespace["SB3Policy"], namespace["TorchRLPolicy"]
    from parcover_env.policies import Policy

    assert issubclass(sb3, Policy) and issubclass(torchrl, Policy)

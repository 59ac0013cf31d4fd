"""The README's API example runs as printed (keeps the README true to the code)."""

from __future__ import annotations

import re
from pathlib import Path


def test_readme_api_example_runs():
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = re.search(r"## The API in 15 lines\n\n```python\n(.*?)```", text, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["infos"]["robot_0"]["metrics/success"] == 1.0
    assert namespace["frame"].ndim == 3

"""The documentation site's pages run as printed: every ``python`` block of a page, in order, in a fresh
directory, after writing the page's files (a block titled ``title="NAME"`` in a non-Python language is
the file NAME). Python blocks titled with a path are excerpts of the package's source, shown only."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```", re.S | re.M)

PAGES = (
    "concepts/localization.md",
    "tutorials/add_scenario.md",
    "tutorials/add_sensor.md",
    "tutorials/add_reward_term.md",
    "tutorials/add_policy.md",
)
"""Pages whose Python blocks run here (getting_started.md's block is the README's, run by test_readme)."""


def blocks(page: Path) -> list[tuple[str, str | None, str]]:
    """``(language, title or None, code)`` of each fenced block of ``page``, in order."""
    out = []
    for lang, attrs, code in FENCE.findall(page.read_text()):
        title = re.search(r'title="([^"]+)"', attrs)
        out.append((lang, title.group(1) if title else None, code))
    return out


def test_fence_parser_reads_languages_titles_and_code(tmp_path):
    page = tmp_path / "p.md"
    page.write_text('intro\n\n```yaml title="a.yaml"\nx: 1\n```\n\n```python\nprint(1)\n```\n'
                    '\n```python title="pkg/mod.py"\ndef f(): ...\n```\n')
    assert blocks(page) == [("yaml", "a.yaml", "x: 1\n"), ("python", None, "print(1)\n"),
                            ("python", "pkg/mod.py", "def f(): ...\n")]


@pytest.mark.parametrize("name", PAGES)
def test_page_python_blocks_run(name, tmp_path, monkeypatch):
    page = DOCS / name
    found = blocks(page)
    runnable = [code for lang, title, code in found if lang == "python" and title is None]
    assert runnable, f"{name} has no runnable python block"
    for lang, title, code in found:
        if title is not None and lang != "python":
            (tmp_path / title).write_text(code)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": f"docs_{Path(name).stem}"}
    for i, code in enumerate(runnable):
        exec(compile(code, f"{name} [python block {i + 1}]", "exec"), namespace)


def test_every_tutorial_page_is_run_or_linked():
    """A tutorial page of this site runs here, or (compare-your-policy) in tests/test_tutorials.py."""
    tutorials = {str(p.relative_to(DOCS)) for p in (DOCS / "tutorials").glob("*.md")}
    others = tutorials - set(PAGES) - {"tutorials/index.md", "tutorials/compare_your_policy.md"}
    assert not others, f"tutorial pages whose code no test runs: {sorted(others)}"


def test_getting_started_api_block_is_the_readme_block():
    """The site's "API in 15 lines" is the README's, which tests/test_readme.py runs."""
    pattern = r"## The API in 15 lines\n\n```python\n(.*?)```"
    site = re.search(pattern, (DOCS / "getting_started.md").read_text(), re.S).group(1)
    readme = re.search(pattern, (ROOT / "README.md").read_text(), re.S).group(1)
    assert site == readme



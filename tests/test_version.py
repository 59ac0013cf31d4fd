"""One version string: ``parcover_env.__version__`` is the source; everything that names the version
agrees with it (pyproject, installed metadata, the CLI, the docs site, the changelog, the env's
version history)."""

from __future__ import annotations

import importlib.metadata
import json
import re
import sys
from pathlib import Path

import pytest

import parcover_env

ROOT = Path(__file__).resolve().parents[1]
VERSION = re.compile(r"^\d+\.\d+\.\d+$")


def test_version_is_semver_and_pyproject_reads_it_from_the_package():
    assert VERSION.match(parcover_env.__version__)
    tomllib = pytest.importorskip("tomllib", reason="Python < 3.11 has no tomllib")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "parcover_env.__version__"}


def test_setuptools_resolves_the_same_version(monkeypatch):
    pytest.importorskip("setuptools", reason="setuptools is not installed in this environment")
    from setuptools.config.pyprojecttoml import read_configuration

    monkeypatch.chdir(ROOT)  # setuptools resolves ``attr:`` from the project directory
    config = read_configuration(ROOT / "pyproject.toml", expand=True)
    assert config["project"]["version"] == parcover_env.__version__


def test_installed_metadata_matches_when_installed_from_this_checkout():
    try:
        dist = importlib.metadata.distribution("parcover_env")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("parcover_env is not installed (only on the path)")
    direct = dist.read_text("direct_url.json")
    if not direct or Path(json.loads(direct).get("url", "").removeprefix("file://")).resolve() != ROOT:
        pytest.skip("the installed parcover_env is another checkout's (e.g. a worktree on PYTHONPATH)")
    assert dist.version == parcover_env.__version__


def test_cli_prints_the_version(capsys):
    from parcover_env.cli.main import main

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"parcover {parcover_env.__version__}"


def test_docs_site_name_carries_the_version():
    sys.path.insert(0, str(ROOT))
    try:
        import docs_hooks
    finally:
        sys.path.remove(str(ROOT))
    assert docs_hooks.package_version() == parcover_env.__version__
    config = docs_hooks.on_config({"site_name": "parcover_env", "extra": {}})
    assert config["site_name"] == f"parcover_env {parcover_env.__version__}"


def test_changelog_newest_release_is_this_version_and_unreleased_is_on_top():
    text = (ROOT / "CHANGELOG.md").read_text()
    headings = re.findall(r"^## \[([^\]]+)\](?: - (\d{4}-\d{2}-\d{2}))?$", text, re.M)
    assert headings[0] == ("Unreleased", "")
    releases = [v for v, _ in headings[1:]]
    assert releases[0] == parcover_env.__version__
    key = [tuple(map(int, v.split("."))) for v in releases]
    assert key == sorted(key, reverse=True) and len(set(key)) == len(key)


def test_env_version_history_names_released_versions():
    """The env docstring's "Version history" ties each env version to a release of the changelog;
    the newest env version is this release's or an earlier one's."""
    from parcover_env.envs.parallel import ParallelCoverageEnv

    history = ParallelCoverageEnv.__doc__.split("Version history", 1)[1]
    pairs = re.findall(r"\* v(\d+) \((\d+\.\d+\.\d+)\)", history)
    assert [int(v) for v, _ in pairs] == list(range(len(pairs) - 1, -1, -1))
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", (ROOT / "CHANGELOG.md").read_text(), re.M)
    assert {r for _, r in pairs} <= set(releases)
    newest = tuple(map(int, pairs[0][1].split(".")))
    assert newest <= tuple(map(int, parcover_env.__version__.split(".")))


"""The documentation site builds with warnings as errors (what ``make docs`` runs)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

import parcover_env

ROOT = Path(__file__).resolve().parents[1]
MISSING = [m for m in ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")
           if importlib.util.find_spec(m.split(".")[0]) is None
           or (m == "mkdocstrings_handlers.python" and importlib.util.find_spec(m) is None)]


@pytest.mark.skipif(bool(MISSING), reason=f"docs toolchain not installed (pip install -e '.[docs]'): {MISSING}")
def test_site_builds_strict(tmp_path):
    site = tmp_path / "site"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    home = (site / "index.html").read_text()
    assert f"parcover_env {parcover_env.__version__}" in home
    api = (site / "api" / "envs" / "index.html").read_text()
    assert "ParallelCoverageEnv" in api and "Version history" in api   # rendered from the docstring
    for page in ("getting_started", "concepts/sensors", "tutorials/add_sensor", "gallery", "results"):
        assert (site / page / "index.html").is_file(), page
    assert not (site / "learned" / "episodes").exists()   # benchmark records are not published


def test_docs_hook_turns_sphinx_roles_into_code_spans():
    sys.path.insert(0, str(ROOT))
    try:
        import docs_hooks
    finally:
        sys.path.remove(str(ROOT))
    html = ("see :class:<code>~parcover_env.sensors.base.Sensor</code> and :func:<code>merge_routes</code>, "
            ":mod:<code>parcover_env.errors</code>; plain <code>x</code>")
    assert docs_hooks.strip_roles(html) == ("see <code>Sensor</code> and <code>merge_routes</code>, "
                                            "<code>parcover_env.errors</code>; plain <code>x</code>")

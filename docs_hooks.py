"""mkdocs hook: the site's name carries the package version, read from ``parcover_env/__init__.py``.

The version string lives in one place (``parcover_env.__version__``; pyproject reads it too). The
file is parsed, not imported, so building the docs needs none of the package's dependencies.
"""

from __future__ import annotations

import ast
from pathlib import Path

INIT = Path(__file__).resolve().parent / "parcover_env" / "__init__.py"


def package_version() -> str:
    """The ``__version__`` literal of ``parcover_env/__init__.py``."""
    for node in ast.parse(INIT.read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__version__" for t in node.targets):
            return ast.literal_eval(node.value)
    raise RuntimeError(f"{INIT}: no __version__ assignment")


def on_config(config, **kwargs):
    """Name the site ``parcover_env X.Y.Z``."""
    config["site_name"] = f"parcover_env {package_version()}"
    return config

"""mkdocs hooks: the site's name carries the package version; Sphinx roles in docstrings read as code.

The version string lives in one place (``parcover_env.__version__``; pyproject reads it too). The
file is parsed, not imported, so building the docs needs none of the package's dependencies.

The package's docstrings cross-reference with Sphinx roles (``:class:`~parcover_env.x.Y```), which
mkdocstrings leaves as text (``:class:`` before the code span); they are shown as the code span alone,
``~`` keeping the last dotted component, as Sphinx does.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

INIT = Path(__file__).resolve().parent / "parcover_env" / "__init__.py"
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|obj|exc|const):<code>(~?)([^<]+)</code>")


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


def strip_roles(html: str) -> str:
    """``:class:<code>~a.b.C</code>`` -> ``<code>C</code>``; without ``~`` the whole name stays."""
    return ROLE.sub(lambda m: f"<code>{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}</code>", html)


def on_page_content(html, **kwargs):
    """Sphinx roles left as text by the API reference's docstrings become plain code spans."""
    return strip_roles(html)

"""Contracts between rooms and their compiled code, read from the source with ``ast``: kernels take
named records (no call with more than 12 positional arguments, no compiled function with more than
12 parameters), kernel modules are public rooms (no private module or name imported across
modules), and the angle wrap is written once.

``LEFT`` lists known exceptions still to remove: it is empty and may only stay so.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "parcover_env"
MAX_POSITIONAL = 12
LEFT: dict[str, set] = {"calls": set(), "kernels": set(), "private modules": set(), "private imports": set(),
                       "wraps": set()}
THIRD_PARTY_PRIVATE = {("parcover_env/world/physics.py", "pymunk._chipmunk")}
"""pymunk exposes chipmunk's C functions only through its private module (the fast body setters)."""
COMPILERS = {"njit", "jit", "cfunc", "vectorize", "guvectorize"}


def _modules() -> dict[str, ast.Module]:
    return {str(p.relative_to(ROOT)): ast.parse(p.read_text()) for p in sorted(PACKAGE.rglob("*.py"))}


def _private(name: str) -> bool:
    return any(part.startswith("_") and not part.startswith("__") for part in name.split("."))


def test_no_call_passes_more_than_12_positional_arguments():
    calls = {(path, ast.unparse(node.func)) for path, tree in _modules().items() for node in ast.walk(tree)
             if isinstance(node, ast.Call) and len(node.args) > MAX_POSITIONAL}
    assert calls <= LEFT["calls"], sorted(calls - LEFT["calls"])


def test_no_compiled_function_takes_more_than_12_parameters():
    """A kernel with many inputs takes records (:mod:`parcover_env.geometry.records`, NamedTuples)."""
    wide = set()
    for path, tree in _modules().items():
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef):
                continue
            names = {ast.unparse(d.func if isinstance(d, ast.Call) else d).rpartition(".")[2]
                     for d in node.decorator_list}
            if names & COMPILERS and len(node.args.args) > MAX_POSITIONAL:
                wide.add((path, node.name))
    assert wide <= LEFT["kernels"], sorted(wide - LEFT["kernels"])


def test_kernel_modules_are_public_rooms():
    private = {str(p.relative_to(ROOT)) for p in PACKAGE.rglob("_*.py") if not p.name.startswith("__")}
    assert private <= LEFT["private modules"], sorted(private - LEFT["private modules"])


def test_no_private_name_or_module_is_imported_across_modules():
    found = set()
    for path, tree in _modules().items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                found |= {(path, node.module if _private(node.module) else f"{node.module}.{a.name}")
                          for a in node.names if _private(node.module) or _private(a.name)}
            elif isinstance(node, ast.Import):
                found |= {(path, a.name) for a in node.names if _private(a.name)}
    left = found - THIRD_PARTY_PRIVATE - LEFT["private imports"]
    assert left == set(), sorted(left)


def test_the_angle_wrap_is_written_once():
    """``pi - ((pi - a) mod 2 pi)`` lives in :func:`parcover_env.geometry.angles.wrap`; compiled code
    uses :func:`parcover_env.geometry.angle_kernels.wrap`, arrays :func:`~parcover_env.geometry.angles.wrap_angle`."""
    writers = {str(p.relative_to(ROOT)) for p in PACKAGE.rglob("*.py")
               if "% (2.0 * math.pi)" in p.read_text() or "np.mod(np.pi -" in p.read_text()}
    assert writers - LEFT["wraps"] == {"parcover_env/geometry/wrap_formula.py"}

"""The house's import rules, read from the source with ``ast`` (nothing is imported).

Rooms sit on floors (see docs/architecture.md); a module may import from its own
room or from rooms on lower floors, never from a higher floor. ``viz`` draws state and is imported
only by ``envs`` (lazily, inside ``render``), ``harness`` and ``cli``. No import cycles at all.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "parcover_env"
FLOORS = {
    "errors": 0,
    "geometry": 1,
    "config": 2,
    "world": 3, "sensors": 3,
    "planning": 4, "localization": 4, "control": 4,
    "scenarios": 5,
    "viz": 6, "mission": 6,
    "sim": 7,
    "envs": 8,
    "expert": 9, "policies": 9,
    "harness": 10, "train": 10,  # train: the training stack on the batched worlds (issue 41), beside harness
    "cli": 11,
}
VIZ_CLIENTS = {"envs", "harness", "cli"}


def _modules() -> dict[str, Path]:
    mods = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = path
    return mods


def _imports(module: str, path: Path) -> list[tuple[str, bool]]:
    """(imported module, at module level?) for every parcover_env import of ``module``."""
    tree = ast.parse(path.read_text())
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    top_level = {id(n) for n in tree.body}
    for node in tree.body:  # `if TYPE_CHECKING:` blocks are not run
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            top_level -= {id(n) for n in ast.walk(node)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + [base]).strip(".")
            names = [base]
        else:
            continue
        out += [(n, id(node) in top_level) for n in names if n.startswith("parcover_env")]
    return out


ENTRY_POINTS = {"parcover_v0", "parcover_v1", "parcover_v2"}  # top-level factory modules: may import anything


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] not in ENTRY_POINTS else None


MODULES = _modules()
EDGES = [(m, target, top) for m, p in MODULES.items() for target, top in _imports(m, p)]


def test_every_room_has_a_floor():
    rooms = {_room(m) for m in MODULES} - {None, "configs"}
    assert rooms <= set(FLOORS), f"rooms without a floor: {rooms - set(FLOORS)}"


@pytest.mark.parametrize("module, target", [(m, t) for m, t, _ in EDGES if _room(m) and _room(t)])
def test_imports_never_go_up_a_floor(module, target):
    src, dst = _room(module), _room(target)
    if dst == "viz":
        assert src in VIZ_CLIENTS | {"viz"}, f"{module} imports {target}: only envs, harness and cli draw"
        return
    assert FLOORS[dst] <= FLOORS[src], f"{module} (floor {FLOORS[src]}) imports {target} (floor {FLOORS[dst]})"


def test_env_imports_viz_only_lazily():
    eager = [(m, t) for m, t, top in EDGES if _room(m) == "envs" and _room(t) == "viz" and top]
    assert not eager, f"envs must import viz inside render(): {eager}"


def test_no_import_cycles():
    graph = nx.DiGraph()
    for module, target, top in EDGES:
        while target not in MODULES and "." in target:
            target = target.rpartition(".")[0]
        if top and target != module and not module.startswith(target + "."):
            graph.add_edge(module, target)
    assert list(nx.simple_cycles(graph)) == []


def test_no_import_cycles_even_through_lazy_or_type_checking_imports():
    """A lazy or annotation-only import still couples two modules: none of them may close a cycle either
    (the shared piece moves down a floor instead, as ``sim.contract`` holds the phases' data types)."""
    graph = nx.DiGraph()
    for module, target, _ in EDGES:
        while target not in MODULES and "." in target:
            target = target.rpartition(".")[0]
        if target != module and not module.startswith(target + "."):
            graph.add_edge(module, target)
    assert list(nx.simple_cycles(graph)) == []


def test_at_most_four_loose_modules():
    loose = [p.name for p in PACKAGE.glob("*.py") if p.name != "__init__.py"]
    assert len(loose) <= 4, loose


def test_package_import_is_light():
    """``import parcover_env`` loads no room (the env, planner, scipy, networkx, numba come on first use)."""
    import subprocess
    import sys

    code = ("import sys, parcover_env; heavy = [m for m in sys.modules if m.startswith(('parcover_env.', 'scipy',"
            " 'networkx', 'pymunk', 'cv2', 'torch', 'numba', 'llvmlite'))]; print(sorted(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "['parcover_env.errors']"


def test_lazy_names_resolve_to_the_real_objects():
    import parcover_env
    from parcover_env.config import Scenario
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.scenarios import load_scenario

    assert parcover_env.raw_env is ParallelCoverageEnv is parcover_env.ParallelCoverageEnv
    assert parcover_env.Scenario is Scenario and parcover_env.load_scenario is load_scenario
    assert {"raw_env", "load_scenario", "scenario_names", "make_vec_env"} <= set(dir(parcover_env))
    from parcover_env.envs.vec_env import make_vec_env

    assert parcover_env.make_vec_env is make_vec_env
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        parcover_env.nope  # noqa: B018


def test_every_core_module_imports_on_its_own():
    """A module of ``sim`` or ``mission`` imported first (no other package module loaded) imports:
    no import-order cycle hides behind a package ``__init__`` (``envs`` loads its env lazily)."""
    import subprocess
    import sys

    core = sorted(m for m in MODULES if _room(m) in ("sim", "mission") or m.startswith("parcover_env.envs."))
    code = "\n".join([
        "import importlib, sys",
        "bad = []",
        "for m in sys.argv[1:]:",
        "    for name in [n for n in sys.modules if n.startswith('parcover_env')]:",
        "        del sys.modules[name]",
        "    try:",
        "        importlib.import_module(m)",
        "    except ImportError as e:",
        "        bad.append((m, str(e)))",
        "print(bad)"])
    out = subprocess.run([sys.executable, "-c", code, *core], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out

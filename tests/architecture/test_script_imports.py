"""The scripts outside the package (``benchmarks/``, ``baselines/``, ``examples/``, ``docs/lab/scripts/``) import
each other in no cycle, read from the source with ``ast``: the benchmark scripts import only ``throughput.py``'s
sections and their shared runners, and the example and the trainers import no other script."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("benchmarks", "baselines", "examples", "docs/lab/scripts")


def _scripts() -> dict[str, Path]:
    return {f"{folder}/{p.stem}": p for folder in FOLDERS for p in sorted((ROOT / folder).glob("*.py"))}


def _edges(scripts: dict[str, Path]) -> set[tuple[str, str]]:
    """(importer, imported) for every import of a script's bare module name. A bare name resolves to a
    script of the importer's own folder, else of ``benchmarks/`` (``profile_step`` puts it on ``sys.path``)."""
    edges = set()
    for name, path in scripts.items():
        folder = name.rsplit("/", 1)[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                targets = [node.module]
            else:
                continue
            for target in targets:
                for candidate in (f"{folder}/{target}", f"benchmarks/{target}"):
                    if candidate in scripts and candidate != name:
                        edges.add((name, candidate))
                        break
    return edges


def test_the_scripts_import_each_other_in_no_cycle():
    scripts = _scripts()
    graph = nx.DiGraph(_edges(scripts))
    graph.add_nodes_from(scripts)
    assert list(nx.simple_cycles(graph)) == []


def test_which_scripts_import_another():
    assert _edges(_scripts()) == {
        ("benchmarks/throughput", "benchmarks/batching"),
        ("benchmarks/throughput", "benchmarks/memory_soak"),
        ("benchmarks/throughput", "benchmarks/runners"),
        ("benchmarks/batching", "benchmarks/runners"),
        ("benchmarks/memory_soak", "benchmarks/runners"),
        ("docs/lab/scripts/profile_step", "benchmarks/runners"),
        ("docs/lab/scripts/profile_step", "benchmarks/throughput"),
    }


def test_the_edge_reader_sees_a_cycle(tmp_path):
    """The reader is not blind: two scripts importing each other are an edge each way and one cycle."""
    (tmp_path / "a.py").write_text("from b import x\n")
    (tmp_path / "b.py").write_text("import a\n")
    edges = _edges({"t/a": tmp_path / "a.py", "t/b": tmp_path / "b.py"})
    assert edges == {("t/a", "t/b"), ("t/b", "t/a")}
    assert sorted(map(sorted, nx.simple_cycles(nx.DiGraph(edges)))) == [["t/a", "t/b"]]
